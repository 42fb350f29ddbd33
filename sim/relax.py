"""Relaxation to rest, and a stage that runs on the pile of a state file and saves it.

The rest criterion and the relaxation drag: :func:`relax`.
"""

from __future__ import annotations

import logging
import math
import time as _time

import numpy as np

from .blowup import BlowUpError
from .checkpoint import keep_last_good
from .config import SimConfig
from .engine import Simulation
from .io import check_input_stage, lineage, load_simulation, save_state
from .progress import Progress, fixed_remaining, summary
from .run_loop import Interrupted, stop_on_signals
from .timestep import check_run, dt_source

log = logging.getLogger("sim")


class RelaxationError(RuntimeError):
    """The pile did not come to rest within ``relax.max_time``."""


def _rest_measures(sim, load):
    """What the rest criterion compares, for the load ``load`` (N) a stage settles.

    Returns
    -------
    ke : float
        Mean kinetic energy per particle over ``m g d`` (mean mass, gravity,
        mean diameter).
    vmax : float
        The largest particle speed, m/s.
    unbalanced : float
        The unbalanced force, ``sum_p |F_p + m_p g|`` (contact forces and
        gravity, drag excluded), over ``load``; 0 when ``load`` is 0.
    """
    n = sim.n
    if n == 0:
        return 0.0, 0.0, 0.0
    g = max(float(np.hypot(*sim.gravity)), 1e-12)
    m = float(np.mean(sim.shapes.mass[:n]))
    d = 2.0 * float(np.mean(sim.shapes.radius[:n]))
    ke = sim.kinetic_energy() / n / (m * g * d)
    vmax = float(np.max(np.hypot(*sim.velocity.T)))
    unbalanced = float(np.hypot(*sim.net_forces().T).sum()) / load if load > 0 else 0.0
    return ke, vmax, unbalanced


def relax(sim: Simulation, cfg: SimConfig, what="relax", load=None, progress=None):
    """Run until at rest (criterion held for ``hold_time``) or fail after ``max_time``.

    The criterion applies to the load that the stage settles: with ``s`` that
    load over the pile's weight, the pile is at rest once the kinetic energy
    per particle is below ``relax.kinetic_energy_fraction · s² · m g d``,
    every speed below ``relax.max_speed · s`` and the unbalanced force below
    ``relax.unbalanced_force · load``, all for ``relax.hold_time``.  After
    pouring the load is the weight (``s = 1``); after a gravity probe it is
    the change of weight, whose motion, speeds and out-of-balance forces are
    that much smaller, so that the increment is at rest to the same relative
    degree as the relaxed pile.

    The background drag ``relax.drag`` acts while this runs (and during a
    gravity ramp), never while pouring; once the kinetic-energy criterion
    holds, or after ``relax.drag_time``, it becomes ``relax.rocking_drag``.

    Parameters
    ----------
    sim : Simulation
    cfg : SimConfig
    what : str
        Name of the stage in log lines and errors.
    load : float, optional
        The load the stage settles, N; default: the weight under the current
        gravity.
    progress : sim.progress.Progress, optional
        The stage's progress lines, which go on here (its heartbeat, with the
        rest measures as detail); default: lines of this relaxation alone.

    Raises
    ------
    RelaxationError
        If the pile is not at rest after ``relax.max_time`` of simulated time.
    """
    weight = float(np.sum(sim.shapes.mass[:sim.n])) * float(np.hypot(*sim.gravity))
    load = weight if load is None else float(load)
    scale = load / weight if weight > 0 else 1.0
    t0 = sim.time
    if progress is None:
        progress = Progress(cfg.pour.progress_interval, fixed_remaining(t0 + cfg.relax.max_time),
                            at_most=True)
    sim.drag = cfg.relax.drag
    spin_drag, sim.spin_drag = sim.spin_drag, 0.0  # the pour's drag on rotation does not relax
    heartbeat, sim.heartbeat = sim.heartbeat, progress.heartbeat(what)
    try:
        return _relax_loop(sim, cfg, what, t0, load, scale, progress)
    finally:
        sim.drag = 0.0
        sim.spin_drag = spin_drag
        sim.heartbeat = heartbeat


def _relax_loop(sim, cfg, what, t0, load, scale, progress):
    r = cfg.relax
    ke_max = r.kinetic_energy_fraction * scale ** 2
    speed_max = r.max_speed * scale
    chunk = max(min(1e-3, r.hold_time / 5.0), sim.dt)
    rest_since = None
    while True:
        sim.run(duration=chunk)
        ke, vmax, unbalanced = _rest_measures(sim, load)
        calm = ke < ke_max
        if (calm or sim.time - t0 >= r.drag_time) and sim.drag != r.rocking_drag:
            log.info("%s: %s after %.4f s (KE per particle %.3g m g d, max speed %.3g m/s);"
                     " drag %g -> %g 1/s", what, "calm" if calm else "relax.drag_time over",
                     sim.time - t0, ke, vmax, sim.drag, r.rocking_drag)
            sim.drag = r.rocking_drag
        if calm and vmax < speed_max and unbalanced < r.unbalanced_force:
            rest_since = sim.time if rest_since is None else rest_since
            if sim.time - rest_since >= r.hold_time:
                log.info("%s: at rest after %.4f s (KE per particle %.3g m g d, max speed "
                         "%.3g m/s, unbalanced force %.3g of %.4g N)", what, sim.time - t0, ke,
                         vmax, unbalanced, load)
                return sim
        else:
            rest_since = None
        if sim.time - t0 > r.max_time:
            raise RelaxationError(
                f"{what}: not at rest after relax.max_time = {r.max_time} s of simulated "
                f"time (KE per particle {ke:.3g} m g d, max speed {vmax:.3g} m/s, "
                f"unbalanced force {unbalanced:.3g} of the {load:.4g} N load; criteria for "
                f"this stage: KE < {ke_max:.3g} m g d, speed < {speed_max:.3g} m/s from "
                f"relax.kinetic_energy_fraction = {r.kinetic_energy_fraction} and "
                f"relax.max_speed = {r.max_speed} scaled by the load, unbalanced force < "
                f"relax.unbalanced_force = {r.unbalanced_force}); raise relax.max_time or "
                "the damping")
        progress.detail = (f"KE per particle {ke:.2g} m g d, max speed {vmax:.2g} m/s, "
                           f"unbalanced force {unbalanced:.2g} of the load")


def check_stage(cfg: SimConfig, sim, what, extra_time=0.0, gravity=None):
    """Refuse a relaxation or probe whose time step cannot carry it
    (:func:`sim.timestep.check_run`), before it runs.

    Its simulated time is at most ``extra_time`` (a probe's ramp or stretch)
    plus ``relax.max_time``; its fastest particle one that keeps its speed
    and falls from the top of the pile to the support under the stronger of
    the gravity before and ``gravity`` (the contacts only dissipate); its
    drag the stronger of ``relax.drag`` and ``relax.rocking_drag``.

    Parameters
    ----------
    cfg : SimConfig
    sim : Simulation
        The pile as read from its file.
    what : str
    extra_time : float
        Simulated time before the relaxation, s.
    gravity : float, optional
        The magnitude of the gravity the stage goes to, m/s².

    Raises
    ------
    sim.config.ConfigError
        In one line naming the settings.
    """
    r = cfg.relax
    g = max(float(np.hypot(*sim.gravity)), gravity or 0.0)
    if sim.n:
        v0 = float(np.max(np.hypot(*sim.velocity.T)))
        top = max(float(np.max(sim.position[:, 1] + sim.shapes.radius[:sim.n])), 0.0)
    else:
        v0 = top = 0.0
    check_run(sim.scene, what, duration=extra_time + r.max_time,
              speed=math.hypot(v0, math.sqrt(2.0 * g * top)), drag=max(r.drag, r.rocking_drag),
              sources={
                  "duration": f"relax.max_time = {r.max_time!r} s"
                              + (f" after {extra_time!r} s of the probe" if extra_time else ""),
                  "speed": f"the pile's particles (fastest {v0:.3g} m/s, top at {top:.3g} m, "
                           f"under gravity {g:.3g} m/s^2)",
                  "drag": f"relax.drag = {r.drag!r} 1/s and relax.rocking_drag = "
                          f"{r.rocking_drag!r} 1/s",
                  "dt": dt_source(cfg.model, kept="the input file")})


def run_stage(cfg: SimConfig, sim, ds, out, stage, what, work, extra_time=0.0, gravity=None):
    """Run a stage on the pile of a state file and save it as ``stage``.

    It is first checked (:func:`check_stage`, with `extra_time` and
    `gravity`).  Its progress lines come at least every
    ``pour.progress_interval`` of wall time; on a signal
    (:func:`sim.run_loop.stop_on_signals`) it ends with one log line saying
    that nothing was saved and raises :class:`sim.run_loop.Interrupted`.

    Parameters
    ----------
    cfg : SimConfig
    sim : Simulation
        The pile, as read from the file.
    ds : xarray.Dataset
        The file (its identity carries over: :func:`sim.io.lineage`).
    out : path
        The stage's state file (written atomically).
    stage, what : str
        The stage's name in the file and in log lines.
    work : callable
        ``work(progress)`` runs the stage on ``sim`` with the stage's
        :class:`sim.progress.Progress` (``sim.heartbeat`` meanwhile); it
        returns further global attributes of the file (a dict, or None).  On
        a blow-up the last good state is kept beside ``out``
        (:func:`sim.checkpoint.keep_last_good`).
    extra_time, gravity : float
        See :func:`check_stage`.

    Returns
    -------
    Simulation
    """
    check_stage(cfg, sim, what, extra_time, gravity)
    t = _time.monotonic()
    progress = Progress(cfg.pour.progress_interval,
                        fixed_remaining(sim.time + extra_time + cfg.relax.max_time), at_most=True)
    sim.heartbeat = progress.heartbeat(what)
    # a signal that comes while the state is written lets it finish: it ends no run then
    with stop_on_signals():
        try:
            attrs = work(progress) or {}
        except BlowUpError as exc:
            keep_last_good(sim, out, cfg, exc)
            raise
        except Interrupted as exc:
            log.error("%s: stopped by %s at t = %.4f s simulated; nothing saved (%s is written "
                      "only at the end of the stage); to resume, run the same command again: it "
                      "starts the stage afresh from its input", what, exc.name, sim.time, out)
            raise
        finally:
            sim.heartbeat = None
        save_state(sim, out, cfg.to_dict(), stage=stage, **lineage(ds), **attrs)
    summary(sim, what, _time.monotonic() - t)
    return sim


def relax_file(cfg: SimConfig, input_path, out):
    """Relax the pile of a poured state file and save it as the ``relaxed`` stage.

    Raises
    ------
    sim.io.StateFileError
        For a file of another stage (a pour's checkpoint, a blow-up's last
        good state, a relaxed or probed pile), before anything runs.
    """
    sim, ds = load_simulation(input_path, cfg.model)
    check_input_stage(input_path, ds, lambda stage: stage == "poured", "python -m sim relax",
                      "a poured state (stage 'poured', written by python -m sim pour)")

    def work(progress):
        relax(sim, cfg, f"relax {ds.attrs.get('protocol', '')} seed {ds.attrs.get('seed', '')}",
              progress=progress)

    return run_stage(cfg, sim, ds, out, "relaxed", "relax", work)
