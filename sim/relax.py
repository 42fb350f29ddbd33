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
from .config import SimConfig, setting_schema
from .engine import Simulation
from .io import check_input_stage, lineage, load_simulation, save_state
from .progress import Progress, fixed_remaining, summary
from .run_loop import Interrupted, stop_on_signals
from .timestep import check_run, drag_limit, dt_source

log = logging.getLogger("sim")


class RelaxationError(RuntimeError):
    """The pile did not come to rest within ``relax.max_time``."""


#: Factor by which the energy watchdog raises the drag when the contacts feed
#: the kinetic energy (:class:`EnergyWatchdog`).
FED_DRAG_FACTOR = 4.0

#: A window of the watchdog holds at least this many chunks of steps.
WATCH_CHUNKS = 20

#: A window of the watchdog spans at least this many contact periods
#: (:func:`contact_period`): the kinetic energy sloshes with the elastic at
#: about that period, and the means over the window's halves must average it out.
WATCH_PERIODS = 20

#: A window of the watchdog spans at least this many decay times ``1/c`` of
#: the drag ``c``: under the drag alone the kinetic energy then falls by e⁻²
#: from the window's first half to its second, a factor e beyond the
#: watchdog's threshold e⁻¹ (:class:`EnergyWatchdog`), so that neither a
#: fluctuation nor the drag's own decay passes for the other.
WATCH_DECAY_TIMES = 2.0

#: Names of the bodies in the contact table (``contact_j`` < 0; below −3 the
#: polygons of a rough base).
BODY_NAMES = {-1: "the support", -2: "a wall", -3: "a wall"}


def contact_period(sim):
    """A contact period of the pile, s: ``2 pi sqrt(m / Y)`` for its heaviest
    particle ``m`` on a contact of stiffness ``Y`` (``model.youngs_modulus``,
    the stiffness scale of the contact law)."""
    if sim.n == 0:
        return 0.0
    return 2.0 * math.pi * math.sqrt(float(np.max(sim.shapes.mass[:sim.n]))
                                     / sim.model.youngs_modulus)


def watch_window(sim, least):
    """The length of an :class:`EnergyWatchdog` window for the pile's current
    drag, s: ``least``, but at least :data:`WATCH_PERIODS` contact periods
    (:func:`contact_period`) and :data:`WATCH_DECAY_TIMES` decay times of the
    drag.  A drag too weak to take a measurable share of the kinetic energy
    within ``relax.max_time`` gets a window longer than the relaxation may
    run: it is never judged."""
    window = max(float(least), WATCH_PERIODS * contact_period(sim))
    return max(window, WATCH_DECAY_TIMES / sim.drag) if sim.drag > 0.0 else window


def _rest_measures(sim, load, net):
    """What the rest criterion compares, for the load ``load`` (N) a stage settles.

    ``net`` is :meth:`sim.engine.Simulation.net_forces`.

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
    unbalanced = float(np.hypot(*net.T).sum()) / load if load > 0 else 0.0
    return ke, vmax, unbalanced


class EnergyWatchdog:
    """Does the kinetic energy fall as fast as the relaxation drag makes it?

    The drag ``c`` takes ``2 c`` of the kinetic energy per second (the force
    ``−c m v`` and torque ``−c I ω`` on every particle) and a conservative,
    damped contact law only takes more, so while the pile is not at rest its
    kinetic energy falls at least as ``exp(−2 c t)``.  Over each window of
    :attr:`window` seconds the watchdog compares the mean kinetic energy of
    the window's second half with that of its first, and a ratio above
    ``exp(−c window / 2)`` (a decay at less than half the drag's own rate)
    is energy fed when the energy balance says who feeds it: the work of the
    contacts on the particles, the change of kinetic plus gravitational
    energy plus what the drag took (``2 c KE`` per second, summed over the
    chunks), is more than half the drag's take.  So a flank that gravity
    keeps creeping (the work is gravity's) or a pile that unloads after a
    gravity probe while its motion dies away (the kinetic energy falls) is
    no finding.  A window in which the rest criteria hold is no evidence and
    starts afresh, as does one in which the drag changed.  A window is never
    shorter than the physics needs to tell a feed from a fluctuation
    (:func:`watch_window`): with a window of a few chunks of steps (a hold
    time of 1 ms or 0) the kinetic energy sloshing between the contacts
    passed for fed, blamed a particle in flight and raised the drag a
    hundredfold.

    The feed it finds in a stiff pile (``youngs_modulus`` ≥ 10⁹ N/m, docs/model.md,
    Relaxation drag): a polygon rocking on an edge, whose elastic force acts
    at the midpoint of the contact line and does net work on each rocking
    cycle; the normal damping and the drag take a fixed share per cycle of
    the contact's frequency (∝ sqrt(Y)) and of a second respectively, so a
    drag that stops the rocking at 10⁷ N/m leaves it going at 10⁹ N/m.

    Parameters
    ----------
    sim : Simulation
        The relaxing pile; its drag then is the one the window judges.
    window : float
        The least length of a window, s; each window is
        :func:`watch_window` of it for the drag it judges (attribute ``window``).
    """

    def __init__(self, sim, window):
        self.least = float(window)
        self._restart(sim)

    def _restart(self, sim):
        """Open a window at the current state."""
        self.drag = sim.drag
        self.window = watch_window(sim, self.least)
        self.start = sim.time
        self.times = []
        self.energies = []          # per particle, J/m, one row per chunk
        self.force2 = np.zeros(sim.n)
        self.momentum2 = np.zeros(sim.n)
        self.energy0 = sim.kinetic_energy() + sim.potential_energy()
        self.drag_work = 0.0

    def add(self, sim, net, at_rest):
        """Take the state after a chunk of steps; ``net`` its net forces
        (:meth:`sim.engine.Simulation.net_forces`).

        Returns
        -------
        str or None
            At the end of a window in which the contacts fed the kinetic
            energy, one sentence that names the particle carrying most of it;
            None otherwise.
        """
        if at_rest or sim.drag != self.drag:
            self._restart(sim)
            return None
        m = sim.shapes.mass[:sim.n]
        v2 = np.sum(sim.velocity ** 2, axis=1)
        self.drag_work += 2.0 * self.drag * sim.kinetic_energy() * (
            sim.time - (self.times[-1] if self.times else self.start))
        self.times.append(sim.time)
        self.energies.append(0.5 * (m * v2 + sim.shapes.inertia[:sim.n] * sim.omega ** 2))
        self.force2 += np.sum(net ** 2, axis=1)
        self.momentum2 += m * m * v2
        if sim.time - self.start < self.window or len(self.times) < WATCH_CHUNKS:
            return None
        found = self._verdict(sim)
        self._restart(sim)
        return found

    def _verdict(self, sim):
        e = np.array(self.energies)
        half = len(e) // 2
        first, second = float(e[:half].sum(axis=1).mean()), float(e[half:].sum(axis=1).mean())
        span = 0.5 * (self.times[-1] - self.times[0])
        c = self.drag
        if not first > 0.0 or second <= first * math.exp(-c * span):
            return None
        work = sim.kinetic_energy() + sim.potential_energy() - self.energy0 + self.drag_work
        if not work > 0.5 * self.drag_work:
            return None
        rate = math.log(first / second) / span if second > 0.0 else math.inf
        n = sim.n
        g = max(float(np.hypot(*sim.gravity)), 1e-12)
        mgd = float(np.mean(sim.shapes.mass[:n])) * g * 2.0 * float(np.mean(sim.shapes.radius[:n]))
        per = e[half:].mean(axis=0)
        k = int(np.argmax(per))
        hz = math.sqrt(self.force2[k] / self.momentum2[k]) / (2.0 * math.pi) \
            if self.momentum2[k] > 0.0 else 0.0
        return (f"KE held at {second / n / mgd:.3g} m g d per particle for {2 * span:.3g} s "
                f"(falling at {rate:.3g}/s where the drag of {c:g} 1/s alone takes "
                f"{2 * c:g}/s): the contacts did {work:.3g} J/m of work on the particles "
                f"({work / (2 * span):.3g} W/m); "
                f"particle {k} carries {per[k] / per.sum():.0%} of it, "
                f"{_contacts_of(sim, k)}, oscillating at about {hz:.3g} Hz")


def _contacts_of(sim, k):
    """Particle ``k``'s contacts in words, e.g. "rocking on the support (1 contact)"."""
    c = sim.contacts()
    mine = (c["i"] == k) | (c["j"] == k)
    other = np.where(c["i"][mine] == k, c["j"][mine], c["i"][mine])
    names = [BODY_NAMES.get(int(j), "the rough base") if j < 0 else f"particle {j}"
             for j in other]
    if not names:
        return "in flight (no contact)"
    if len(names) == 1:
        return f"rocking on {names[0]} (1 contact)"
    return f"in {len(names)} contacts ({', '.join(names)})"


def _stronger_drag(sim):
    """:data:`FED_DRAG_FACTOR` times the drag, at most the schema's largest
    ``relax.rocking_drag`` and no more than the time step carries
    (:func:`sim.timestep.drag_limit`); the drag itself where none is."""
    drag = sim.drag
    c = min(drag * FED_DRAG_FACTOR, float(setting_schema("relax", "rocking_drag")["maximum"]))
    while c > 1.01 * drag and drag_limit(sim.scene.bound, sim.model.integrator, c) < sim.dt:
        c = 0.5 * (c + drag)
    return c if c > 1.01 * drag else drag


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
    From then on an :class:`EnergyWatchdog` checks that the contacts feed no
    kinetic energy; where they do (a polygon rocking in a stiff pile), it
    logs one warning line naming the particle and raises the drag
    (:func:`_stronger_drag`), which vanishes at rest as the other drags do.
    The criteria are checked after each chunk of steps: a fifth of the hold
    time but no less than a contact period (:func:`contact_period`), however
    short the hold time; at most 1 ms and at least one step.

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

    Returns
    -------
    dict
        The drag actually applied, for the stage's file: ``relax_drag_max``,
        the strongest that acted, and ``relax_drag_final``, the one acting
        when the pile came to rest (1/s); the watchdog's raises make them
        differ from the settings.

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
    chunk = max(min(1e-3, max(r.hold_time / 5.0, contact_period(sim))), sim.dt)
    rest_since = watch = fed = None
    strongest = sim.drag
    while True:
        sim.run(duration=chunk)
        net = sim.net_forces()
        ke, vmax, unbalanced = _rest_measures(sim, load, net)
        calm = ke < ke_max
        if (calm or sim.time - t0 >= r.drag_time) and watch is None:
            if sim.drag != r.rocking_drag:
                log.info("%s: %s after %.4f s (KE per particle %.3g m g d, max speed %.3g m/s);"
                         " drag %g -> %g 1/s", what, "calm" if calm else "relax.drag_time over",
                         sim.time - t0, ke, vmax, sim.drag, r.rocking_drag)
                sim.drag = r.rocking_drag
                strongest = max(strongest, sim.drag)
            if sim.drag > 0.0:
                watch = EnergyWatchdog(sim, max(r.hold_time, WATCH_CHUNKS * chunk))
        at_rest = calm and vmax < speed_max and unbalanced < r.unbalanced_force
        if watch is not None:
            found = watch.add(sim, net, at_rest)
            if found:
                fed = found
                stronger = _stronger_drag(sim)
                log.warning("%s: energy fed at %.4f s: %s; drag %g -> %g 1/s%s", what,
                            sim.time - t0, found, sim.drag, stronger,
                            "" if stronger > sim.drag else " (the most the time step carries)")
                sim.drag = stronger
                strongest = max(strongest, sim.drag)
        if at_rest:
            rest_since = sim.time if rest_since is None else rest_since
            if sim.time - rest_since >= r.hold_time:
                log.info("%s: at rest after %.4f s (KE per particle %.3g m g d, max speed "
                         "%.3g m/s, unbalanced force %.3g of %.4g N)", what, sim.time - t0, ke,
                         vmax, unbalanced, load)
                return {"relax_drag_max": strongest, "relax_drag_final": sim.drag}
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
                "the damping" + (f"; last energy watchdog finding: {fed}" if fed else ""))
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
    g = max(float(np.hypot(*sim.gravity)), gravity or 0.0)
    if sim.n:
        v0 = float(np.max(np.hypot(*sim.velocity.T)))
        top = max(float(np.max(sim.position[:, 1] + sim.shapes.radius[:sim.n])), 0.0)
    else:
        v0 = top = 0.0
    check_stage_run(cfg, sim.scene, what, v0, top, g, extra_time, kept="the input file")


def check_stage_run(cfg: SimConfig, scene, what, v0, top, g, extra_time=0.0, kept=None):
    """:func:`check_stage`'s rule for a pile described by its numbers, not its state.

    Parameters
    ----------
    cfg : SimConfig
    scene : sim.scene.Scene
        The pile's particles, time step and integrator.
    what : str
        The stage, leading the message.
    v0 : float
        The fastest particle's speed, m/s.
    top : float
        The height of the pile's top above the support, m.
    g : float
        The strongest gravity of the stage, m/s².
    extra_time : float
        Simulated time before the relaxation, s.
    kept : str, optional
        Where the time step comes from when it is not the settings' own
        (:func:`sim.timestep.dt_source`).

    Raises
    ------
    sim.config.ConfigError
        In one line naming the settings.
    """
    r = cfg.relax
    check_run(scene, what, duration=extra_time + r.max_time,
              speed=math.hypot(v0, math.sqrt(2.0 * g * top)), drag=max(r.drag, r.rocking_drag),
              sources={
                  "duration": f"relax.max_time = {r.max_time!r} s"
                              + (f" after {extra_time!r} s of the probe" if extra_time else ""),
                  "speed": f"the pile's particles (fastest {v0:.3g} m/s, top at {top:.3g} m, "
                           f"under gravity {g:.3g} m/s^2)",
                  "drag": f"relax.drag = {r.drag!r} 1/s and relax.rocking_drag = "
                          f"{r.rocking_drag!r} 1/s",
                  "dt": dt_source(cfg.model, kept=kept)})


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
        return relax(sim, cfg,
                     f"relax {ds.attrs.get('protocol', '')} seed {ds.attrs.get('seed', '')}",
                     progress=progress)

    return run_stage(cfg, sim, ds, out, "relaxed", "relax", work)
