"""Progress lines a person reads at a glance (issue 29, item 4): the pour's
released particles of N and per cent, and an ETA in h:mm:ss from the rate
since the start of pouring, not counting the start-up before it."""

import logging
import math
import re
import time
from types import SimpleNamespace

import pytest

from sim.durations import UNKNOWN, hms, parse_hms
from sim.progress import Progress, fixed_remaining, pour_remaining

HMS = r"\d+:[0-5]\d:[0-5]\d"


class FakeClock:
    """A wall clock the test moves by hand."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


@pytest.mark.parametrize("seconds, text", [
    (0, "0:00:00"), (0.4, "0:00:00"), (59.5, "0:01:00"), (59.4, "0:00:59"), (61, "0:01:01"),
    (3599.6, "1:00:00"), (3600, "1:00:00"), (86399, "23:59:59"), (100000, "27:46:40"),
    (-5, "-0:00:05"), (-0.2, "0:00:00"),
    (math.nan, UNKNOWN), (math.inf, UNKNOWN), (-math.inf, UNKNOWN), (None, UNKNOWN)])
def test_hms_edge_values(seconds, text):
    assert hms(seconds) == text


def test_parse_hms_refuses_what_is_no_duration():
    assert UNKNOWN == "unknown"
    for text in (UNKNOWN, "397", "6:7", "0:60:00", "1:00:00 s", ""):
        assert parse_hms(text) is None
    for seconds in (0, 61, 3600, 100000, -5):
        assert parse_hms(hms(seconds)) == seconds


@pytest.mark.parametrize("per_step, per_particle_step", [
    (0.0, 2e-4),    # a large pile: the particles' forces cost all
    (5e-3, 0.0),    # a small one: the step itself costs all, however many particles
    (2e-3, 5e-5)])  # both
def test_pour_eta_is_the_work_left_at_the_pouring_rate(caplog, per_step, per_particle_step):
    """Start-up (building, compiling) takes 1000 s of wall time, then the
    pour runs at a steady cost per step and per particle-step: the ETA is the
    steps and particle-steps left at those costs, not at the rate of the
    whole run with its start-up."""
    n_total, interval, settle, dt = 50, 0.01, 0.1, 1e-5
    steps_per_release = round(interval / dt)
    clock = FakeClock()
    progress = Progress(10.0, pour_remaining(n_total, interval, settle),
                        total=n_total, clock=clock)
    sim = SimpleNamespace(n=1, step=steps_per_release, time=interval, dt=dt)
    clock.now = 1000.0  # the first chunk has run after a long start-up
    lines = []
    with caplog.at_level(logging.INFO, logger="sim"):
        progress(sim, "pour wedge seed 3")
        while sim.n < 35:
            sim.n += 1  # a release, then its chunk of steps
            sim.step += steps_per_release
            sim.time += interval
            clock.now += (per_step + per_particle_step * sim.n) * steps_per_release
            caplog.clear()
            progress(sim, "pour wedge seed 3")
            lines += [(r.getMessage(), clock.now) for r in caplog.records]
    assert len(lines) >= 2, "too few progress lines in 35 releases"
    line, at = lines[-1]
    n = int(re.search(r"released (\d+) of", line).group(1))
    # Independently: the particle count ramps linearly from n to n_total over
    # the releases to come, then stays for the settling time.
    feed = (n_total - n) * interval
    steps = (feed + settle) / dt
    particle_steps = ((n + n_total) / 2 * feed + n_total * settle) / dt
    expected = per_step * steps + per_particle_step * particle_steps
    assert f"released {n} of {n_total} ({math.floor(100 * n / n_total)} %), ETA " in line
    eta = re.search(rf"ETA ({HMS});", line)
    assert eta, line
    assert parse_hms(eta.group(1)) == pytest.approx(expected, abs=0.5)
    assert expected > 60  # a test of more than the rounding
    assert at / (at - 1000.0) > 5  # counting the start-up would say 5 times as long
    assert "particles," not in line  # "released k of N" instead


def test_pour_line_at_a_glance():
    clock = FakeClock()
    progress = Progress(10.0, pour_remaining(3500, 0.01, 0.1),
                        total=3500, clock=clock)
    sim = SimpleNamespace(n=2743, step=4_000_000, time=27.43, dt=1e-5)
    progress(sim, "pour wedge seed 3")  # the start
    assert progress.line(sim, "pour wedge seed 3") == (
        "pour wedge seed 3: released 2743 of 3500 (78 %), ETA unknown; t = 27.4300 s "
        "simulated, about 7.6700 s to go, 4000000 steps, nan ns per particle-step")
    sim.n, sim.step = 3499, 4_000_001
    clock.now = 1.0
    progress(sim, "pour wedge seed 3")
    line = progress.line(sim, "pour wedge seed 3")
    assert re.match(rf"pour wedge seed 3: released 3499 of 3500 \(99 %\), ETA {HMS}; ", line), line


def test_relax_line_says_at_most_in_hms(caplog):
    """A relaxation's ETA is an upper bound and says so, in h:mm:ss, with the
    particle count and the detail."""
    clock = FakeClock()
    progress = Progress(10.0, fixed_remaining(10.0), at_most=True, clock=clock)
    sim = SimpleNamespace(n=3500, step=100, time=0.1, dt=1e-5)
    clock.now = 50.0  # start-up
    with caplog.at_level(logging.INFO, logger="sim"):
        progress(sim, "relax wedge seed 3", detail="KE per particle 0.1 m g d")
        sim.step, sim.time = 10100, 0.2
        clock.now += 12.0  # 12 s for 3500 * 10000 particle-steps
        progress(sim, "relax wedge seed 3", detail="KE per particle 0.1 m g d")
    (line,) = [r.getMessage() for r in caplog.records]
    expected = 12.0 / (3500 * 10000) * 3500 * 9.8 / 1e-5  # 9.8 s to go, all particles
    assert line == (f"relax wedge seed 3: ETA at most {hms(expected)}; t = 0.2000 s simulated, "
                    "at most 9.8000 s to go, 3500 particles, 10100 steps, 343 ns per "
                    "particle-step, KE per particle 0.1 m g d")
    assert hms(expected) == "0:19:36"  # 12 s per 0.1 s simulated: 98 x 12 s


def test_the_summary_lines_cpu_is_the_process_own_count():
    """sim.progress.process_cpu reads getrusage; Python's process_time reads the same
    user + system time through another call: over a busy loop of about 0.3 s both
    rise alike (to the kernel's accounting tick, 10 ms, and a margin)."""
    from sim.progress import process_cpu

    a, b = process_cpu(), time.process_time()
    while time.process_time() - b < 0.3:
        sum(range(1000))
    assert process_cpu() - a == pytest.approx(time.process_time() - b, abs=0.03)
