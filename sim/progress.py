"""Progress logging: a run's progress lines with their remaining-time
estimates (:class:`Progress`), and the summary line of a finished stage."""

from __future__ import annotations

import logging
import math
import resource
import time as _time

from .durations import hms
from .measure import angle_of_repose, mean_coordination

log = logging.getLogger("sim")


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

    A run calls it after each chunk of steps through :meth:`heartbeat`.

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

    Attributes
    ----------
    detail : str
        What the lines of :meth:`heartbeat` end with (a relaxation's rest
        measures); empty at first.
    """

    def __init__(self, interval, remaining, at_most=False, total=None, clock=_time.monotonic):
        self.interval = interval
        self.remaining = remaining
        self.at_most = at_most
        self.total = total
        self.clock = clock
        self.detail = ""    # what :meth:`heartbeat`'s lines end with
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

    def heartbeat(self, what):
        """A ``sim.heartbeat`` (:func:`sim.run_loop.run`) that calls this
        object after every chunk of steps, with `what` and the current
        :attr:`detail`: a line at least every ``interval`` of wall time
        however long one ``sim.run`` lasts (beyond that, by at most one chunk
        of steps: 1 ms of simulated time)."""
        return lambda sim: self(sim, what, self.detail)

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
    the source is not clear (:func:`sim.release.spot_clear`) make the real pour longer, which
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


def summary(sim, what, wall, contacts=None):
    """Log the summary line of a finished stage `what` of `sim` after `wall` s of wall time.

    Parameters
    ----------
    sim : Simulation
    what : str
        The stage, as the line names it.
    wall : float
        Its wall time, s.
    contacts : tuple of numpy.ndarray, optional
        The contacts' ``(i, j)`` where `sim` has not evaluated its forces since
        it was loaded (a table pile reloaded without its parked particles);
        default: those of its last force evaluation.
    """
    pos = sim.position
    if contacts is None:
        c = sim.contacts()
        contacts = (c["i"], c["j"])
    angle = angle_of_repose(pos[:, 0], pos[:, 1], sim.shapes.radius[:sim.n])
    log.info("%s done: wall %.1f s, %d steps, %d particles, t = %.4f s, angle of repose "
             "%.1f deg, mean coordination %.2f; CPU %.1f s in this process", what, wall, sim.step, sim.n,
             sim.time, angle, mean_coordination(*contacts, sim.n), process_cpu())


def process_cpu() -> float:
    """CPU seconds (user + system, all threads) this process has used so far.

    A stage's own count, read when its summary line is written: Snakemake's
    benchmark files sample a job's CPU every 0.5 s for its first 15 s and every
    30 s after, with no sample at its end, so they miss a job's last seconds
    (docs/performance/pour_budget.md).
    """
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime
