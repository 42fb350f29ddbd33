"""A pile's budget by phase (analysis/pour_budget.py) on cases whose answer is known by construction.

Particles released at a constant rate give the delivery's particle-steps in
closed form; the pour's CPU split between delivery and settling adds back to
it; a job sampled the way Snakemake's benchmark samples it gets its unsampled
tail back; and the pour's log lines are read as the simulator writes them.
"""

import math

import numpy as np
import pytest

from analysis.pour_budget import (apportion, arm_summary, cost_fit, delivery_particle_steps, first_long_sample_jobs,
                                  last_release, last_sample, pile_budget, release_knots, settling_wall_share,
                                  tail_estimate)
from workflow.tools.pour_budget import pour_log

DT = 7e-6          # s, the decision piles' step
RATE = 200.0       # releases per s
FRAME = 0.05       # s between frames


def constant_rate(n, frame=FRAME):
    """Known release counts of `n` particles released at RATE from t = 0 (count 1 + RATE t), every `frame` s
    before the last release, and the last release's time."""
    t_last = (n - 1) / RATE
    times = np.arange(frame, t_last, frame)
    return times, 1.0 + RATE * times, t_last


def test_constant_rate_delivery_has_its_closed_form():
    """The count 1 + r t over steps = T/dt: particle-steps = steps + r dt steps² / 2."""
    n = 1201
    times, released, t_last = constant_rate(n)
    steps = t_last / DT
    expected = steps + RATE * DT * steps ** 2 / 2
    assert delivery_particle_steps(times, released, t_last, DT, n) == pytest.approx(expected, rel=1e-12)
    # the staircase of single releases it stands for differs by half a particle over the delivery
    staircase = sum((t_last - k / RATE) for k in range(n)) / DT
    assert delivery_particle_steps(times, released, t_last, DT, n) == pytest.approx(staircase, rel=1 / n)


def test_the_last_release_goes_on_at_the_rate_before_it():
    n = 1201
    times, released, t_last = constant_rate(n)
    after = times[-1] + 0.3                      # the next known point: all released, at the pour's end
    estimate, lo, hi = last_release(np.r_[times, after], np.r_[released, n], n)
    assert (lo, hi) == (times[-1], after)
    assert estimate == pytest.approx(t_last, rel=1e-12)
    # a release held back: the estimate never passes the first point with all of them
    estimate, _, hi = last_release(np.r_[times, times[-1] + 1e-3], np.r_[released, n], n)
    assert estimate == hi
    # nor the latest time the pour's schedule allows
    estimate, _, hi = last_release(np.r_[times, after], np.r_[released, n], n, latest=times[-1] + 1e-3)
    assert estimate == hi == times[-1] + 1e-3


def test_known_points_are_sorted_merged_and_checked():
    t, r = release_knots([0.2, 0.1, 0.2], [30, 10, 30], 50)
    assert t.tolist() == [0.0, 0.1, 0.2] and r.tolist() == [1, 10, 30]
    with pytest.raises(ValueError, match="must not fall"):
        release_knots([0.1, 0.2], [20, 10], 50)
    with pytest.raises(ValueError, match="no known point"):
        last_release([0.1], [10], 50)


def test_apportioning_adds_up_to_the_total():
    split = apportion(90.0, {"delivery": 2.0, "settling": 1.0})
    assert split == {"delivery": 60.0, "settling": 30.0}
    assert all(math.isnan(v) for v in apportion(math.nan, {"a": 1.0}).values())
    assert all(math.isnan(v) for v in apportion(5.0, {"a": 0.0}).values())


def test_a_pile_budget_splits_the_pour_and_sums_its_shares():
    n = 1201
    times, released, t_last = constant_rate(n)
    t_pour = t_last + 0.15
    s_pour = round(t_pour / DT)
    cpu = {"pour": 80.0, "relax": 10.0, "probe": 12.0}
    wall = {"pour": 12.0, "relax": 5.0, "probe": 6.0}          # all within Snakemake's short samples
    b = pile_budget(n, DT, (t_pour, s_pour), (np.r_[times, t_pour], np.r_[released, n]), (0.7, 100_000, n),
                    [(0.3, 40_000, n), (0.2, 30_000, n - 1)], cpu, wall)
    assert b["delivery_s"] == pytest.approx(t_last) and b["settling_s"] == pytest.approx(0.15)
    assert b["settling_ps"] == pytest.approx(n * (s_pour - t_last / DT))
    assert b["relax_ps"] == n * 100_000 and b["probe_steps"] == 70_000
    assert b["probe_ps"] == n * 40_000 + (n - 1) * 30_000
    assert b["cpu_delivery"] + b["cpu_settling"] == pytest.approx(cpu["pour"])
    assert b["cpu_delivery"] / b["cpu_settling"] == pytest.approx(b["delivery_ps"] / b["settling_ps"])
    assert b["cpu_est_total"] == b["cpu_total"] == pytest.approx(102.0)
    assert sum(b[f"share_{p}"] for p in ("delivery", "settling", "relax", "probe")) == pytest.approx(1.0)
    assert b["ns_ps_relax"] == pytest.approx(1e9 * 10.0 / (n * 100_000))
    # a job whose log counted its own CPU takes that count as its CPU with the tail; the
    # others keep the benchmark's (here within its short samples, so unchanged)
    c = pile_budget(n, DT, (t_pour, s_pour), (np.r_[times, t_pour], np.r_[released, n]), (0.7, 100_000, n),
                    [(0.3, 40_000, n), (0.2, 30_000, n - 1)], cpu, wall,
                    counted={"pour": 95.5, "relax": math.nan, "probe": 14.0})
    assert (c["cpu_est_pour"], c["cpu_est_relax"], c["cpu_est_probe"]) == (95.5, 10.0, 14.0)
    assert (c["counted_pour"], c["counted_relax"], c["counted_probe"]) == (True, False, True)
    assert c["cpu_pour"] == 80.0 and c["cpu_est_total"] == pytest.approx(119.5)
    assert c["cpu_est_delivery"] + c["cpu_est_settling"] == pytest.approx(95.5)


def sampled(load, wall):
    """The cpu_time Snakemake's benchmark records for a job at a constant `load` (CPU s per s) lasting
    `wall` s: the CPU at its last sample, 0.5 s apart for 30 samples, then 30 s apart."""
    times = [0.5 * k for k in range(31)]
    while times[-1] + 30.0 < 1000.0:
        times.append(times[-1] + 30.0)
    return load * max(t for t in times if t <= wall)


@pytest.mark.parametrize("wall", [27.35, 44.0, 60.0, 132.64, 220.55])
def test_the_unsampled_tail_comes_back(wall):
    recorded = sampled(0.9, wall)
    assert recorded < 0.9 * wall
    assert tail_estimate(recorded, wall) == pytest.approx(0.9 * wall)


def test_jobs_sampled_last_at_15_s_are_counted_with_their_largest_record():
    walls = [10.0, 20.0, 30.0, 44.0, 60.0]
    assert first_long_sample_jobs([sampled(1.0, w) for w in walls], walls) == (3, 15.0)
    assert first_long_sample_jobs([5.0], [10.0])[0] == 0


def test_the_tail_is_left_alone_where_the_samples_reach_the_end_or_are_in_doubt():
    assert tail_estimate(9.5, 10.0) == 9.5                   # within the short samples
    assert last_sample(45.4) == (45.0, False)                # a 45-s sample that may not have been taken
    assert math.isnan(tail_estimate(30.0, 45.4))
    assert last_sample(132.64) == (105.0, True)


def test_cost_fit_finds_a_jobs_overhead_and_its_cost_per_particle_step():
    ps = np.array([1e8, 2e8, 9e8, 5e8])
    overhead, ns, jobs = cost_fit(ps, 7.0 + 140e-9 * ps)
    assert (overhead, ns, jobs) == (pytest.approx(7.0), pytest.approx(140.0), 4)
    assert math.isnan(cost_fit([1e8, np.nan], [1.0, 2.0])[0])


def test_settling_wall_share_reads_the_clock_between_its_points():
    clock = [(0, 100.0), (1000, 110.0), (1100, 120.0)]
    assert settling_wall_share(clock, 1000) == pytest.approx(0.5)
    assert settling_wall_share(clock, 1050) == pytest.approx(0.25)
    assert math.isnan(settling_wall_share([], 10)) and math.isnan(settling_wall_share(clock, 2000))


def test_arm_summary_takes_median_and_range_of_the_finite_values():
    s = arm_summary([{"a": 1.0}, {"a": 5.0}, {"a": 2.0}, {"a": math.nan}])["a"]
    assert s == {"median": 2.0, "min": 1.0, "max": 5.0, "n": 3}


LOG = """\
2026-12-07 22:40:50,859 INFO pour wedge seed 2017: started by process vm 24897
2026-12-07 22:40:50,888 INFO pouring 1600 particles (wedge, seed 2017), dt = 7.07e-06 s (verlet; limit 1.41e-05 s)
2026-12-07 22:41:01,900 INFO pour wedge seed 2017: released 491 of 1600 (30 %), ETA 0:01:41; t = 2.3107 s \
simulated, about 5.3284 s to go, 326950 steps, 125 ns per particle-step
2026-12-07 22:42:51,074 INFO frames: 148 written to results/study/piles/wedge/seed2017/pour.checkpoint.frames.nc \
(4.04 MB), 0.21 s of wall time spent taking them
2026-12-07 22:43:01,928 INFO pour wedge seed 2017 done: wall 131.0 s, 1088556 steps, 1600 particles, t = 7.6933 s, \
angle of repose 28.5 deg, mean coordination 3.06
"""


def test_a_pour_log_gives_its_release_counts_and_wall_clock(tmp_path):
    path = tmp_path / "seed2017.log"
    path.write_text(LOG)
    log = pour_log(path)
    assert log["times"] == [2.3107] and log["released"] == [491]
    steps = [s for s, _ in log["clock"]]
    assert steps == [0, 326950, 1088556]
    assert log["clock"][2][1] - log["clock"][0][1] == pytest.approx(131.04)
    assert log["runs"] == 1
    path.write_text(LOG + LOG)                     # a resumed pour: its wall clock is not one run's
    assert pour_log(path)["clock"] == [] and pour_log(path)["runs"] == 2
