"""The probes of a pile at rest: gravity lowered, tilted or restored
(:func:`change_gravity`), and the support stretched (:func:`stretch_file`);
each relaxes the pile again (:func:`sim.relax.relax`) and saves it."""

from __future__ import annotations

import re

import numpy as np

from .config import SimConfig
from .io import check_input_stage, load_simulation
from .pour import GRAVITY
from .relax import relax, run_stage
from .scene import BODY_SUPPORT

#: What every probe but the restoring one starts from.
RELAXED = "a relaxed state (stage 'relaxed', written by python -m sim relax)"
#: What the restoring probe starts from (:func:`restore_file`).
REDUCED = ("a gravity reduction of a relaxed state (stage 'reduced' or 'reducedNN', written by "
           "python -m sim probe --level)")


def is_reduction(stage: str) -> bool:
    """Whether ``stage`` names a gravity reduction (``reduced``, ``reducedNN``)."""
    return re.fullmatch(r"reduced(\d\d)?", stage) is not None


def _load_input(cfg, input_path, command, restore=False):
    """The simulation and dataset of a probe's input: a relaxed state, or for
    the restoring probe a reduced one (:func:`sim.io.check_input_stage`)."""
    sim, ds = load_simulation(input_path, cfg.model)
    if restore:
        check_input_stage(input_path, ds, is_reduction, f"python -m sim probe {command}", REDUCED)
    else:
        check_input_stage(input_path, ds, lambda stage: stage == "relaxed",
                          f"python -m sim probe {command}", RELAXED)
    return sim, ds


def change_gravity(cfg: SimConfig, input_path, target, out, stage, what, command, **attrs):
    """Change gravity of a state at rest to ``target(g)``, relax again and save.

    With ``probe.mode = "ramp"`` gravity goes linearly to `target` over
    ``probe.ramp_time`` in 50 equal steps; with ``"step"`` at once.  The pile
    then relaxes to the rest criterion of the increment: :func:`sim.relax.relax` with
    the change of weight, ``M |Δg|``, as the load.

    Parameters
    ----------
    cfg : SimConfig
    input_path : path
        A relaxed state, or a reduced one for the restoring probe.
    target : callable
        The new gravity vector (m/s²) from the state's gravity vector ``g``.
    out : path
        The probe's state file (written atomically).
    stage : str
        Its stage name.
    what : str
        Name of the probe in log lines.
    command : str
        The option of ``python -m sim probe`` that asks for it (``--level``,
        ``--tilt``, ``--restore``: only ``--restore`` starts from a reduced state).
    **attrs
        Further global attributes of the state file.

    Raises
    ------
    sim.io.StateFileError
        If the input's stage is not :data:`RELAXED` (:data:`REDUCED` for
        ``--restore``), before anything runs.
    """
    sim, ds = _load_input(cfg, input_path, command, restore=command == "--restore")
    g_start = np.array(sim.gravity, float)
    g_end = np.array(target(g_start), float)

    ramp = cfg.probe.mode == "ramp"

    def work(progress):
        sim.drag = cfg.relax.drag
        if ramp:
            for s in range(1, 51):
                sim.set_gravity(*(g_start + (g_end - g_start) * s / 50.0))
                sim.run(duration=cfg.probe.ramp_time / 50.0)
        sim.set_gravity(*g_end)
        mass = float(np.sum(sim.shapes.mass[:sim.n]))
        return {**attrs, **relax(sim, cfg, what, load=mass * float(np.hypot(*(g_end - g_start))),
                                 progress=progress)}

    return run_stage(cfg, sim, ds, out, stage, what, work,
                     extra_time=cfg.probe.ramp_time if ramp else 0.0,
                     gravity=float(np.hypot(*g_end)))


def probe_file(cfg: SimConfig, input_path, level, out, stage="reduced"):
    """Lower gravity by ``level`` (Δ) from a relaxed state to (1 − Δ) g and relax
    again (:func:`change_gravity`); the stage records ``gravity_reduction``."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"level = {level!r}: the gravity reduction must be in (0, 1)")
    return change_gravity(cfg, input_path, lambda g: (1.0 - level) * g, out, stage,
                          f"probe {level:g}", "--level", gravity_reduction=level)


def tilt_file(cfg: SimConfig, input_path, tilt, out, stage):
    """Add a horizontal component ``tilt · |g|`` to the gravity of a relaxed state
    and relax again (:func:`change_gravity`); the stage records ``gravity_tilt``."""
    if not (0.0 < abs(tilt) < 0.5):
        raise ValueError(f"tilt = {tilt!r}: the tilt of gravity must be in (-0.5, 0.5), not 0")
    return change_gravity(cfg, input_path, lambda g: g + (tilt * float(np.hypot(*g)), 0.0), out,
                          stage, f"tilt {tilt:+g}", "--tilt", gravity_tilt=tilt)


def restore_file(cfg: SimConfig, input_path, out, stage="restored"):
    """Restore full gravity ``(0, −g0)`` (:data:`GRAVITY`) from a reduced state and
    relax again (:func:`change_gravity`); the part of the strain increment
    that comes back is the elastic part."""
    return change_gravity(cfg, input_path, lambda g: (0.0, -GRAVITY), out, stage, "restore",
                          "--restore", gravity_reduction=0.0)


#: Equal increments in which :func:`stretch_file` imposes the support's strain
#: over ``probe.stretch_time``: at the study's strain of 1e-4, a contact at
#: the toe of a full-size pile (x = 0.54 m) is dragged by 1.1e-7 m per
#: increment, a spring change of 0.3 N, against contact forces of order 10 N.
STRETCH_INCREMENTS = 500


def support_reaction_moment(sim):
    """``Σ_c x_c F_x,c`` over the support's contacts (N m), from the last
    force evaluation: the generalised force conjugate to a stretch ε of the
    support (a stretch that raises it linearly by ΔP does the work ε ΔP / 2)."""
    c = sim.contacts()
    on = c["j"] == BODY_SUPPORT
    return float(np.sum(c["x"][on] * c["fx"][on]))


def stretch_file(cfg: SimConfig, input_path, strain, out, stage="stretched"):
    """Stretch the support of a relaxed pile by ``strain`` and relax again.

    The support's surface point at x moves by ``strain · x`` horizontally
    (x = 0 on the pouring axis), linearly over ``probe.stretch_time`` in
    :data:`STRETCH_INCREMENTS` equal steps (:meth:`sim.engine.Simulation.stretch_body`:
    the particles touching the support are dragged by their tangential
    springs; the surface stays the plane y = 0).  Then the pile relaxes to
    the rest criterion of the change of load, taken as the sum over the
    support's contacts of the change of their horizontal force during the
    stretch.  Unlike a gravity probe this load is not a body force: its
    strain field is not one that any change of gravity makes
    (docs/model.md, "The support stretch").

    Parameters
    ----------
    cfg : SimConfig
    input_path : path
        A state at rest (``relaxed``).
    strain : float
        The support's strain ε, in (−0.01, 0.01), not 0 (> 0: stretched).
    out : path
        The stage's state file (written atomically); it records
        ``support_stretch`` = ε and ``support_reaction_moment`` before and
        after (:func:`support_reaction_moment`).
    stage : str

    Raises
    ------
    ValueError
        For a strain outside that range, an input not relaxed
        (:class:`sim.io.StateFileError`), a pile on a rough base (its fixed
        polygons do not stretch), a scene without the support or a
        frictionless support, before anything runs.
    """
    strain = float(strain)
    if not (0.0 < abs(strain) < 0.01):
        raise ValueError(f"stretch = {strain!r}: the support's strain must be in (-0.01, 0.01), not 0")
    sim, ds = _load_input(cfg, input_path, "--stretch")
    if sim.base is not None:
        raise ValueError(f"{input_path}: the pile lies on a rough base (physics.rough_base = "
                         f"true, {sim.base.count} fixed polygons), which the stretch does not "
                         "move: the flat support it stretches under them drags no particle; "
                         "allowed: a pile poured on the flat support (physics.rough_base = false)")
    if BODY_SUPPORT not in sim.body_ids:
        raise ValueError(f"{input_path}: the scene has no support to stretch (physics.support = false)")
    if not sim.model.support_friction > 0.0:
        raise ValueError(f"model.support_friction = {sim.model.support_friction}: the stretched support "
                         "drags the particles only through friction; give it > 0")
    on = ds["contact_j"].values == BODY_SUPPORT
    before = {"i": ds["contact_i"].values[on].astype(np.int64), "fx": ds["force_x"].values[on]}
    moment_before = float(np.sum(ds["contact_x"].values[on] * before["fx"]))
    what = f"stretch {strain:+g}"

    def work(progress):
        sim.drag = cfg.relax.drag
        chunk = cfg.probe.stretch_time / STRETCH_INCREMENTS
        for _ in range(STRETCH_INCREMENTS):
            # a chunk first: the increment moves the springs of the contacts of
            # the last force evaluation, which a state read from a file has not had
            sim.run(duration=chunk)
            sim.stretch_body(BODY_SUPPORT, strain / STRETCH_INCREMENTS)
        applied = relax(sim, cfg, what, load=_support_force_change(before, sim.contacts()),
                        progress=progress)
        return {"support_stretch": strain, "support_reaction_moment_before": moment_before,
                "support_reaction_moment": support_reaction_moment(sim), **applied}

    return run_stage(cfg, sim, ds, out, stage, what, work, extra_time=cfg.probe.stretch_time)


def _support_force_change(before, after):
    """``Σ_p |ΔF_x|`` of the support's horizontal forces on each particle, N,
    from ``before`` (its support contacts: ``i``, ``fx``) to ``after`` (all
    contacts, :meth:`sim.engine.Simulation.contacts`)."""
    on = after["j"] == BODY_SUPPORT
    n = int(max(before["i"].max(initial=-1), after["i"].max(initial=-1))) + 1
    fx = np.zeros((2, n))
    np.add.at(fx[0], before["i"], before["fx"])
    np.add.at(fx[1], after["i"][on], after["fx"][on])
    return float(np.abs(fx[1] - fx[0]).sum())
