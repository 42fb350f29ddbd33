"""Pouring protocols, relaxation to rest and the gravity probe.

* **Wedge sequence (point source).**  Particles are released one at a time,
  every ``1/rate`` seconds, at ``x = 0`` plus a uniform jitter of
  ``±jitter``, at ``release_height`` above the current tip of the pile (plus
  the particle's circumradius), moving down at ``release_speed``.
* **Layered sequence (line source).**  The release point is uniform along a
  horizontal line at the same height.  Its length follows the momentary width
  of the pile's top: the horizontal extent (centre ± circumradius) of the
  settled particles whose tops lie within ``top_band`` of the highest one,
  plus ``line_margin`` on each side.  It is also kept within the flanks of a
  triangular pile of slope ``layered_slope_deg`` (20° by default, below the
  angle of repose) whose area is that of all the particles at a solid fraction
  of 0.8: at top height h the line's half-length is at most
  ``(H − h) / tan(slope)`` with H that pile's height.  Over the bare support
  the line spans the full base of that pile, so the first layer covers the
  base of the final pile and every later layer is narrower: the pile grows
  layer by layer without avalanches and its slope stays below the angle of
  repose.

A particle counts as *settled* when its speed is below 0.1 m/s; the tip is the
highest ``y + R`` of settled particles (0 on the bare support).  A release
waits while the release disc (radius ``R`` of the new particle) overlaps a
particle still in flight, so particles never start overlapping.

The shapes of a pile come from a generator seeded with ``(seed, 0)``, and the
release position and orientation of particle k from generators seeded with
``(seed, 1, k)`` and ``(seed, 2, k)``, so a pour resumed from a checkpoint
releases the same particles at the same places as the uninterrupted one.
"""

from __future__ import annotations

import logging
import math
import time as _time
from pathlib import Path

import numpy as np

from .config import ConfigError, SimConfig
from .engine import BlowUpError, Simulation
from .io import load_simulation, save_state
from .measure import angle_of_repose, mean_coordination
from .shapes import make_shapes

log = logging.getLogger("sim")

SETTLED_SPEED = 0.1
GRAVITY = 9.81


class RelaxationError(RuntimeError):
    """The pile did not come to rest within ``relax.max_time``."""


def _keep_last_good(sim, out, cfg, exc, **attrs):
    """Save the state a blow-up returned to, beside ``out``, under a name that says so."""
    path = Path(out).with_suffix(".lastgood.nc")
    save_state(sim, path, cfg.to_dict(), stage="lastgood", error=str(exc), **attrs)
    log.error("last good state (t = %.6g s) saved to %s", sim.time, path)


def pile_shapes(cfg: SimConfig, seed: int):
    """The shapes of a pile's particles, drawn reproducibly from its seed."""
    p = cfg.particles
    return make_shapes(np.random.default_rng([seed, 0]), cfg.pour.n_particles,
                       p.corners_min, p.corners_max, p.semi_axis_mean, p.semi_axis_spread,
                       cfg.model.density, p.min_edge_fraction, p.min_angle_deg)


def _settled(sim):
    v = sim.velocity
    return np.hypot(v[:, 0], v[:, 1]) < SETTLED_SPEED


def pile_top(sim):
    """Height of the tip (highest y + R of settled particles; 0 when none)."""
    if sim.n == 0:
        return 0.0
    s = _settled(sim)
    if not s.any():
        return 0.0
    return float(np.max(sim.position[s, 1] + sim.shapes.radius[:sim.n][s]))


def top_width(sim, band):
    """Extent ``(x_left, x_right)`` of the settled particles near the top, or None."""
    if sim.n == 0:
        return None
    s = _settled(sim)
    if not s.any():
        return None
    pos = sim.position[s]
    rad = sim.shapes.radius[:sim.n][s]
    top = pos[:, 1] + rad
    near = top > top.max() - band
    return float(np.min(pos[near, 0] - rad[near])), float(np.max(pos[near, 0] + rad[near]))


def target_pile(shapes, slope_deg):
    """Half base width and height of a triangular pile of all the particles.

    Its area is their total area over a solid fraction of 0.8; its flanks rise
    at ``slope_deg``.
    """
    area = float(np.sum(shapes.area)) / 0.8
    slope = math.tan(math.radians(slope_deg))
    half = math.sqrt(area / slope)
    return half, half * slope


def release_point(sim, cfg: SimConfig, protocol, seed, k):
    """Where particle k would be released now, as ``(x, y)``.

    With side walls the point lies at least one circumradius inside them.
    """
    rng = np.random.default_rng([seed, 1, k])
    radius = float(sim.shapes.radius[k])
    top = pile_top(sim)
    y = top + cfg.pour.release_height + radius
    if protocol == "wedge":
        lo, hi = -cfg.pour.jitter, cfg.pour.jitter
    else:
        half, height = target_pile(sim.shapes, cfg.pour.layered_slope_deg)
        bound = max(half * (1.0 - top / height), radius)
        extent = top_width(sim, cfg.pour.top_band)
        lo, hi = (-bound, bound) if extent is None else extent
        lo = max(lo - cfg.pour.line_margin, -bound)
        hi = min(hi + cfg.pour.line_margin, bound)
        if hi <= lo:
            lo, hi = -bound, bound
    if sim.walls is not None:
        lo = min(max(lo, sim.walls[0] + radius), sim.walls[1] - radius)
        hi = max(min(hi, sim.walls[1] - radius), lo)
    return rng.uniform(lo, hi), y


def _spot_clear(sim, x, y, radius):
    if sim.n == 0:
        return True
    pos = sim.position
    reach = sim.shapes.radius[:sim.n] + radius
    return bool(np.all(np.hypot(pos[:, 0] - x, pos[:, 1] - y) > reach))


class Progress:
    """Logs simulated time, particles, steps per second and ETA every ``interval`` s.

    Times count from the first call (a resumed pour or a relaxation starts
    at its own zero); the ETA assumes ``total`` seconds of simulated time.
    """

    def __init__(self, interval, total_time):
        self.interval = interval
        self.total = total_time
        self.t0 = _time.monotonic()
        self.last = self.t0
        self.start = None

    def __call__(self, sim, what, force=False, detail=""):
        if self.start is None:
            self.start = (sim.time, sim.step)
        now = _time.monotonic()
        if not force and now - self.last < self.interval:
            return
        self.last = now
        wall = now - self.t0
        t, steps = sim.time - self.start[0], sim.step - self.start[1]
        rate = steps / wall if wall > 0 else 0.0
        frac = min(t / self.total, 1.0) if self.total > 0 else 1.0
        eta = wall * (1 - frac) / frac if frac > 0 else float("nan")
        log.info("%s: %.4f s of %.4f s simulated (t = %.4f s), %d particles, %d steps, "
                 "%.0f steps/s, ETA %.0f s%s", what, t, self.total, sim.time, sim.n, steps,
                 rate, eta, f", {detail}" if detail else "")


def pour(cfg: SimConfig, protocol: str, seed: int, out, checkpoint=None,
         settle_time=0.1):
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
        ``pour.checkpoint_interval`` wall seconds, deleted on success.
    settle_time : float
        Simulated time after the last release before the state is saved, s.

    Returns
    -------
    Simulation
    """
    if protocol not in ("wedge", "layered"):
        raise ValueError(f"protocol = {protocol!r}: must be 'wedge' or 'layered'")
    if not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed = {seed!r}: must be a non-negative integer")
    if not cfg.physics.support:
        raise ConfigError("physics.support = false: a pile is poured onto the support; "
                          "without it the particles fall for ever (allowed: true)")
    p = cfg.pour
    shapes = pile_shapes(cfg, seed)
    checkpoint = Path(checkpoint) if checkpoint else None
    interval = 1.0 / p.rate
    next_release = 0.0
    if checkpoint is not None and checkpoint.exists():
        sim, ds = load_simulation(checkpoint, cfg.model, capacity_shapes=shapes)
        next_release = float(ds.attrs["next_release"])
        log.info("resuming %s seed %d from checkpoint %s: t = %.4f s, %d particles",
                 protocol, seed, checkpoint, sim.time, sim.n)
    else:
        phys = cfg.physics
        sim = Simulation(shapes, cfg.model, gravity=(0.0, -GRAVITY), support=phys.support,
                         walls=phys.walls, rotate=phys.rotation)
    log.info("pouring %d particles (%s, seed %d), dt = %.3g s (%s; limit %.3g s)",
             p.n_particles, protocol, seed, sim.dt, cfg.model.integrator,
             sim.bound.dt_limit)
    total = max(p.n_particles * interval - sim.time, 0.0) + settle_time
    progress = Progress(p.progress_interval, total)
    t_wall = _time.monotonic()
    last_ckpt = t_wall
    attrs = {"protocol": protocol, "seed": seed}
    try:
        while sim.n < p.n_particles:
            if sim.time >= next_release:
                k = sim.n
                x, y = release_point(sim, cfg, protocol, seed, k)
                if _spot_clear(sim, x, y, float(shapes.radius[k])):
                    theta = np.random.default_rng([seed, 2, k]).uniform(0, 2 * math.pi)
                    sim.place(k, x, y, theta, 0.0, -p.release_speed)
                    next_release += interval
                else:
                    next_release = sim.time + 0.1 * interval
            sim.run(duration=max(next_release - sim.time, sim.dt))
            progress(sim, f"pour {protocol} seed {seed}")
            if checkpoint is not None and _time.monotonic() - last_ckpt > p.checkpoint_interval:
                save_state(sim, checkpoint, cfg.to_dict(), stage="checkpoint",
                           next_release=next_release, **attrs)
                last_ckpt = _time.monotonic()
        sim.run(duration=settle_time)
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc, **attrs)
        raise
    save_state(sim, out, cfg.to_dict(), stage="poured", **attrs)
    if checkpoint is not None and checkpoint.exists():
        checkpoint.unlink()
    _summary(sim, f"pour {protocol} seed {seed}", _time.monotonic() - t_wall)
    return sim


def _summary(sim, what, wall):
    pos = sim.position
    c = sim.contacts()
    angle = angle_of_repose(pos[:, 0], pos[:, 1], sim.shapes.radius[:sim.n])
    log.info("%s done: wall %.1f s, %d steps, %d particles, t = %.4f s, angle of repose "
             "%.1f deg, mean coordination %.2f", what, wall, sim.step, sim.n, sim.time,
             angle, mean_coordination(c["i"], c["j"], sim.n))


def _rest_measures(sim):
    """Mean kinetic energy per particle over ``m g d``, and the largest speed."""
    n = sim.n
    if n == 0:
        return 0.0, 0.0
    g = max(float(np.hypot(*sim.gravity)), 1e-12)
    m = float(np.mean(sim.shapes.mass[:n]))
    d = 2.0 * float(np.mean(sim.shapes.radius[:n]))
    return sim.kinetic_energy() / n / (m * g * d), float(np.max(np.hypot(*sim.velocity.T)))


def relax(sim: Simulation, cfg: SimConfig, what="relax"):
    """Run until at rest (criterion held for ``hold_time``) or fail after ``max_time``.

    The background drag ``relax.drag`` acts while this runs (and during a
    gravity ramp), never while pouring; once the kinetic-energy criterion
    holds, or after ``relax.drag_time``, it becomes ``relax.rocking_drag``.

    Raises
    ------
    RelaxationError
        If the pile is not at rest after ``relax.max_time`` of simulated time.
    """
    r = cfg.relax
    t0 = sim.time
    sim.drag = r.drag
    try:
        return _relax_loop(sim, cfg, what, t0)
    finally:
        sim.drag = 0.0


def _relax_loop(sim, cfg, what, t0):
    r = cfg.relax
    chunk = max(min(1e-3, r.hold_time / 5.0), sim.dt)
    rest_since = None
    progress = Progress(cfg.pour.progress_interval, r.max_time)
    while True:
        sim.run(duration=chunk)
        ke, vmax = _rest_measures(sim)
        calm = ke < r.kinetic_energy_fraction
        if (calm or sim.time - t0 >= r.drag_time) and sim.drag != r.rocking_drag:
            log.info("%s: %s after %.4f s (KE per particle %.3g m g d, max speed %.3g m/s);"
                     " drag %g -> %g 1/s", what, "calm" if calm else "relax.drag_time over",
                     sim.time - t0, ke, vmax, sim.drag, r.rocking_drag)
            sim.drag = r.rocking_drag
        if ke < r.kinetic_energy_fraction and vmax < r.max_speed:
            rest_since = sim.time if rest_since is None else rest_since
            if sim.time - rest_since >= r.hold_time:
                log.info("%s: at rest after %.4f s (KE per particle %.3g J/m, max speed "
                         "%.3g m/s)", what, sim.time - t0, sim.kinetic_energy() / sim.n, vmax)
                return sim
        else:
            rest_since = None
        if sim.time - t0 > r.max_time:
            raise RelaxationError(
                f"{what}: not at rest after relax.max_time = {r.max_time} s of simulated "
                f"time (KE per particle {sim.kinetic_energy() / sim.n:.3g} J/m, max speed "
                f"{float(np.max(np.hypot(*sim.velocity.T))):.3g} m/s; criteria: "
                f"kinetic_energy_fraction = {r.kinetic_energy_fraction}, max_speed = "
                f"{r.max_speed} m/s); raise relax.max_time or the damping")
        progress(sim, what, detail=f"KE per particle {ke:.2g} m g d, max speed {vmax:.2g} m/s")


def relax_file(cfg: SimConfig, input_path, out):
    """Relax the pile of a state file and save it as the ``relaxed`` stage."""
    sim, ds = load_simulation(input_path, cfg.model)
    t = _time.monotonic()
    try:
        relax(sim, cfg, f"relax {ds.attrs.get('protocol', '')} seed {ds.attrs.get('seed', '')}")
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc)
        raise
    save_state(sim, out, cfg.to_dict(), stage="relaxed", protocol=ds.attrs.get("protocol", ""),
               seed=int(ds.attrs.get("seed", -1)))
    _summary(sim, "relax", _time.monotonic() - t)
    return sim


def probe_file(cfg: SimConfig, input_path, level, out, stage="reduced"):
    """Lower gravity by ``level`` (Δ) from a relaxed state, relax again and save.

    With ``probe.mode = "ramp"`` gravity decreases linearly over
    ``probe.ramp_time`` in 50 equal steps; with ``"step"`` at once.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level = {level!r}: the gravity reduction must be in (0, 1)")
    sim, ds = load_simulation(input_path, cfg.model)
    gx0, gy0 = sim.gravity
    t = _time.monotonic()
    try:
        sim.drag = cfg.relax.drag
        if cfg.probe.mode == "ramp":
            for s in range(1, 51):
                f = 1.0 - level * s / 50.0
                sim.set_gravity(f * gx0, f * gy0)
                sim.run(duration=cfg.probe.ramp_time / 50.0)
        sim.set_gravity((1.0 - level) * gx0, (1.0 - level) * gy0)
        relax(sim, cfg, f"probe {level:g}")
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc)
        raise
    save_state(sim, out, cfg.to_dict(), stage=stage, gravity_reduction=level,
               protocol=ds.attrs.get("protocol", ""), seed=int(ds.attrs.get("seed", -1)))
    _summary(sim, f"probe {level:g}", _time.monotonic() - t)
    return sim
