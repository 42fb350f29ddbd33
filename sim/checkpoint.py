"""A pour's checkpoint housekeeping, and the last good state of a blow-up.

A checkpoint is resumed only if it was made for the same pile by the same
code (:func:`sim.io.code_version`) under the same result-relevant settings of
:data:`POUR_SECTIONS`; otherwise, or when it cannot be read, it is renamed
aside (``*.unused``) and the pour starts afresh.  The frames of a film taken
so far are kept beside it (:func:`sim.frames.partial_path`).
"""

from __future__ import annotations

import json
import logging
import os
import time as _time
from pathlib import Path

from .config import result_settings
from .frames import partial_path
from .io import POUR_SECTIONS, StateFileError, code_version, load_simulation, save_state

log = logging.getLogger("sim")


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
        for stale in path.parent.glob(f".{path.name}.*.tmp"):
            stale.unlink()


def set_aside(checkpoint, reason):
    """Rename an unusable checkpoint out of the way (kept for inspection) and log why."""
    aside = checkpoint.with_name(f"{checkpoint.name}.{_time.strftime('%Y%m%dT%H%M%S')}.unused")
    os.replace(checkpoint, aside)
    log.warning("checkpoint %s %s; set aside as %s, pouring afresh", checkpoint, reason, aside)


def resume(cfg, protocol, seed, checkpoint, shapes):
    """The simulation and next release time of a usable checkpoint, or None.

    A checkpoint is used only if it was made for the same pile by the same
    code under the same result-relevant settings (:meth:`SimConfig.result_dict`);
    otherwise, or if it cannot be read, it is set aside.
    """
    try:
        sim, ds = load_simulation(checkpoint, cfg.model, capacity_shapes=shapes)
        made = {"protocol": ds.attrs.get("protocol"), "seed": int(ds.attrs.get("seed", -1)),
                "code version": ds.attrs.get("code_version"),
                "configuration": result_settings(json.loads(ds.attrs.get("config", "{}")),
                                                 POUR_SECTIONS)}
        next_release = float(ds.attrs["next_release"])
    except (StateFileError, KeyError, ValueError, AttributeError) as exc:
        set_aside(checkpoint, f"is unusable ({exc})")
        return None
    now = {"protocol": protocol, "seed": seed, "code version": code_version(),
           "configuration": cfg.result_dict(POUR_SECTIONS)}
    differ = [key for key in now if made[key] != now[key]]
    if differ:
        set_aside(checkpoint, f"was made with another {' and '.join(differ)}")
        return None
    log.info("resuming %s seed %d from checkpoint %s: t = %.4f s, %d particles",
             protocol, seed, checkpoint, sim.time, sim.n)
    return sim, next_release


def save_checkpoint(sim, checkpoint, cfg, next_release, recorder=None, lock=None, **attrs):
    """Write the checkpoint (stage ``checkpoint``, with the time of the next
    release) and the frames so far, and refresh the pour's lock."""
    if recorder is not None:
        recorder.save(partial_path(checkpoint), cfg.to_dict(), **attrs)
    save_state(sim, checkpoint, cfg.to_dict(), stage="checkpoint", next_release=next_release,
               **attrs)
    if lock is not None:
        lock.refresh()


def remove_checkpoint(checkpoint):
    """Delete a checkpoint and its frames (a finished pour, or a fresh start)."""
    checkpoint.unlink(missing_ok=True)
    partial_path(checkpoint).unlink(missing_ok=True)
