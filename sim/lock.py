"""The pour's process lock (:class:`PourLock`) and the pile's log kept over all runs of its pour (:func:`appended_log`)."""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import time as _time
from pathlib import Path

log = logging.getLogger("sim")


def lock_path(checkpoint) -> Path:
    """The lock file of a pour with the checkpoint `checkpoint`: ``<checkpoint>.lock``."""
    checkpoint = Path(checkpoint)
    return checkpoint.with_name(checkpoint.name + ".lock")


class PourLockedError(RuntimeError):
    """Another live process is pouring the same pile."""


@contextlib.contextmanager
def appended_log(path):
    """Append the simulator's log lines (logger ``sim``, at its level: INFO
    from the command line) to ``path`` while in the block, besides where they
    go anyway; an error that ends the block is appended too, as the command
    line prints it.  Nothing without a path.

    Parameters
    ----------
    path : path or None
        The log file; created with its folder when missing, never emptied.
    """
    if not path:
        yield
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, mode="a")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    log.addHandler(handler)
    try:
        yield
    except Exception as exc:
        # into this file only: the command line prints it to the terminal itself
        handler.handle(log.makeRecord(log.name, logging.ERROR, __file__, 0, "%s", (exc,), None))
        raise
    finally:
        log.removeHandler(handler)
        handler.close()


class PourLock:
    """A lock file naming the process that pours a pile (``host pid``).

    Taking it fails with :class:`PourLockedError` while its holder lives, so
    a pour left running by a killed Snakemake and the rerun's pour never
    write the same checkpoint.  A lock whose holder is gone is taken over:
    on this host when no process has its PID, from another host (a shared
    file system) when it was not refreshed for ``stale_after`` seconds (the
    holder refreshes it at every checkpoint).

    Parameters
    ----------
    path : path
        The lock file.
    stale_after : float
        Seconds without a refresh after which another host's lock is stale.
    """

    def __init__(self, path, stale_after):
        self.path = Path(path)
        self.stale_after = stale_after
        self.owner = f"{socket.gethostname()} {os.getpid()}"

    def _holder_alive(self, text):
        """Whether the holder named by the lock's `text` may still run (an
        empty or garbled lock is one whose writer died while writing it)."""
        host, _, pid = text.partition(" ")
        if not pid.isdigit():
            return False
        if host != socket.gethostname():
            return _time.time() - self.path.stat().st_mtime < self.stale_after
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            return False
        except PermissionError:      # a process of another user
            return True
        return True

    def __enter__(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            try:
                holder = self.path.read_text().strip()
                alive = self._holder_alive(holder)
            except FileNotFoundError:
                holder, alive = "", False
            if alive:
                raise PourLockedError(
                    f"{self.path}: this pile is being poured by process {holder!r} "
                    "(host pid); wait for it or stop it (delete the lock file only if "
                    "that process is gone)") from None
            log.warning("taking over the lock %s of %r, which is gone", self.path, holder)
            fd = os.open(self.path, os.O_CREAT | os.O_TRUNC | os.O_WRONLY)
        with os.fdopen(fd, "w") as fh:
            fh.write(self.owner + "\n")
        return self

    def refresh(self):
        """Mark the lock as still held (its modification time)."""
        os.utime(self.path)

    def __exit__(self, *exc):
        try:
            if self.path.read_text().strip() == self.owner:
                self.path.unlink()
        except FileNotFoundError:
            pass

