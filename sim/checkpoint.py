"""A pour's checkpoint housekeeping, its finished copy, and the last good state of a blow-up.

A checkpoint is resumed only if it was made for the same pile by the same
code (:func:`sim.io.code_version`) under the same result-relevant settings of
``sim.config.STAGE_SECTIONS["pour"]``; otherwise, or when it cannot be read, it is renamed
aside (``*.unused``) and the pour starts afresh.  The frames of a film taken
so far are kept beside it (:func:`sim.frames.partial_path`).

A finished pour may also be kept apart from its outputs (:func:`keep_finished`),
where a workflow that deletes those outputs (Snakemake, which counts them
incomplete when it was interrupted while the pour ran) leaves it: a rerun takes
it under the same rule as a checkpoint instead of pouring again
(:func:`take_finished`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time as _time
from pathlib import Path

from .atomic import OutputError, atomic_path, stale_temporaries
from .config import STAGE_SECTIONS, result_settings
from .frames import partial_path
from .io import (StateFileError, code_version, load_simulation,
                 save_state)

log = logging.getLogger("sim")

#: What reading a pour's state file and its attributes raises when the file is unusable.
UNREADABLE = (StateFileError, KeyError, ValueError, AttributeError)


def last_good_path(out) -> Path:
    """Where :func:`keep_last_good` saves the last good state of the run writing ``out``:
    ``out`` with the suffix ``.lastgood.nc``."""
    return Path(out).with_suffix(".lastgood.nc")


def keep_last_good(sim, out, cfg, exc, **attrs):
    """Save the state a blow-up returned to, beside ``out``, under a name that says so."""
    path = last_good_path(out)
    save_state(sim, path, cfg.to_dict(), stage="lastgood", error=str(exc), **attrs)
    log.error("last good state (t = %.6g s) saved to %s", sim.time, path)


def remove_temporaries(checkpoint, *outputs):
    """Delete the temporary files whose writer was killed: of checkpoints, of
    their frames and of the pour's ``outputs`` (its state and film, written
    under the same lock); only the holder of the pour's lock may."""
    paths = [checkpoint, partial_path(checkpoint), *(Path(o) for o in outputs if o)]
    for path in paths:
        for stale in stale_temporaries(path):
            stale.unlink()


def set_aside(checkpoint, reason):
    """Rename an unusable checkpoint out of the way (kept for inspection) and log why."""
    aside = checkpoint.with_name(f"{checkpoint.name}.{_time.strftime('%Y%m%dT%H%M%S')}.unused")
    os.replace(checkpoint, aside)
    log.warning("checkpoint %s %s; set aside as %s, pouring afresh", checkpoint, reason, aside)


def _made_otherwise(ds, cfg, protocol, seed):
    """What a pour's state file `ds` was made for otherwise than this pour.

    Parameters
    ----------
    ds : xarray.Dataset
        A checkpoint or a poured state.
    cfg : SimConfig
    protocol : str
    seed : int

    Returns
    -------
    list of str
        Of "protocol", "seed", "code version" (:func:`sim.io.code_version`) and
        "configuration" (the result-relevant settings, :meth:`SimConfig.result_dict`),
        those that differ; empty for a file this pour may take as its own.

    Raises
    ------
    ValueError, AttributeError
        When the file's attributes cannot be read as such (:data:`UNREADABLE`).
    """
    made = {"protocol": ds.attrs.get("protocol"), "seed": int(ds.attrs.get("seed", -1)),
            "code version": ds.attrs.get("code_version"),
            "configuration": result_settings(json.loads(ds.attrs.get("config", "{}")),
                                             STAGE_SECTIONS["pour"])}
    now = {"protocol": protocol, "seed": seed, "code version": code_version(),
           "configuration": cfg.result_dict(STAGE_SECTIONS["pour"])}
    return [key for key in now if made[key] != now[key]]


def resume(cfg, protocol, seed, checkpoint, shapes):
    """The simulation and next release time of a usable checkpoint, or None.

    A checkpoint is used only if it was made for the same pile by the same
    code under the same result-relevant settings (:func:`_made_otherwise`);
    otherwise, or if it cannot be read, it is set aside.
    """
    try:
        sim, ds = load_simulation(checkpoint, cfg.model, capacity_shapes=shapes)
        differ = _made_otherwise(ds, cfg, protocol, seed)
        next_release = float(ds.attrs["next_release"])
    except UNREADABLE as exc:
        set_aside(checkpoint, f"is unusable ({exc})")
        return None
    if differ:
        set_aside(checkpoint, f"was made with another {' and '.join(differ)}")
        return None
    log.info("resuming %s seed %d from checkpoint %s: t = %.4f s, %d particles",
             protocol, seed, checkpoint, sim.time, sim.n)
    return sim, next_release


def _write_checkpoint(sim, checkpoint, cfg, next_release, recorder, lock, attrs):
    """Write the checkpoint (stage ``checkpoint``, with the time of the next
    release) and the frames so far, and refresh the pour's lock, written or not
    (the run holding it is alive).

    Raises
    ------
    sim.atomic.OutputError
        If a file cannot be written; the checkpoint on disk is as it was.
    """
    try:
        if recorder is not None:
            recorder.save(partial_path(checkpoint), cfg.to_dict(), **attrs)
        save_state(sim, checkpoint, cfg.to_dict(), stage="checkpoint",
                   next_release=next_release, **attrs)
    finally:
        if lock is not None:
            lock.refresh()


def _left(checkpoint, stopped=False):
    """What a stop leaves (`stopped`), or would leave, of a pour whose
    checkpoint could not be written now."""
    if Path(checkpoint).exists():
        return f"{checkpoint} keeps its last write, from which a rerun resumes" + (
            "" if stopped else ", and a stop before the next one is written loses the pour "
                               "since then")
    if stopped:
        return "no checkpoint was ever written, so a rerun pours afresh"
    return "there is none yet, and a stop before one is written loses the pour so far"


def save_checkpoint(sim, checkpoint, cfg, next_release, recorder=None, lock=None, **attrs):
    """Write the checkpoint of a running pour (:func:`_write_checkpoint`);
    ``attrs`` holds its ``protocol`` and ``seed``.

    A checkpoint that cannot be written (a full disk, a read-only file
    system) ends no pour: it only shortens a rerun after a stop, while ending
    the pour would lose all of it since its start or last checkpoint, its
    output's disk maybe healthy.  So the pour goes on, with one warning line
    that names the cause and what a stop would lose, and tries again at the
    next interval.

    Returns
    -------
    bool
        Whether it was written.
    """
    try:
        _write_checkpoint(sim, checkpoint, cfg, next_release, recorder, lock, attrs)
    except OutputError as exc:
        log.warning("pour %s seed %s: checkpoint not written (%s); pouring on without it: %s",
                    attrs.get("protocol"), attrs.get("seed"), _cause(exc), _left(checkpoint))
        return False
    return True


def save_stop_checkpoint(sim, checkpoint, cfg, next_release, recorder, lock, signal_name,
                         **attrs):
    """Write the checkpoint of a pour stopped by the signal ``signal_name``
    (:func:`_write_checkpoint`).

    Returns
    -------
    bool
        Whether it was written; where it cannot be, one error line says that
        the state of the stop is lost, why, and what is left on disk.
    """
    try:
        _write_checkpoint(sim, checkpoint, cfg, next_release, recorder, lock, attrs)
    except OutputError as exc:
        log.error("pour %s seed %s: stopped by %s; the checkpoint could not be written (%s): "
                  "the state of the stop is lost; %s", attrs.get("protocol"), attrs.get("seed"),
                  signal_name, _cause(exc), _left(checkpoint, stopped=True))
        return False
    return True


def _cause(exc):
    """The cause of a failed write (:class:`sim.atomic.OutputError`), without its
    claim that nothing was lost: true of the file, not of the pour."""
    return str(exc).split("; nothing was lost")[0]


def remove_checkpoint(checkpoint):
    """Delete a checkpoint and its frames (a finished pour, or a fresh start)."""
    checkpoint.unlink(missing_ok=True)
    partial_path(checkpoint).unlink(missing_ok=True)


def _copy(source, path):
    """Write a copy of the file `source` to `path` atomically (:func:`sim.atomic.atomic_path`).

    A copy, not a hard link: a hard link would make the two one file, which
    :func:`sim.distinct_paths.check_distinct_paths` refuses as ``--out`` and ``--finished``.
    """
    with atomic_path(path) as tmp:
        shutil.copyfile(source, tmp)


def keep_finished(finished, out, frames=None):
    """Keep a copy of a finished pour, its state `out` and its `frames` (or none),
    as `finished` and the frames beside it (:func:`sim.frames.partial_path`).

    Each copy is written atomically, the frames first, so a `finished` state
    that exists is whole and its frames, where the pour took them, are there.
    Frames of an earlier pour left beside it are removed when this one took none.
    """
    finished = Path(finished)
    if frames:
        _copy(frames, partial_path(finished))
    else:
        partial_path(finished).unlink(missing_ok=True)
    _copy(out, finished)


def take_finished(cfg, protocol, seed, finished, out, frames=None):
    """The simulation of a finished pour kept by :func:`keep_finished`, copied
    to `out` (and its frames to `frames`), or None to pour.

    The finished pour is taken only if it was made for the same pile by the
    same code under the same result-relevant settings (:func:`_made_otherwise`,
    the rule of a checkpoint), and with its frames where `frames` asks for a
    film; a log line says so.  Otherwise it is removed with one log line (a
    rerun under other settings pours afresh and never sees it again), or, when
    only its frames are missing, left for the pour to supersede.  The
    temporary files that a killed copy left of it and of the outputs are
    removed first (:func:`remove_temporaries`; the caller holds the pour's lock).

    Parameters
    ----------
    cfg : SimConfig
    protocol : str
    seed : int
    finished : path
        The finished pour kept (``pour --finished``).
    out, frames : path
        The pour's state file and frames (or None).

    Returns
    -------
    Simulation or None
    """
    finished = Path(finished)
    remove_temporaries(finished, out, frames)
    if not finished.exists():
        return None
    what = f"pour {protocol} seed {seed}: the finished pour {finished}"
    try:
        sim, ds = load_simulation(finished)
        differ = _made_otherwise(ds, cfg, protocol, seed)
        why = f"was made with another {' and '.join(differ)}" if differ else None
    except UNREADABLE as exc:
        why = f"is unusable ({exc})"
    if why:
        finished.unlink()
        partial_path(finished).unlink(missing_ok=True)
        log.warning("%s %s; removed, pouring afresh", what, why)
        return None
    if frames and not partial_path(finished).exists():
        log.warning("%s has no frames of a film (%s); pouring afresh to take them",
                    what, partial_path(finished))
        return None
    if frames:
        _copy(partial_path(finished), frames)
    _copy(finished, out)
    log.info("%s was made for this pile by this code under these settings; taken as it is "
             "(copied to %s%s), not poured again", what, out,
             f" and its frames to {frames}" if frames else "")
    return sim
