"""The one atomic write of the project: a file appears whole under its name, or not at all.

Both packages write every file through :func:`atomic_path` (the simulator's
states, checkpoints, frames and logs of numbers; the analysis' fields,
figures, films, exports and pages), so that a killed or failed writer never
leaves a complete-looking file and a failure reads the same from either
command line (:class:`OutputError`).  Like :mod:`sim.distinct_paths` it is shared with
the analysis: it knows nothing of states or physics, only files.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
from pathlib import Path
from typing import Iterator


class OutputError(OSError):
    """A file could not be written; the message says why and that nothing was lost."""


def temporary_path(path, pid: int | None = None) -> Path:
    """The hidden temporary name a writer of ``path`` writes under: ``.{stem}.{pid}.tmp{ext}``.

    It lies in the folder of ``path`` (so that the rename is atomic) and keeps
    its extension, so that writers that choose a format by the extension
    (a film's container, a VTK file) see the right one.

    Parameters
    ----------
    path : str or Path
    pid : int, optional
        The writing process (default: this one).
    """
    path = Path(path)
    return path.with_name(f".{path.stem}.{os.getpid() if pid is None else pid}.tmp{path.suffix}")


def stale_temporaries(path) -> list[Path]:
    """The temporary files (:func:`temporary_path`) that killed writers of ``path`` left behind."""
    path = Path(path)
    return sorted(path.parent.glob(f".{path.stem}.*.tmp{path.suffix}"))


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed to ``path`` when the block succeeds.

    The folder is created if missing.  If the block raises, the temporary
    file is removed and ``path`` is left as it was; a failure to write (a
    read-only file system, a full disk: :class:`OSError` or netCDF's
    :class:`RuntimeError`) becomes an :class:`OutputError` saying so in one line.

    Parameters
    ----------
    path : str or Path

    Yields
    ------
    pathlib.Path
        The temporary path to write to (:func:`temporary_path`).

    Raises
    ------
    OutputError
        Naming ``path``, the cause and that nothing was lost.
    """
    path = Path(path)
    existed = path.exists()
    tmp = temporary_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        yield tmp
        os.replace(tmp, path)
    except (OSError, RuntimeError) as exc:
        written = tmp.stat().st_size if tmp.exists() else 0
        _remove(tmp)
        raise OutputError(_write_failure(path, exc, written, existed)) from None
    finally:
        _remove(tmp)


def _remove(tmp: Path) -> None:
    """Remove ``tmp`` if it is there (a read-only file system refuses even that: then nothing is there)."""
    with contextlib.suppress(OSError):
        tmp.unlink(missing_ok=True)


def _write_failure(path: Path, exc: BaseException, written: int, existed: bool) -> str:
    """One line on a failed write of ``path``: why (read-only, full disk, other) and what is left.

    netCDF reports a full disk as "HDF error" or even "Permission denied", so a
    folder with under 1 MiB (or under twice what was written) free is named full.
    """
    folder = next((d for d in [path.parent, *path.parent.parents] if d.exists()), path.parent)
    try:
        free = shutil.disk_usage(folder).free
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        free, read_only = None, False
    code = getattr(exc, "errno", None)
    if code == errno.EROFS or read_only:
        why = f"the file system holding {folder} is read-only"
    elif code == errno.ENOSPC or (free is not None and free < max(2**20, 2 * written)):
        why = f"the disk holding {folder} is full ({free} bytes free" + (
            f" after {written} bytes of it were written)" if written else ")")
    else:
        why = f"{type(exc).__name__}: {getattr(exc, 'strerror', None) or exc}"
    kept = "is as it was" if existed else "was not created"
    return f"cannot write {path}: {why}; nothing was lost: {path} {kept} and the partial file was removed"
