"""Where a pile's simulation time goes: its phases, their particle-steps and CPU (issue 57, item 2).

A pile is poured, relaxed and probed by three kinds of job.  The pour has two
phases: *delivery*, from the first release (t = 0) to the last, while the
particle count grows, and *settling*, from the last release to the pour's stop
criterion (:func:`sim.pour._land`), with all particles present.  The
relaxation and each probe run with all particles.  A step costs roughly in
proportion to the particles present, so each phase is measured in
*particle-steps*, the particle count integrated over its steps, and the pour's
CPU is shared between delivery and settling in proportion to theirs
(:func:`apportion`).

The release count is known exactly at the pour's frames and progress lines
(``released`` of ``frames.nc``, the log's ``released N of M ... t = X s``);
between two of them it is taken as linear (:func:`delivery_particle_steps`:
one release interval of error in a pour of thousands), and the last release
is placed within its bracket by the release rate just before it
(:func:`last_release`).

Snakemake's benchmark files (9.x, ``snakemake/benchmark.py``) sample a job's
CPU time every 0.5 s for its first 30 samples, about 15 s, then every 30 s,
and take no sample at the end: the CPU a job spends after its last sample is
not in ``cpu_time``, so a job of 15 to 45 s of wall time is recorded with the
CPU of its first 15 s.  :func:`tail_estimate` adds that tail back at the load
the samples saw (the job's CPU over its wall time up to the last sample).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Snakemake's benchmark sampling: this many samples (after the first) this far apart (s), then every
#: SAMPLE_LONG s (``BENCHMARK_INTERVAL_SHORT``, ``BENCHMARK_INTERVAL`` of snakemake/benchmark.py).
SHORT_SAMPLES, SAMPLE_SHORT, SAMPLE_LONG = 30, 0.5, 30.0
#: Wall time (s) by which the samples run late (each sample reads the process tree): a job that ended
#: within this of a sample time may or may not have been sampled then, and its tail is not estimated.
SAMPLE_LAG = 1.0
#: The phases of a pile, in order.
PHASES = ("delivery", "settling", "relax", "probe")


def last_sample(wall_s: float) -> tuple[float, bool]:
    """The wall time (s) of a job's last CPU sample, and whether it is certain.

    The samples fall at ``0.5 k`` s for ``k <= 30`` and at ``15 + 30 j`` s after
    (module docstring); the last before ``wall_s``.  Uncertain (False) when the job
    ended within :data:`SAMPLE_LAG` after a long-interval sample's time: the samples
    lag, and that one may not have been taken.
    """
    short_end = SHORT_SAMPLES * SAMPLE_SHORT
    if wall_s <= short_end:
        return SAMPLE_SHORT * math.floor(wall_s / SAMPLE_SHORT), True
    t = short_end + SAMPLE_LONG * math.floor((wall_s - short_end) / SAMPLE_LONG)
    return t, wall_s - t >= SAMPLE_LAG


def tail_estimate(cpu_s: float, wall_s: float) -> float:
    """A job's CPU seconds with the unsampled tail added at the sampled load (module docstring).

    Jobs within the short samples (up to 15 s plus :data:`SAMPLE_LAG`) are sampled to within 0.5 s of
    their end and keep ``cpu_s``; NaN where the last sample is uncertain (:func:`last_sample`).
    """
    if not (math.isfinite(cpu_s) and math.isfinite(wall_s)):
        return math.nan
    if wall_s <= SHORT_SAMPLES * SAMPLE_SHORT + SAMPLE_LAG:
        return cpu_s
    t, certain = last_sample(wall_s)
    return cpu_s * wall_s / t if certain else math.nan


def first_long_sample_jobs(cpu_s, wall_s) -> tuple[int, float]:
    """The jobs last sampled at the first long-interval sample (wall time from 15 s plus
    :data:`SAMPLE_LAG` to 45 s): how many, and the largest CPU seconds recorded for one of them,
    which the sampling caps near 15 s for a single-threaded job however long it ran (NaN for none)."""
    cpu, wall = np.asarray(cpu_s, float), np.asarray(wall_s, float)
    start = SHORT_SAMPLES * SAMPLE_SHORT
    inside = (wall >= start + SAMPLE_LAG) & (wall < start + SAMPLE_LONG) & np.isfinite(cpu)
    return int(inside.sum()), float(cpu[inside].max()) if inside.any() else math.nan


def release_knots(times, released, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The release count's known points: ``(0, 1)`` (the first particle is placed before
    the first step) and each ``(time, released)`` given, sorted by time, duplicates merged.

    Raises
    ------
    ValueError
        If the count falls with time or exceeds `n`.
    """
    t = np.concatenate([[0.0], np.asarray(times, float)])
    r = np.concatenate([[1.0], np.asarray(released, float)])
    order = np.argsort(t, kind="stable")
    t, r = t[order], r[order]
    keep = np.concatenate([np.diff(t) > 0, [True]])
    t, r = t[keep], r[keep]
    if np.any(np.diff(r) < 0) or r.max() > n:
        raise ValueError(f"release counts {r.tolist()[:5]}...: they must not fall with time nor exceed {n}")
    return t, r


def last_release(times, released, n: int, latest: float = math.inf) -> tuple[float, float, float]:
    """When the last of `n` particles was released: ``(estimate, after, by)`` (s).

    ``after`` is the latest known time with fewer than `n` released, ``by`` the
    earliest with all `n`, or `latest` where that is earlier (and later than
    ``after``): the latest time the pour's schedule allows; the estimate goes on
    from ``after`` at the release rate between the two known points before it,
    and stays at most ``by``.

    Raises
    ------
    ValueError
        If no known point has all `n` released.
    """
    t, r = release_knots(times, released, n)
    full = np.flatnonzero(r >= n)
    if not full.size:
        raise ValueError(f"no known point has all {n} particles released (at most {int(r.max())})")
    b = int(full[0])
    a = b - 1
    if a < 0:
        return float(t[b]), float(t[b]), float(t[b])
    by = float(min(t[b], latest)) if latest > t[a] else float(t[b])
    rate = (r[a] - r[a - 1]) / (t[a] - t[a - 1]) if a >= 1 else math.nan
    step = (n - r[a]) / rate if rate > 0 else 0.5 * (by - t[a])
    return float(min(t[a] + step, by)), float(t[a]), by


def delivery_particle_steps(times, released, t_last: float, dt: float, n: int) -> float:
    """Particle-steps of the delivery: the release count integrated over ``[0, t_last]``, over `dt`.

    The count is linear between the known points (:func:`release_knots`) before
    `t_last`, and reaches `n` at `t_last`.
    """
    t, r = release_knots(times, released, n)
    inside = t < t_last
    t = np.concatenate([t[inside], [t_last]])
    r = np.concatenate([r[inside], [float(n)]])
    return float(np.trapezoid(r, t)) / dt


def apportion(total: float, weights: dict[str, float]) -> dict[str, float]:
    """`total` shared in proportion to `weights` (NaN shares for a NaN total or no weight)."""
    whole = float(sum(weights.values()))
    if not (math.isfinite(total) and whole > 0):
        return {k: math.nan for k in weights}
    return {k: total * w / whole for k, w in weights.items()}


def pile_budget(n: int, dt: float, pour: tuple[float, int], release: tuple, relax: tuple[float, int, int],
                probes: list[tuple[float, int, int]], cpu: dict[str, float], wall: dict[str, float],
                settle_min: float = 0.0, counted: dict[str, float] | None = None) -> dict[str, Any]:
    """One pile's phases: simulated time, steps, particle-steps and CPU.

    Parameters
    ----------
    n : int
        Particles the pour releases (all present after the last release).
    dt : float
        The time step, s.
    pour : (float, int)
        The pour's simulated time (s) and steps (from t = 0).
    release : (times, released)
        The release count's known points (frames, progress lines).
    relax : (float, int, int)
        The relaxation's simulated time, steps and particles (those of the poured state: fewer
        than `n` where a table's pour kept only the particles on it).
    probes : list of (float, int, int)
        Each probe's simulated time, steps and particles.
    cpu, wall : dict
        CPU and wall seconds of the jobs ``pour``, ``relax``, ``probe`` (the probes summed),
        as the benchmark files give them.
    settle_min : float
        The least simulated time (s) the pour runs after its last release (its settling time
        and one landing window, :func:`sim.pour.pour`): the last release is at most the
        pour's end less this (:func:`last_release`).
    counted : dict or None
        CPU seconds of the jobs as their own summary lines count them
        (:func:`analysis.run_times.stage_cpu_time`, the process's getrusage at
        the stage's end); where one is finite it is the job's CPU with the
        tail, exactly, in place of :func:`tail_estimate`'s estimate.

    Returns
    -------
    dict
        Per phase of :data:`PHASES`: ``{phase}_s``, ``{phase}_steps``, ``{phase}_ps``
        (particle-steps); ``last_release_after``/``_by``, the bracket of the last release;
        per job ``cpu_{job}`` (recorded), ``cpu_est_{job}`` (with the tail: counted,
        else :func:`tail_estimate`), ``counted_{job}`` (whether it was counted) and
        ``ns_ps_{job}`` (CPU ns per particle-step, with the tail);
        per phase ``cpu_{phase}`` and ``cpu_est_{phase}`` (the pour's CPU apportioned by
        particle-steps) and ``share_{phase}`` (of the estimated total); ``cpu_total``,
        ``cpu_est_total``.
    """
    t_last, after, by = last_release(*release, n, latest=pour[0] - settle_min)
    out: dict[str, Any] = {"last_release_after": after, "last_release_by": by}
    delivery_steps = t_last / dt
    out.update(delivery_s=t_last, delivery_steps=delivery_steps,
               delivery_ps=delivery_particle_steps(*release, t_last, dt, n))
    out.update(settling_s=pour[0] - t_last, settling_steps=pour[1] - delivery_steps)
    out["settling_ps"] = n * out["settling_steps"]
    out.update(relax_s=relax[0], relax_steps=relax[1], relax_ps=relax[2] * relax[1])
    out.update(probe_s=float(sum(p[0] for p in probes)), probe_steps=int(sum(p[1] for p in probes)),
               probe_ps=float(sum(p[2] * p[1] for p in probes)))
    job_ps = {"pour": out["delivery_ps"] + out["settling_ps"], "relax": out["relax_ps"], "probe": out["probe_ps"]}
    for job in ("pour", "relax", "probe"):
        out[f"cpu_{job}"] = cpu.get(job, math.nan)
        line = (counted or {}).get(job, math.nan)
        out[f"counted_{job}"] = math.isfinite(line)
        out[f"cpu_est_{job}"] = line if math.isfinite(line) else tail_estimate(out[f"cpu_{job}"],
                                                                                 wall.get(job, math.nan))
        out[f"wall_{job}"] = wall.get(job, math.nan)
        out[f"ns_ps_{job}"] = 1e9 * out[f"cpu_est_{job}"] / job_ps[job] if job_ps[job] > 0 else math.nan
    for prefix in ("cpu_", "cpu_est_"):
        split = apportion(out[f"{prefix}pour"], {"delivery": out["delivery_ps"], "settling": out["settling_ps"]})
        out[f"{prefix}delivery"], out[f"{prefix}settling"] = split["delivery"], split["settling"]
        out[f"{prefix}total"] = out[f"{prefix}pour"] + out[f"{prefix}relax"] + out[f"{prefix}probe"]
    for phase in PHASES:
        out[f"share_{phase}"] = out[f"cpu_est_{phase}"] / out["cpu_est_total"]
        out[f"share_recorded_{phase}"] = out[f"cpu_{phase}"] / out["cpu_total"]
    return out


def settling_wall_share(clock: list[tuple[int, float]], delivery_steps: float) -> float:
    """The settling's share of a pour's wall time: the wall clock after step `delivery_steps` over the
    whole, from ``clock``, ``[(step, wall s)]`` from the pour's start to its end, linear between its
    points; NaN with fewer than two points or the step outside them."""
    if len(clock) < 2:
        return math.nan
    steps, wall = (np.asarray(v, float) for v in zip(*sorted(clock)))
    if not steps[0] <= delivery_steps <= steps[-1] or wall[-1] <= wall[0]:
        return math.nan
    return float((wall[-1] - np.interp(delivery_steps, steps, wall)) / (wall[-1] - wall[0]))


def cost_fit(particle_steps, cpu_s) -> tuple[float, float, int]:
    """Least-squares ``cpu = overhead + cost * particle_steps`` over jobs: the CPU seconds a job
    spends besides its steps (start-up, reading and writing states), the CPU ns per particle-step,
    and the number of jobs fitted (those with finite values; NaN below three)."""
    x, y = np.asarray(particle_steps, float), np.asarray(cpu_s, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        return math.nan, math.nan, int(ok.sum())
    (overhead, slope), *_ = np.linalg.lstsq(np.c_[np.ones(ok.sum()), x[ok]], y[ok], rcond=None)
    return float(overhead), float(1e9 * slope), int(ok.sum())


def arm_summary(piles: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per numeric key of the piles' budgets: median, smallest, largest and count of its finite values."""
    out = {}
    for key in piles[0]:
        values = np.asarray([p.get(key, math.nan) for p in piles], float)
        finite = values[np.isfinite(values)]
        out[key] = ({"median": float(np.median(finite)), "min": float(finite.min()), "max": float(finite.max()),
                     "n": int(finite.size)} if finite.size else
                    {"median": math.nan, "min": math.nan, "max": math.nan, "n": 0})
    return out
