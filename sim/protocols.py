"""Pouring protocols, relaxation to rest, the gravity probes and the support stretch.

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

import contextlib
import json
import logging
import math
import os
import socket
import time as _time
from pathlib import Path

import numpy as np

from .config import ConfigError, SimConfig, result_settings
from .durations import hms
from .blowup import BlowUpError
from .engine import Simulation
from .scene import BODY_SUPPORT
from .frames import FrameRecorder, partial_path
from .io import StateFileError, code_version, load_simulation, save_state
from .measure import angle_of_repose, mean_coordination
from .shapes import make_shapes

log = logging.getLogger("sim")

SETTLED_SPEED = 0.1
GRAVITY = 9.81


class RelaxationError(RuntimeError):
    """The pile did not come to rest within ``relax.max_time``."""


class LandingError(RuntimeError):
    """Poured particles were still in flight :data:`LANDING_TIME` after the last release."""


class PourLockedError(RuntimeError):
    """Another live process is pouring the same pile."""


#: The configuration sections a pour reads; a checkpoint is resumed only under
#: the same result-relevant settings of these.
POUR_SECTIONS = ("model", "particles", "pour", "physics")

#: Simulated time (s) after the last release within which every particle must
#: have landed (see :func:`_in_flight`), else the pour fails.
LANDING_TIME = 1.0


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
    """Logs a progress line of a run every ``interval`` s of wall time.

    A pour's line reads, e.g., ``pour wedge seed 3: released 2743 of 3500
    (78 %), ETA 0:06:37; t = 31.9000 s simulated, about 3.2000 s to go,
    4705393 steps, 1100 ns per particle-step``; a relaxation's (no `total`)
    ``relax wedge seed 3: ETA at most 0:02:00; t = 0.4000 s simulated, at
    most 9.6000 s to go, 3500 particles, ...`` and its `detail`.  The ns per
    particle-step are the wall time since the start over the particle-steps
    run since.

    The run starts at the first call, after its first chunk of steps: the
    start-up before it (reading or building the pile, compiling the kernels
    on their first call) is not part of the rate.  The ETA (``h:mm:ss``,
    :func:`sim.durations.hms`; ``unknown`` before any step was timed) is the
    steps and particle-steps still to do at the wall time per step and per
    particle-step that the chunks since that start took (:meth:`rates`).  A
    step costs both: a growing pile costs more per simulated second at its
    end than at its start, so extrapolating simulated time alone would
    promise too early an end; but a small pile's step costs about the same
    with 5 or 150 particles (the cost of a step itself: launching its
    kernels, threads), so extrapolating particle-steps alone would promise
    far too late an end (a 150-particle pour of 4 min wall time, which
    its particle-steps put at 10 to 40 min over its first third).

    Parameters
    ----------
    interval : float
        Wall-clock seconds between lines, the first one `interval` after the
        start.
    remaining : callable
        ``remaining(sim)`` -> (simulated s, particle-s) still to come: the
        simulated time left and its integral of the particle count.
    at_most : bool
        The run may end earlier (a relaxation stops once at rest): the line
        says "at most" instead of "about".
    total : int, optional
        The particles the run releases (a pour): the line says how many of
        them are released and what per cent (rounded down, so 100 % only
        once all are) instead of the particle count.
    clock : callable
        Wall clock, s, read at every call (default :func:`time.monotonic`).
    """

    def __init__(self, interval, remaining, at_most=False, total=None, clock=_time.monotonic):
        self.interval = interval
        self.remaining = remaining
        self.at_most = at_most
        self.total = total
        self.clock = clock
        self.last = None   # wall time of the previous line (or the start)
        self.before = None  # (wall time, step) of the previous call
        # Sums over the chunks since the start, chunk c with s steps of n
        # particles in t s: s, n s, n² s, t, n t.
        self.steps = self.work = self.work_n = self.wall = self.wall_n = 0.0

    def __call__(self, sim, what, detail=""):
        """Count the chunk of steps run since the previous call (by as many
        particles as there are now: particles are only added between chunks)
        and log a line (:meth:`line`) when ``interval`` has passed since the
        previous one."""
        now = self.clock()
        if self.before is None:
            self.last = now
        else:
            steps, wall = sim.step - self.before[1], now - self.before[0]
            self.steps += steps
            self.work += sim.n * steps
            self.work_n += sim.n ** 2 * steps
            self.wall += wall
            self.wall_n += sim.n * wall
        self.before = (now, sim.step)
        if now - self.last < self.interval:
            return
        self.last = now
        log.info("%s", self.line(sim, what, detail))

    def rates(self):
        """Wall seconds per step and per particle-step of the chunks since the start.

        The least-squares fit, neither rate negative, of each chunk's wall
        time ``t`` by ``a s + b n s`` (``s`` steps of ``n`` particles),
        weighting the chunk by ``1/s`` (its time is the sum of its steps'),
        so that either rate alone is the wall time since the start over the
        steps (``a``) or, with a constant ``n``, the particle-steps (``b``)
        since.  With one particle count only (a relaxation) the two cannot
        be told apart: all is ``b``.

        Returns
        -------
        (float, float)
            ``a`` (s per step) and ``b`` (s per particle-step); both NaN
            before any step was timed.
        """
        s_ss, s_sp, s_pp, s_ts, s_tp = self.steps, self.work, self.work_n, self.wall, self.wall_n
        if s_ss <= 0 or s_pp <= 0:
            return math.nan, math.nan
        det = s_ss * s_pp - s_sp ** 2  # >= 0, 0 for one particle count only
        if det <= 1e-9 * s_ss * s_pp:
            return 0.0, s_ts / s_sp
        a, b = (s_pp * s_ts - s_sp * s_tp) / det, (s_ss * s_tp - s_sp * s_ts) / det
        if a >= 0 and b >= 0:
            return a, b
        # One rate is 0: the fit of the other that leaves the smaller residual.
        if s_ts ** 2 / s_ss > s_tp ** 2 / s_pp:
            return s_ts / s_ss, 0.0
        return 0.0, s_tp / s_pp

    def eta(self, sim):
        """Wall seconds still to go: the steps and particle-steps to come
        (``remaining``) at :meth:`rates`; NaN before any step was timed."""
        a, b = self.rates()
        left, particle_seconds = self.remaining(sim)
        return (a * left + b * particle_seconds) / sim.dt

    def line(self, sim, what, detail=""):
        """The progress line of `sim` now (see the class).

        Parameters
        ----------
        sim : Simulation
        what : str
            Name of the run, leading the line.
        detail : str
            Appended to the line after a comma.

        Returns
        -------
        str
        """
        bound = "at most" if self.at_most else "about"
        eta = self.eta(sim)
        cost = self.wall / self.work if self.work > 0 else math.nan  # s per particle-step
        head = f"{what}: "
        if self.total:
            head += (f"released {sim.n} of {self.total} "
                     f"({math.floor(100 * sim.n / self.total)} %), ")
        head += f"ETA {'at most ' if self.at_most and math.isfinite(eta) else ''}{hms(eta)}"
        counts = [f"t = {sim.time:.4f} s simulated", f"{bound} {self.remaining(sim)[0]:.4f} s to go"]
        if not self.total:
            counts.append(f"{sim.n} particles")
        counts += [f"{sim.step} steps", f"{1e9 * cost:.0f} ns per particle-step"]
        return f"{head}; {', '.join(counts)}{f', {detail}' if detail else ''}"


def pour_remaining(n_particles, interval, settle_time):
    """``remaining(sim)`` of :class:`Progress` for a pour.

    The particles not yet released come one per ``interval`` after the next
    release is due, then ``settle_time`` follows; releases held back because
    the source is not clear (``_spot_clear``) make the real pour longer, which
    each line's estimate takes in as it comes.
    """
    def remaining(sim):
        to_release = n_particles - sim.n
        feed = to_release * interval
        return feed + settle_time, sim.n * feed + 0.5 * to_release * feed + n_particles * settle_time
    return remaining


def fixed_remaining(end_time):
    """``remaining(sim)`` of :class:`Progress` for a run of the particles there are until ``end_time``."""
    def remaining(sim):
        left = max(end_time - sim.time, 0.0)
        return left, sim.n * left
    return remaining


def pour(cfg: SimConfig, protocol: str, seed: int, out, checkpoint=None,
         settle_time=0.1, frames=None, run_log=None):
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
        resumed only if made for this pile by the same code (:func:`code_version`)
        under the same settings (bookkeeping aside); otherwise, or when it
        cannot be read, it is renamed aside (``*.unused``) and the pour starts
        afresh, with a log line.  While pouring, the lock file
        ``<checkpoint>.lock`` (:class:`PourLock`) keeps a second process off.
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
        the lock, its log lines are appended to the file (:func:`appended_log`)
        from a line naming the process.  A run the lock refuses leaves the file
        as it is, so it never spoils the log of the pour that is running.

    Returns
    -------
    Simulation

    Raises
    ------
    PourLockedError
        If a live process holds the lock.
    LandingError
        If particles are still in flight :data:`LANDING_TIME` after the last release.
    """
    if protocol not in ("wedge", "layered"):
        raise ValueError(f"protocol = {protocol!r}: must be 'wedge' or 'layered'")
    if not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed = {seed!r}: must be a non-negative integer")
    if not cfg.physics.support:
        raise ConfigError("physics.support = false: a pile is poured onto the support; "
                          "without it the particles fall for ever (allowed: true)")
    checkpoint = Path(checkpoint) if checkpoint else None
    with contextlib.ExitStack() as held:
        lock = None if checkpoint is None else held.enter_context(
            PourLock(checkpoint.with_name(checkpoint.name + ".lock"),
                     stale_after=3 * cfg.pour.checkpoint_interval + 60.0))
        held.enter_context(appended_log(run_log))
        log.info("pour %s seed %d: started by process %s %d", protocol, seed,
                 socket.gethostname(), os.getpid())
        return _pour(cfg, protocol, seed, out, checkpoint, settle_time, lock, frames)


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


def _set_aside(checkpoint, reason):
    """Rename an unusable checkpoint out of the way (kept for inspection) and log why."""
    aside = checkpoint.with_name(f"{checkpoint.name}.{_time.strftime('%Y%m%dT%H%M%S')}.unused")
    os.replace(checkpoint, aside)
    log.warning("checkpoint %s %s; set aside as %s, pouring afresh", checkpoint, reason, aside)


def _resume(cfg, protocol, seed, checkpoint, shapes):
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
        _set_aside(checkpoint, f"is unusable ({exc})")
        return None
    now = {"protocol": protocol, "seed": seed, "code version": code_version(),
           "configuration": cfg.result_dict(POUR_SECTIONS)}
    differ = [key for key in now if made[key] != now[key]]
    if differ:
        _set_aside(checkpoint, f"was made with another {' and '.join(differ)}")
        return None
    log.info("resuming %s seed %d from checkpoint %s: t = %.4f s, %d particles",
             protocol, seed, checkpoint, sim.time, sim.n)
    return sim, next_release


def _pour(cfg, protocol, seed, out, checkpoint, settle_time, lock, frames):
    """The pour itself (see :func:`pour`); ``lock`` is refreshed at each checkpoint."""
    p = cfg.pour
    shapes = pile_shapes(cfg, seed)
    interval = 1.0 / p.rate
    resumed = None
    if checkpoint is not None:
        # temporary files of checkpoints (and their frames) whose writer was
        # killed (we hold the lock)
        for name in (checkpoint.name, partial_path(checkpoint).name):
            for stale in checkpoint.parent.glob(f".{name}.*.tmp"):
                stale.unlink()
        if checkpoint.exists():
            resumed = _resume(cfg, protocol, seed, checkpoint, shapes)
    recorder = FrameRecorder(shapes, p.n_particles, p.frame_interval) if frames else None
    if resumed is not None:
        sim, next_release = resumed
        if recorder is not None:
            recorder.resume(partial_path(checkpoint), sim.time)
    else:
        if checkpoint is not None:
            partial_path(checkpoint).unlink(missing_ok=True)
        phys = cfg.physics
        sim = Simulation(shapes, cfg.model, gravity=(0.0, -GRAVITY), support=phys.support,
                         walls=phys.walls, rotate=phys.rotation)
        next_release = 0.0
    sim.spin_drag = p.spin_drag
    log.info("pouring %d particles (%s, seed %d), dt = %.3g s (%s; limit %.3g s)",
             p.n_particles, protocol, seed, sim.dt, cfg.model.integrator,
             sim.bound.dt_limit)
    progress = Progress(p.progress_interval, pour_remaining(p.n_particles, interval, settle_time),
                        total=p.n_particles)
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
            if recorder is not None:
                recorder(sim)
            if checkpoint is not None and _time.monotonic() - last_ckpt > p.checkpoint_interval:
                if recorder is not None:
                    recorder.save(partial_path(checkpoint), cfg.to_dict(), **attrs)
                save_state(sim, checkpoint, cfg.to_dict(), stage="checkpoint",
                           next_release=next_release, **attrs)
                if lock is not None:
                    lock.refresh()
                last_ckpt = _time.monotonic()
        sim.run(duration=settle_time)
        _land(sim, cfg, f"pour {protocol} seed {seed}")
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc, **attrs)
        raise
    if recorder is not None:
        recorder.finish(sim)
        recorder.save(frames, cfg.to_dict(), **attrs)
    save_state(sim, out, cfg.to_dict(), stage="poured", **attrs)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
        partial_path(checkpoint).unlink(missing_ok=True)
    _summary(sim, f"pour {protocol} seed {seed}", _time.monotonic() - t_wall)
    return sim


def _in_flight(sim, cfg):
    """Mask of the particles in flight: touching nothing (no contact with a
    particle or body), with the energy to rise above their release height
    (``y + |v|²/2g`` above the pile's top plus ``release_height`` plus their
    circumradius).  A polygon hopping on the support or rolling down the
    flank is not in flight; one bounced off the pile is."""
    c = sim.contacts()
    touching = np.zeros(sim.n, bool)
    touching[c["i"]] = True
    touching[c["j"][c["j"] >= 0]] = True
    g = max(float(np.hypot(*sim.gravity)), 1e-12)
    reach = sim.position[:, 1] + np.sum(sim.velocity ** 2, axis=1) / (2.0 * g)
    release = pile_top(sim) + cfg.pour.release_height + sim.shapes.radius[:sim.n]
    return ~touching & (reach > release)


def _land(sim, cfg, what):
    """Run on until no particle is in flight (:func:`_in_flight`), at most
    :data:`LANDING_TIME` s of simulated time.

    Raises
    ------
    LandingError
        Naming how many particles are still in flight and how fast they move.
    """
    t0 = sim.time
    while np.any(flying := _in_flight(sim, cfg)):
        if sim.time - t0 >= LANDING_TIME:
            speed = np.hypot(*sim.velocity.T)
            raise LandingError(
                f"{what}: {int(np.sum(flying))} of {sim.n} particles are still in flight "
                f"{LANDING_TIME} s after the last release (fastest {float(speed.max()):.3g} "
                f"m/s, highest at y = {float(sim.position[:, 1].max()):.3g} m): they bounce "
                f"off the pile; lower pour.release_speed = {cfg.pour.release_speed} m/s or "
                f"pour.release_height = {cfg.pour.release_height} m, or raise "
                f"model.damping = {cfg.model.damping}")
        sim.run(duration=0.01)


def _summary(sim, what, wall):
    pos = sim.position
    c = sim.contacts()
    angle = angle_of_repose(pos[:, 0], pos[:, 1], sim.shapes.radius[:sim.n])
    log.info("%s done: wall %.1f s, %d steps, %d particles, t = %.4f s, angle of repose "
             "%.1f deg, mean coordination %.2f", what, wall, sim.step, sim.n, sim.time,
             angle, mean_coordination(c["i"], c["j"], sim.n))


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


def relax(sim: Simulation, cfg: SimConfig, what="relax", load=None):
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

    Raises
    ------
    RelaxationError
        If the pile is not at rest after ``relax.max_time`` of simulated time.
    """
    weight = float(np.sum(sim.shapes.mass[:sim.n])) * float(np.hypot(*sim.gravity))
    load = weight if load is None else float(load)
    scale = load / weight if weight > 0 else 1.0
    t0 = sim.time
    sim.drag = cfg.relax.drag
    spin_drag, sim.spin_drag = sim.spin_drag, 0.0  # the pour's drag on rotation does not relax
    try:
        return _relax_loop(sim, cfg, what, t0, load, scale)
    finally:
        sim.drag = 0.0
        sim.spin_drag = spin_drag


def _relax_loop(sim, cfg, what, t0, load, scale):
    r = cfg.relax
    ke_max = r.kinetic_energy_fraction * scale ** 2
    speed_max = r.max_speed * scale
    chunk = max(min(1e-3, r.hold_time / 5.0), sim.dt)
    rest_since = None
    progress = Progress(cfg.pour.progress_interval, fixed_remaining(t0 + r.max_time), at_most=True)
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
        progress(sim, what, detail=f"KE per particle {ke:.2g} m g d, max speed {vmax:.2g} "
                 f"m/s, unbalanced force {unbalanced:.2g} of the load")


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


#: Stages of state files that are not at rest, so that no probe starts from them.
NOT_AT_REST = ("poured", "checkpoint")


def change_gravity(cfg: SimConfig, input_path, target, out, stage, what, **attrs):
    """Change gravity of a state at rest to ``target(g)``, relax again and save.

    With ``probe.mode = "ramp"`` gravity goes linearly to `target` over
    ``probe.ramp_time`` in 50 equal steps; with ``"step"`` at once.  The pile
    then relaxes to the rest criterion of the increment: :func:`relax` with
    the change of weight, ``M |Δg|``, as the load.

    Parameters
    ----------
    cfg : SimConfig
    input_path : path
        A state at rest (``relaxed``, or ``reduced`` for the restoring probe).
    target : callable
        The new gravity vector (m/s²) from the state's gravity vector ``g``.
    out : path
        The probe's state file (written atomically).
    stage : str
        Its stage name.
    what : str
        Name of the probe in log lines.
    **attrs
        Further global attributes of the state file.

    Raises
    ------
    ValueError
        If the input's stage is one of :data:`NOT_AT_REST` (a poured pile or a
        pour's checkpoint), before anything runs.
    """
    sim, ds = load_simulation(input_path, cfg.model)
    if ds.attrs.get("stage") in NOT_AT_REST:
        raise ValueError(f"{input_path}: its stage is {ds.attrs['stage']!r}, a state not at rest; a probe "
                         "changes gravity of a state at rest: a relaxed state (python -m sim relax) or a "
                         "probe's state")
    g_start = np.array(sim.gravity, float)
    g_end = np.array(target(g_start), float)
    t = _time.monotonic()
    try:
        sim.drag = cfg.relax.drag
        if cfg.probe.mode == "ramp":
            for s in range(1, 51):
                sim.set_gravity(*(g_start + (g_end - g_start) * s / 50.0))
                sim.run(duration=cfg.probe.ramp_time / 50.0)
        sim.set_gravity(*g_end)
        mass = float(np.sum(sim.shapes.mass[:sim.n]))
        relax(sim, cfg, what, load=mass * float(np.hypot(*(g_end - g_start))))
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc)
        raise
    save_state(sim, out, cfg.to_dict(), stage=stage, protocol=ds.attrs.get("protocol", ""),
               seed=int(ds.attrs.get("seed", -1)), **attrs)
    _summary(sim, what, _time.monotonic() - t)
    return sim


def probe_file(cfg: SimConfig, input_path, level, out, stage="reduced"):
    """Lower gravity by ``level`` (Δ) from a relaxed state to (1 − Δ) g and relax
    again (:func:`change_gravity`); the stage records ``gravity_reduction``."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"level = {level!r}: the gravity reduction must be in (0, 1)")
    return change_gravity(cfg, input_path, lambda g: (1.0 - level) * g, out, stage,
                          f"probe {level:g}", gravity_reduction=level)


def tilt_file(cfg: SimConfig, input_path, tilt, out, stage):
    """Add a horizontal component ``tilt · |g|`` to the gravity of a relaxed state
    and relax again (:func:`change_gravity`); the stage records ``gravity_tilt``."""
    if not (0.0 < abs(tilt) < 0.5):
        raise ValueError(f"tilt = {tilt!r}: the tilt of gravity must be in (-0.5, 0.5), not 0")
    return change_gravity(cfg, input_path, lambda g: g + (tilt * float(np.hypot(*g)), 0.0), out,
                          stage, f"tilt {tilt:+g}", gravity_tilt=tilt)


def restore_file(cfg: SimConfig, input_path, out, stage="restored"):
    """Restore full gravity ``(0, −g0)`` (:data:`GRAVITY`) from a reduced state and
    relax again (:func:`change_gravity`); the part of the strain increment
    that comes back is the elastic part."""
    return change_gravity(cfg, input_path, lambda g: (0.0, -GRAVITY), out, stage, "restore",
                          gravity_reduction=0.0)


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
        For a strain outside that range, a state not at rest, a scene without
        the support or a frictionless support, before anything runs.
    """
    strain = float(strain)
    if not (0.0 < abs(strain) < 0.01):
        raise ValueError(f"stretch = {strain!r}: the support's strain must be in (-0.01, 0.01), not 0")
    sim, ds = load_simulation(input_path, cfg.model)
    if ds.attrs.get("stage") in NOT_AT_REST:
        raise ValueError(f"{input_path}: its stage is {ds.attrs['stage']!r}, a state not at rest; the "
                         "support stretch starts from a state at rest (a relaxed state)")
    if BODY_SUPPORT not in sim.body_ids:
        raise ValueError(f"{input_path}: the scene has no support to stretch (physics.support = false)")
    if not sim.model.support_friction > 0.0:
        raise ValueError(f"model.support_friction = {sim.model.support_friction}: the stretched support "
                         "drags the particles only through friction; give it > 0")
    what = f"stretch {strain:+g}"
    t = _time.monotonic()
    on = ds["contact_j"].values == BODY_SUPPORT
    before = {"i": ds["contact_i"].values[on].astype(np.int64), "fx": ds["force_x"].values[on]}
    moment_before = float(np.sum(ds["contact_x"].values[on] * before["fx"]))
    try:
        sim.drag = cfg.relax.drag
        chunk = cfg.probe.stretch_time / STRETCH_INCREMENTS
        for _ in range(STRETCH_INCREMENTS):
            # a chunk first: the increment moves the springs of the contacts of
            # the last force evaluation, which a state read from a file has not had
            sim.run(duration=chunk)
            sim.stretch_body(BODY_SUPPORT, strain / STRETCH_INCREMENTS)
        load = _support_force_change(before, sim.contacts())
        relax(sim, cfg, what, load=load)
    except BlowUpError as exc:
        _keep_last_good(sim, out, cfg, exc)
        raise
    save_state(sim, out, cfg.to_dict(), stage=stage, protocol=ds.attrs.get("protocol", ""),
               seed=int(ds.attrs.get("seed", -1)), support_stretch=strain,
               support_reaction_moment_before=moment_before,
               support_reaction_moment=support_reaction_moment(sim))
    _summary(sim, what, _time.monotonic() - t)
    return sim


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
