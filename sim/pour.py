"""The pour: particles released one by one from a point (wedge) or line
(layered) source (:mod:`sim.release`; the source's rate, speed and height:
:func:`sim.release.source`) onto the support, until all have landed.

The shapes of a pile come from a generator seeded with ``(seed, 0)``, and the
release orientation of particle k from one seeded with ``(seed, 2, k)``
(its position: :func:`sim.release.release_point`), so a pour resumed from a
checkpoint (:mod:`sim.checkpoint`) releases the same particles at the same
places as the uninterrupted one.  The polygons of a rough base
(``physics.rough_base``, :func:`rough_base`) come from one seeded with
``(seed, 3)``.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import socket
import time as _time
from pathlib import Path

import numpy as np

from .blowup import BlowUpError
from .checkpoint import (keep_finished, keep_last_good, remove_checkpoint, remove_temporaries,
                         resume, save_checkpoint, save_stop_checkpoint, take_finished)
from .config import ConfigError, SimConfig, setting_schema
from .engine import Simulation
from .frames import FrameRecorder, partial_path
from .io import load_simulation, save_state
from .lock import PourLock, appended_log, lock_path
from .progress import Progress, pour_remaining, summary
from .release import (LINE_DRAWS, on_table, pile_height_bound, pile_top, release_point, source,
                      spot_clear, table, target_pile, touching)
from .run_loop import Interrupted, stop_on_signals
from .scene import lay_base, make_scene
from .shapes import shapes_by_settings
from .timestep import check_run, dt_source

log = logging.getLogger("sim")

#: g0, m/s²: the gravity a pile is poured and relaxed under (the probes change it).
GRAVITY = 9.81

#: Simulated time (s) after the last release within which the particles must
#: rest on the pile (see :func:`_land`), else the pour fails.
LANDING_TIME = 1.0

#: Simulated time (s) between the checks of :func:`_land`.
LANDING_WINDOW = 0.05

#: Largest departure of the bodies' mean vertical force on a poured pile, over
#: the time since its landing began, from its weight, as a fraction of it
#: (:func:`_land`).  The mean is ``1 + ΔP_y / (t M g)`` (:func:`_carried`): 0
#: for particles falling free, and for a pile at rest 1 up to the momentum of
#: its last hops and rocking polygons, ``|ΔP_y| <= 2 m v``: one polygon of
#: three rocking at 0.5 m/s departs by 0.07 after 1 s, by 0.68 over a single
#: 0.05 s window, so the mean runs over the whole landing, not a window.
REACTION_TOLERANCE = 0.1

#: The largest seed of a pile (the smallest is 0): that of the workflow's
#: ``protocols.<protocol>.seeds`` (workflow/schemas/config.schema.yaml), well
#: within the int64 a state file stores it as (:func:`sim.digest.data_digest`).
SEED_MAX = 2**32 - 1


class LandingError(RuntimeError):
    """Poured particles did not rest on the pile :data:`LANDING_TIME` after the last release."""


def pile_shapes(cfg: SimConfig, seed: int):
    """The shapes of a pile's particles, drawn reproducibly from its seed.

    Raises
    ------
    sim.config.ConfigError
        When the ``particles`` recipe draws no valid polygon (too flat an
        ellipse for the corners' minimum angle and edge), naming the settings.
    """
    try:
        return _drawn(cfg, np.random.default_rng([seed, 0]), cfg.pour.n_particles)
    except ValueError as exc:
        q = cfg.particles
        raise ConfigError(
            f"particles: semi_axis_mean = {q.semi_axis_mean:.4g} m, semi_axis_spread = "
            f"{q.semi_axis_spread:.4g}, aspect_ratio = {q.aspect_ratio}, corners "
            f"{q.corners_min}-{q.corners_max}, min_angle_deg = {q.min_angle_deg:.4g} and "
            f"min_edge_fraction = {q.min_edge_fraction:.4g} draw no valid polygon (seed {seed}); "
            f"allowed: a recipe whose ellipses hold such polygons (a smaller semi_axis_spread "
            f"or aspect_ratio, fewer corners or a smaller min_angle_deg). The draw said: {exc}"
        ) from None


def _drawn(cfg: SimConfig, rng, n):
    """`n` polygons drawn from `rng` by the recipe of ``cfg.particles``."""
    return shapes_by_settings(rng, n, cfg.particles, cfg.model.density)


def rough_base(cfg: SimConfig, seed: int, shapes):
    """The rough base of a pile (``physics.rough_base``), or None without one.

    Its polygons are drawn by the particles' recipe from a generator seeded
    with ``(seed, 3)`` and laid side by side on the support
    (:func:`sim.scene.lay_base`) between the walls, or without walls over
    ``|x| <= L``, ``L`` the half base width of a triangular pile of all the
    particles `shapes` with flanks at ``physics.rough_base_slope_deg``
    (:func:`sim.release.target_pile`).

    Raises
    ------
    sim.config.ConfigError
        For walls beyond ``|x| = L`` at the flattest slope the setting allows,
        before a polygon is laid: no pile of these particles covers that base.
    """
    phys = cfg.physics
    if not phys.rough_base:
        return None
    if phys.walls is not None:
        lo, hi = phys.walls
        flattest = setting_schema("physics", "rough_base_slope_deg")["minimum"]
        widest = target_pile(shapes, flattest)[0]
        if max(-lo, hi) > widest:
            raise ConfigError(
                f"physics.walls = {list(phys.walls)} with physics.rough_base = true: the base "
                f"spans the walls, wider than a pile of these {len(shapes.mass)} particles with "
                f"the flattest flanks allowed ({flattest} degrees, |x| <= {widest:.3g} m), so no "
                f"pile of them covers it; allowed: walls within |x| <= {widest:.3g} m")
    else:
        hi = target_pile(shapes, phys.rough_base_slope_deg)[0]
        lo = -hi
    return lay_base(lambda rng, n: _drawn(cfg, rng, n), np.random.default_rng([seed, 3]), lo, hi,
                    cfg.model.density)


def pour(cfg: SimConfig, protocol: str, seed: int, out, checkpoint=None,
         settle_time=0.1, frames=None, run_log=None, finished=None):
    """Pour a pile from a point (wedge) or line (layered) source and save it.

    Parameters
    ----------
    cfg : SimConfig
    protocol : {"wedge", "layered"}
    seed : int
    out : path
        The ``poured`` state file (written atomically).
    checkpoint : path, optional
        Checkpoint file: resumed from if present, rewritten every
        ``pour.checkpoint_interval`` wall seconds, deleted on success.  It is
        resumed only if made for this pile by the same code (:func:`sim.io.code_version`)
        under the same settings (bookkeeping aside); otherwise, or when it
        cannot be read, it is renamed aside (``*.unused``) and the pour starts
        afresh, with a log line.  While pouring, the lock file
        ``<checkpoint>.lock`` (:class:`sim.lock.PourLock`) keeps a second process off.
    settle_time : float
        Simulated time after the last release before the state is saved, s;
        longer while particles are still in flight (see :func:`_land`).
    frames : path, optional
        Where to write the frames of a film of the pour
        (:class:`sim.frames.FrameRecorder`, one every ``pour.frame_interval``
        simulated seconds), written just before the poured state.  With a
        checkpoint, the frames so far are kept beside it
        (:func:`sim.frames.partial_path`) and resumed with it.
    run_log : path, optional
        The pile's log, kept over every run of its pour: once this run holds
        the lock, its log lines are appended to the file (:func:`sim.lock.appended_log`)
        from a line naming the process.  A run the lock refuses leaves the file
        as it is, so it never spoils the log of the pour that is running.
    finished : path, optional
        Where to keep a copy of the finished pour (its frames beside it), for a
        workflow that may delete the outputs of a pour that finished (Snakemake
        counts them incomplete when it was interrupted while the pour ran, and
        deletes them to run the pour again): written before the checkpoint is deleted
        (:func:`sim.checkpoint.keep_finished`).  A pour that finds one made for
        this pile by the same code under the same settings takes it as its
        outputs instead of pouring, with a log line; one made otherwise it
        removes (:func:`sim.checkpoint.take_finished`).

    Returns
    -------
    Simulation

    Raises
    ------
    sim.config.ConfigError
        If the time step cannot carry the pour (:func:`check_pour`), before
        anything runs.
    PourLockedError
        If a live process holds the lock.
    LandingError
        If the particles do not rest on the pile :data:`LANDING_TIME` after
        the last release (:func:`_land`).
    sim.run_loop.Interrupted
        On SIGTERM or SIGINT (:func:`sim.run_loop.stop_on_signals`), after
        writing the checkpoint and logging one line that says what it holds
        and how to resume (:func:`_stopped`); the lock is released.
    """
    if protocol not in ("wedge", "layered"):
        raise ValueError(f"protocol = {protocol!r}: must be 'wedge' or 'layered'")
    if not isinstance(seed, int) or not 0 <= seed <= SEED_MAX:
        raise ValueError(f"seed = {seed!r}: must be an integer from 0 to {SEED_MAX}")
    if not cfg.physics.support:
        raise ConfigError("physics.support = false: a pile is poured onto the support; "
                          "without it the particles fall for ever (allowed: true)")
    shapes = pile_shapes(cfg, seed)
    base = check_pour(cfg, protocol, seed, shapes, settle_time)
    checkpoint = Path(checkpoint) if checkpoint else None
    with contextlib.ExitStack() as held:
        held.enter_context(stop_on_signals())
        lock = None if checkpoint is None else held.enter_context(
            PourLock(lock_path(checkpoint),
                     stale_after=3 * cfg.pour.checkpoint_interval + 60.0))
        held.enter_context(appended_log(run_log))
        log.info("pour %s seed %d: started by process %s %d", protocol, seed,
                 socket.gethostname(), os.getpid())
        taken = None if finished is None else take_finished(cfg, protocol, seed, finished, out,
                                                            frames)
        if taken is None:
            return _pour(cfg, protocol, seed, shapes, base, out, checkpoint, settle_time, lock,
                         frames, finished)
        if checkpoint is not None:    # of a run killed after it kept the finished pour
            remove_checkpoint(checkpoint)
        return taken


def check_pour(cfg: SimConfig, protocol, seed, shapes, settle_time=0.1):
    """Refuse a pour whose time step cannot carry it (:func:`sim.timestep.check_run`).

    Its simulated time is at most the releases, ``n_particles / rate``, plus
    ``settle_time`` and :data:`LANDING_TIME`; its fastest particle one
    released at ``release_speed`` that falls from ``release_height`` (plus
    its circumradius) above the top of the pile to the support (rate, speed
    and height those of the source, :func:`sim.release.source`)
    (:func:`sim.release.pile_height_bound`, plus the top of a rough base),
    ``sqrt(v0² + 2 g h)``: the contacts only dissipate; its drag ``spin_drag``.

    Returns
    -------
    sim.scene.RoughBase or None
        The rough base it checked the pour with (:func:`rough_base`), for the
        pour to start on, so that it is laid once.

    Raises
    ------
    sim.config.ConfigError
        In one line naming the settings, before anything runs.
    """
    p = cfg.pour
    src = source(cfg, shapes, protocol, GRAVITY)
    base = rough_base(cfg, seed, shapes)
    scene = make_scene(shapes, cfg.model, cfg.physics.support, cfg.physics.walls,
                       cfg.physics.rotation, base=base)
    height = pile_height_bound(shapes, cfg.physics.walls) + (0.0 if base is None else base.top)
    fall = src.elevation + float(np.max(shapes.radius)) + height
    check_run(scene, f"pour {protocol} seed {seed}",
              duration=p.n_particles / src.rate + settle_time + LANDING_TIME,
              speed=math.hypot(src.speed, math.sqrt(2.0 * GRAVITY * fall)),
              drag=p.spin_drag, sources={
                  "duration": f"pour.n_particles = {p.n_particles} at {src.origin[0]} "
                              f"(and {settle_time + LANDING_TIME} s to settle and land)",
                  "speed": f"{src.origin[1]} and a fall from "
                           f"{src.origin[2]} above a pile up to "
                           f"{height:.3g} m high",
                  "drag": f"pour.spin_drag = {p.spin_drag!r} 1/s",
                  "dt": dt_source(cfg.model)})
    return base



def _start(cfg, protocol, seed, checkpoint, shapes, base, outputs):
    """The simulation to pour with (on the rough base ``base``, or None), its
    next release time and whether it was resumed from a usable checkpoint
    (:func:`sim.checkpoint.resume`); the temporary files a killed run left of
    the checkpoint and of ``outputs`` are removed first."""
    if checkpoint is not None:
        remove_temporaries(checkpoint, *outputs)
        resumed = resume(cfg, protocol, seed, checkpoint, shapes) if checkpoint.exists() else None
        if resumed is not None:
            return (*resumed, True)
        remove_checkpoint(checkpoint)
    phys = cfg.physics
    sim = Simulation(shapes, cfg.model, gravity=(0.0, -GRAVITY), support=phys.support,
                     walls=phys.walls, rotate=phys.rotation,
                     base=base)
    return sim, 0.0, False


def _pour(cfg, protocol, seed, shapes, base, out, checkpoint, settle_time, lock, frames,
          finished):
    """The pour itself (see :func:`pour`) on the rough base ``base`` (or None);
    ``lock`` is refreshed at each checkpoint.

    On a signal (:func:`sim.run_loop.stop_on_signals`) it writes the state
    of the last pass of its release loop as the checkpoint (where the
    periodic ones are written, so a resume retraces the uninterrupted pour),
    logs one line (:func:`_stopped`) and raises :class:`sim.run_loop.Interrupted`.
    """
    p = cfg.pour
    src = source(cfg, shapes, protocol, GRAVITY)
    interval = 1.0 / src.rate
    sim, next_release, resumed = _start(cfg, protocol, seed, checkpoint, shapes, base,
                                        (out, frames))
    half_width = table(cfg, shapes, protocol)
    recorder = (FrameRecorder(shapes, p.n_particles, p.frame_interval, half_width) if frames
                else None)
    if recorder is not None and resumed:
        recorder.resume(partial_path(checkpoint), sim.time)
    sim.spin_drag = p.spin_drag
    log.info("pouring %d particles (%s, seed %d), dt = %.3g s (%s; limit %.3g s)",
             p.n_particles, protocol, seed, sim.dt, cfg.model.integrator,
             sim.bound.dt_limit)
    what = f"pour {protocol} seed {seed}"
    progress = Progress(p.progress_interval, pour_remaining(p.n_particles, interval, settle_time),
                        total=p.n_particles)
    sim.heartbeat = progress.heartbeat(what)
    t_wall = _time.monotonic()
    last_ckpt = t_wall
    attrs = {"protocol": protocol, "seed": seed}
    # the state at the end of the release loop's last pass, or as resumed
    # (None: no checkpoint to write, or a fresh start with nothing to save)
    passed = (sim.snapshot(), next_release) if resumed else None
    try:
        while sim.n < p.n_particles:
            if sim.time >= next_release:
                next_release = _release(sim, cfg, protocol, seed, next_release, interval, src.speed)
            ahead = next_release - sim.time
            sim.run(duration=max(ahead if half_width is None else min(ahead, settle_time),
                                 sim.dt))
            if half_width is not None:
                _retire(sim, half_width)
            if recorder is not None:
                recorder(sim)
            if checkpoint is not None and _time.monotonic() - last_ckpt > p.checkpoint_interval:
                save_checkpoint(sim, checkpoint, cfg, next_release, recorder, lock, **attrs)
                last_ckpt = _time.monotonic()
            if checkpoint is not None:
                passed = (sim.snapshot(), next_release)
        sim.run(duration=settle_time)
        if half_width is not None:
            _retire(sim, half_width)
        _land(sim, src, what, cfg.model.damping, half_width)
    except BlowUpError as exc:
        keep_last_good(sim, out, cfg, exc, **attrs)
        raise
    except Interrupted as exc:
        _stopped(sim, cfg, what, exc, checkpoint, passed, recorder, lock, attrs)
        raise
    finally:
        sim.heartbeat = None
    if recorder is not None:
        recorder.finish(sim)
        recorder.save(frames, cfg.to_dict(), **attrs)
    pairs = None
    if half_width is None:
        save_state(sim, out, cfg.to_dict(), stage="poured", **attrs)
    else:
        kept = on_table(sim, half_width)
        save_state(sim, out, cfg.to_dict(), keep=kept, stage="poured", released=sim.n,
                   left_table=int(sim.n - np.sum(kept)), table_half_width=half_width, **attrs)
        log.info("%s: %d of %d particles released stay on the table |x| <= %.4g m, %d left it",
                 what, int(np.sum(kept)), sim.n, half_width, int(sim.n - np.sum(kept)))
        sim, kept_state = load_simulation(out)
        pairs = (kept_state["contact_i"].values, kept_state["contact_j"].values)
    if finished is not None:
        keep_finished(finished, out, frames)
    if checkpoint is not None:
        remove_checkpoint(checkpoint)
    summary(sim, f"pour {protocol} seed {seed}", _time.monotonic() - t_wall, pairs)
    return sim


def _stopped(sim, cfg, what, exc, checkpoint, passed, recorder, lock, attrs):
    """A pour ended by a signal: write the checkpoint of the state ``passed``
    (``(snapshot, next release)`` of the release loop's last pass, or None)
    and log the one line that says what it holds and how to resume."""
    p = cfg.pour
    if checkpoint is None:
        log.error("%s: stopped by %s at t = %.4f s simulated, %d of %d particles released; "
                  "nothing saved (no --checkpoint): run the command again to pour afresh",
                  what, exc.name, sim.time, sim.n, p.n_particles)
        return
    if passed is None:
        log.error("%s: stopped by %s before the first pass of its release loop; nothing saved: "
                  "run the command again to pour afresh", what, exc.name)
        return
    sim.restore(passed[0])
    if not save_stop_checkpoint(sim, checkpoint, cfg, passed[1], recorder, lock, exc.name,
                                **attrs):
        return
    log.error("%s: stopped by %s; checkpoint %s holds t = %.4f s simulated, %d of %d particles "
              "released; to resume, run the same command again (with --checkpoint %s)",
              what, exc.name, checkpoint, sim.time, sim.n, p.n_particles, checkpoint)


def _release(sim, cfg, protocol, seed, next_release, interval, speed):
    """Release the next particle, moving down at `speed`, at the first clear
    spot of its candidates (:func:`sim.release.release_point`: one for a point
    source, :data:`sim.release.LINE_DRAWS` along a line); returns the time of
    the release after it (sooner when no spot was clear and this one waits).
    A release point lower than a circumradius above the top of a rough base
    is raised to that height."""
    k = sim.n
    radius = float(sim.shapes.radius[k])
    draws = 1 if protocol == "wedge" else LINE_DRAWS
    for x, y in release_point(sim, cfg, protocol, seed, k, draws):
        if sim.base is not None:
            y = max(y, sim.base.top + radius)
        if spot_clear(sim, x, y, radius):
            theta = np.random.default_rng([seed, 2, k]).uniform(0, 2 * math.pi)
            sim.place(k, x, y, theta, 0.0, -speed)
            return next_release + interval
    return sim.time + 0.1 * interval


def _in_flight(sim, elevation, pile):
    """Mask of the particles in flight: touching nothing (no contact with a
    particle or body), with the energy to rise above their release height
    (``y + |v|²/2g`` above the top of the `pile` (a mask) plus the source's
    `elevation` plus their circumradius).  A polygon hopping on the support or
    rolling down the flank is not in flight; one bounced off the pile is."""
    g = max(float(np.hypot(*sim.gravity)), 1e-12)
    reach = sim.position[:, 1] + np.sum(sim.velocity ** 2, axis=1) / (2.0 * g)
    release = pile_top(sim, pile) + elevation + sim.shapes.radius[:sim.n]
    return ~touching(sim) & (reach > release)


def _carried(sim, vy, window, among):
    """The bodies' (support, walls, rough base) mean vertical force on the
    particles `among` (a mask) over the last `window` s of simulated time,
    over their weight; `vy` their vertical velocities `window` s ago.

    By the particles' momentum balance (the forces between them cancel;
    gravity is the only other force on them) the mean force is
    ``M g + ΔP_y / window``, with ``P_y`` their vertical momentum: 1 for a
    pile at rest on the bodies, whatever its vibrations and hops (the mean of
    a bounce's impacts is the weight), 0 for particles in free fall.
    """
    mass = sim.shapes.mass[:sim.n][among]
    change = float(mass @ (sim.velocity[among, 1] - vy[among]))
    return 1.0 + change / (window * float(np.hypot(*sim.gravity)) * float(np.sum(mass)))


def _land(sim, src, what, damping, half_width=None):
    """Run on, in windows of :data:`LANDING_WINDOW` s, until the particles
    rest on the pile: none is in flight (:func:`_in_flight` above the source
    `src`) and the bodies carried the pile's weight since the landing began to
    :data:`REACTION_TOLERANCE` (:func:`_carried`); for at most
    :data:`LANDING_TIME` s of simulated time (`damping`: ``model.damping``,
    for the message).  On a table of `half_width` the pile is the particles
    on it, and those that leave it are parked after each window (:func:`_retire`).

    Raises
    ------
    LandingError
        Naming how many particles are still in flight, what the bodies carried,
        and how fast and high the particles are.
    """
    t0 = sim.time
    vy = sim.velocity[:, 1].copy()
    while True:
        sim.run(duration=LANDING_WINDOW)
        pile = np.ones(sim.n, bool) if half_width is None else on_table(sim, half_width)
        carried = _carried(sim, vy, sim.time - t0, pile)
        flying = int(np.sum(_in_flight(sim, src.elevation, pile)))
        if half_width is not None:
            _retire(sim, half_width)
        if flying == 0 and abs(carried - 1.0) <= REACTION_TOLERANCE:
            return
        if sim.time - t0 >= LANDING_TIME:
            speed = np.hypot(*sim.velocity.T)
            raise LandingError(
                f"{what}: {flying} of {sim.n} particles are still in flight and the bodies "
                f"carried {carried:.3g} of the weight over the last {sim.time - t0:.3g} s (allowed "
                f"1 ± {REACTION_TOLERANCE}) {LANDING_TIME} s after the last release (fastest "
                f"{float(speed.max()):.3g} m/s, highest at y = "
                f"{float(sim.position[:, 1].max()):.3g} m): they do not rest on the pile; lower "
                f"{src.origin[1]} or {src.origin[2]}, or raise model.damping = {damping}")


#: Distance (m) beyond a table's edge of its parking lot (:func:`_retire`):
#: a particle that left the table is parked at the end of the run in which it
#: left (on a table a run lasts at most the pour's ``settle_time``, 0.1 s), in
#: which one rolling off a
#: flank (at most sqrt(2 g H), 2.4 m/s off a pile 0.3 m high) goes less than
#: half of it, so it never reaches the parked ones.
PARK_MARGIN = 0.5


def rest_pose(shapes, k):
    """Orientation (rad) and centre height (m) of particle k lying at rest on
    the support on its edge nearest its centre of mass.

    That edge's line is the nearest supporting line of the polygon, so the
    foot of the perpendicular from the centre lies within the edge: the
    polygon stands on it, stable.
    """
    x, y = shapes.corners(k)
    ex, ey = np.roll(x, -1) - x, np.roll(y, -1) - y
    length = np.hypot(ex, ey)
    nx, ny = ey / length, -ex / length        # outward normals (corners counter-clockwise)
    distance = x * nx + y * ny
    e = int(np.argmin(distance))
    return -0.5 * math.pi - math.atan2(ny[e], nx[e]), float(distance[e])


def _retire(sim, half_width):
    """Park the particles whose centre has left the table ``|x| <= half_width``.

    Each is placed at rest (:func:`rest_pose`) on the support beyond the edge
    it left by, in the next slot of that side's row, which starts
    :data:`PARK_MARGIN` beyond the edge and holds one particle every
    ``2.2 R_max``, so parked particles touch nothing.  The parked particles
    keep their indices (a resumed pour retraces the uninterrupted one) and
    are those beyond ``half_width + PARK_MARGIN / 2``, so the slots taken are
    read from the state itself.
    """
    x = sim.position[:, 0]
    parked = np.abs(x) > half_width + 0.5 * PARK_MARGIN
    leaving = np.flatnonzero((np.abs(x) > half_width) & ~parked)
    spacing = 2.2 * float(np.max(sim.shapes.radius))
    for k in leaving:
        side = math.copysign(1.0, x[k])
        slot = int(np.sum(parked & (np.sign(x) == side)))
        theta, height = rest_pose(sim.shapes, k)
        sim.place(int(k), side * (half_width + PARK_MARGIN + slot * spacing),
                  height * (1.0 + 1e-9), theta)
        parked[k] = True
        x[k] = side * (half_width + PARK_MARGIN)
