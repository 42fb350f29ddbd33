"""workflow/tools/study_progress.py: the one-line progress of the study
(issue 15, item 4), on fake piles/, logs/ and benchmarks/ trees in the
configuration's results folder (results/study, issue 29 item 2), at the paths
of workflow/piles.py."""

import json
import math
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from workflow.piles import Piles
from workflow.tools import study_progress as sp
from workflow.validation import load_config

REPO = Path(__file__).resolve().parents[1]
TOOL = [sys.executable, "-m", "workflow.tools", "study_progress"]

NOW = 1.8e9  # s since the epoch, the "now" of the pure functions
STAGES = ["poured", "relaxed", "reduced"]
# CPU seconds of the finished piles' jobs: pour, relax, probe.
CPU = {("wedge", 1): (1000.0, 100.0, 50.0), ("wedge", 2): (1400.0, 140.0, 60.0)}
# Means per stage: pour 1200, relax 120, probe 55 -> 1375 s of CPU per pile.
ETA_LINE = ("2026-12-01 18:35:03,828 INFO pour wedge seed 3: released 2743 of 3500 (78 %), "
            "ETA 0:06:37; t = 31.9000 s simulated, about 3.2000 s to go, 4705393 steps, "
            "1100 ns per particle-step\n")
# The same line as written before issue 29 (logs of pours started then).
OLD_ETA_LINE = ("2026-12-01 18:35:03,828 INFO pour wedge seed 3: t = 31.9 s simulated, about 3.2 s "
                "to go, 2743 particles, 4705393 steps, 1100 ns per particle-step, ETA 397 s\n")


def write_config(root, wedge=(1, 2, 3), layered=(1, 2)):
    """A small study (schema defaults for the rest: 3500 particles, one probe)."""
    protocols = {name: {"seeds": list(seeds)} for name, seeds in
                 (("wedge", wedge), ("layered", layered)) if seeds}
    config = {"protocols": protocols, "threads": 1}
    path = Path(root) / "config" / "config.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(config))
    return path


def touch(path, mtime=None, text=""):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    if mtime is not None:
        os.utime(path, (mtime, mtime))
    return path


def benchmark(root, piles, protocol, seed, stage, cpu_time, wall=None):
    header = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
    wall = 2 * cpu_time if wall is None else wall
    touch(Path(root) / piles.paths.stage_benchmark(protocol, seed, stage),
          text=header + f"{wall}\t0:00:00\t258\t492\t187\t209\t0\t67\t50\t{cpu_time}\n")


def finished_pile(root, piles, protocol, seed, cpu, now, stages=STAGES):
    """State files, old logs and benchmarks of a finished pile of `piles` (a
    Piles) in the workflow's directory `root`; `cpu` per stage of `stages`."""
    for stage, cpu_time in zip(stages, cpu):
        touch(Path(root) / piles.paths.pile(protocol, seed, stage))
        touch(Path(root) / piles.paths.stage_log(protocol, seed, stage), mtime=now - 3600, text="done\n")
        benchmark(root, piles, protocol, seed, stage, cpu_time)


def live_lock(root, piles, protocol, seed):
    """The pour lock of a pile held by this (live) process, as sim.lock.PourLock writes it."""
    return touch(Path(root) / sp.pour_lock(piles, protocol, seed),
                 text=f"{socket.gethostname()} {os.getpid()}\n")


def dead_pid():
    """The PID of a process that has ended."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def fake_study(root, now=NOW):
    """wedge 1, 2 done; wedge 3 pouring (its lock held by this process, a
    checkpoint, ETA 397 s written 7 s ago);
    layered 2 relaxing (log written a minute ago, no progress line yet);
    layered 1 not started."""
    write_config(root)
    piles, root = piles_of(root), Path(root)
    for (protocol, seed), cpu in CPU.items():
        finished_pile(root, piles, protocol, seed, cpu, now)
    touch(root / piles.paths.pour_checkpoint("wedge", 3))
    live_lock(root, piles, "wedge", 3)
    touch(root / piles.paths.stage_log("wedge", 3, "poured"), mtime=now - 7,
          text="2026-12-01 18:30:00,000 INFO pouring 3500 particles (wedge, seed 3)\n" + ETA_LINE)
    touch(root / piles.paths.pile("layered", 2, "poured"))
    touch(root / piles.paths.stage_log("layered", 2, "poured"), mtime=now - 900, text="poured\n")
    touch(root / piles.paths.stage_log("layered", 2, "relaxed"), mtime=now - 60,
          text="2026-12-01 18:30:00,000 INFO relaxing 3500 particles\n")
    return root


def config_of(root):
    return load_config([Path(root) / "config" / "config.yaml"])


def piles_of(root):
    """The piles of the configuration in `root` (results/study, config `results`'s default)."""
    return Piles(config_of(root))


def states(root, now=NOW, piles=None):
    piles = piles_of(root) if piles is None else piles
    return {(p.protocol, p.seed): p for p in (
        sp.pile_state(root, piles, protocol, seed, now) for protocol, seed in piles.each())}


def test_the_paths_are_those_of_the_workflow(tmp_path):
    write_config(tmp_path)
    piles = piles_of(tmp_path)
    assert piles.stages.all_stages() == STAGES
    assert piles.paths.stage_benchmark("wedge", 3, "poured") == "results/study/benchmarks/pour/wedge/seed3.tsv"
    assert piles.paths.stage_log("layered", 1, "relaxed") == "results/study/logs/relax/layered/seed1.log"
    # the lock sim.pour.pour takes beside the checkpoint it is given
    assert sp.pour_lock(piles, "wedge", 3) == "results/study/piles/wedge/seed3/pour.checkpoint.nc.lock"


def test_parse_progress_lines():
    assert sp.parse_progress(ETA_LINE) == (397.0, 2743, False)
    assert sp.parse_progress(OLD_ETA_LINE) == (397.0, 2743, False)
    relax_now = ("INFO relax wedge seed 3: ETA at most 0:02:00; t = 0.4000 s simulated, at most "
                 "9.6000 s to go, 3500 particles, 10 steps, 900 ns per particle-step, KE per "
                 "particle 0.1 m g d")
    assert sp.parse_progress(relax_now) == (120.0, 3500, True)
    long_pour = ETA_LINE.replace("ETA 0:06:37", "ETA 27:46:40")
    assert sp.parse_progress(long_pour) == (100000.0, 2743, False)
    assert sp.parse_progress(ETA_LINE.replace("ETA 0:06:37", "ETA unknown")) is None
    old = ("2026-12-01 18:35:03,828 INFO bench pile of 3000: 0.0269 s of 1.0000 s simulated, "
           "3000 particles, 4077 steps, 401 steps/s, ETA 367 s, KE per particle 0.28 m g d")
    assert sp.parse_progress(old) == (367.0, 3000, False)
    relax = ("INFO relax: t = 0.4 s simulated, at most 9.6 s to go, 3500 particles, 10 steps, "
             "900 ns per particle-step, ETA 120 s, KE per particle 0.1 m g d")
    assert sp.parse_progress(relax) == (120.0, 3500, True)
    assert sp.parse_progress("INFO pour: ... ETA nan s") is None
    assert sp.parse_progress("INFO pouring 3500 particles") is None


def test_benchmark_cpu(tmp_path):
    write_config(tmp_path)
    piles = piles_of(tmp_path)
    benchmark(tmp_path, piles, "wedge", 1, "poured", 4756.78, wall=8339.04)
    assert sp.benchmark_cpu(tmp_path / piles.paths.stage_benchmark("wedge", 1, "poured")) == 4756.78
    assert sp.benchmark_cpu(tmp_path / "missing.tsv") is None
    two = touch(tmp_path / "two.tsv", text="s\tcpu_time\n10\t4\n12\t6\n")
    assert sp.benchmark_cpu(two) == 5.0  # --benchmark-repeats: the mean
    na = touch(tmp_path / "na.tsv", text="s\tcpu_time\n10\tNA\n")
    assert sp.benchmark_cpu(na) == 10.0  # no CPU time: the wall seconds


def test_counts_and_running_piles(tmp_path):
    piles = states(fake_study(tmp_path))
    assert {k: p.state for k, p in piles.items()} == {
        ("wedge", 1): "done", ("wedge", 2): "done", ("wedge", 3): "running",
        ("layered", 1): "left", ("layered", 2): "running"}
    pouring = piles["wedge", 3]
    assert pouring.missing == ("poured", "relaxed", "reduced")
    assert pouring.eta == 397.0 - 7  # less the 7 s since the line was written
    assert pouring.fraction == pytest.approx(2743 / 3500)
    assert sp.describe_running(pouring) == "wedge 3: pour 78 %, ETA 0:06:30"
    relaxing = piles["layered", 2]
    assert relaxing.missing == ("relaxed", "reduced") and relaxing.eta is None
    assert sp.describe_running(relaxing) == "layered 2: relax"


@pytest.mark.parametrize("line", [ETA_LINE, OLD_ETA_LINE])
@pytest.mark.parametrize("age", [86400, 7])
def test_killed_pour_keeps_its_eta(tmp_path, line, age):
    """A checkpoint without a live lock (a killed pour, its log old or just
    written) is interrupted, not running; its ETA is the work its pour still
    needs, not reduced by the time since (also from a log in the format before
    issue 29)."""
    write_config(tmp_path)
    piles = piles_of(tmp_path)
    touch(tmp_path / piles.paths.pour_checkpoint("wedge", 1))
    touch(tmp_path / piles.paths.stage_log("wedge", 1, "poured"), mtime=NOW - age, text=line)
    pile = states(tmp_path)["wedge", 1]
    assert (pile.state, pile.eta) == ("interrupted", 397.0)
    assert pile.fraction == pytest.approx(2743 / 3500)
    assert sp.describe_running(pile) == "wedge 1: pour 78 %, 0:06:37 to go"


def test_a_pour_runs_only_while_a_live_process_holds_its_lock(tmp_path):
    """sim.lock.PourLock's "host pid": this host's live process, running; a PID
    that has ended, interrupted (with a checkpoint or without one: the lock of
    a pour killed before its first checkpoint); another host's lock, running
    while refreshed within 3 checkpoint intervals and a minute, then
    interrupted; no lock and no checkpoint, left."""
    write_config(tmp_path, wedge=(1, 2, 3, 4, 5, 6), layered=())
    piles = piles_of(tmp_path)
    interval = config_of(tmp_path)["pour"]["checkpoint_interval"]
    for seed in (1, 2):
        touch(tmp_path / piles.paths.pour_checkpoint("wedge", seed))
    live_lock(tmp_path, piles, "wedge", 1)
    gone = f"{socket.gethostname()} {dead_pid()}\n"
    touch(tmp_path / sp.pour_lock(piles, "wedge", 2), text=gone)
    touch(tmp_path / sp.pour_lock(piles, "wedge", 3), text=gone)
    now = time.time()
    touch(tmp_path / sp.pour_lock(piles, "wedge", 4), text="elsewhere.example 12\n",
          mtime=now - 3 * interval)
    touch(tmp_path / sp.pour_lock(piles, "wedge", 5), text="elsewhere.example 12\n",
          mtime=now - 3 * interval - 61)
    # a pour log written just now does not make a pour without a live lock run
    touch(tmp_path / piles.paths.stage_log("wedge", 6, "poured"), mtime=now, text=ETA_LINE)
    assert {seed: p.state for (_, seed), p in states(tmp_path, now=now).items()} == {
        1: "running", 2: "interrupted", 3: "interrupted", 4: "running", 5: "interrupted", 6: "left"}
    line = sp.progress_line(tmp_path, config_of(tmp_path), cores=1, now=now)
    assert line.startswith("study (results/study/): 0 of 6 piles done, 2 running (wedge 1: pour; "
                           "wedge 4: pour), 3 interrupted (resumable: wedge 2: pour; wedge 3: pour; "
                           "wedge 5: pour), 1 left; ")


def test_reads_the_line_the_simulator_writes():
    """The ETA of a line written by sim.progress.Progress, as it reads it."""
    from types import SimpleNamespace

    from sim.progress import Progress, pour_remaining

    progress = Progress(10.0, pour_remaining(3500, 0.01, 0.1), total=3500,
                        clock=iter([0.0, 20.0]).__next__)
    sim = SimpleNamespace(n=2000, step=1000, time=20.0, dt=1e-5)
    progress(sim, "pour wedge seed 3")
    sim.step += 20_000  # 20 s for 2000 x 20 000 particle-steps: 500 ns each
    progress(sim, "pour wedge seed 3")
    line = progress.line(sim, "pour wedge seed 3")
    particle_seconds = pour_remaining(3500, 0.01, 0.1)(sim)[1]
    assert sp.parse_progress("INFO " + line) == (
        pytest.approx(500e-9 * particle_seconds / sim.dt, abs=0.5), 2000, False)


def test_fraction_done_by_hand(tmp_path):
    root = fake_study(tmp_path)
    piles = list(states(root).values())
    means, _ = sp.stage_means(root, piles_of(root), piles)
    # Work left as in test_time_left_by_hand, of 5 piles of 1375 s each.
    left = (390 + 120 + 55) + (120 + 55) + 1375
    assert sp.fraction_done(piles, means, cores=1, threads=1) == pytest.approx(1 - left / (5 * 1375))
    assert sp.fraction_done(piles, {}, cores=1, threads=1) is None
    slow = [sp.PileState("wedge", 1, "running", tuple(STAGES), eta=1e6)]
    assert sp.fraction_done(slow, means, cores=1, threads=1) == 0.0  # never below 0


def test_stale_log_without_checkpoint_is_left(tmp_path):
    write_config(tmp_path)
    touch(tmp_path / piles_of(tmp_path).paths.stage_log("wedge", 1, "poured"), mtime=NOW - 2 * sp.RECENT_S,
          text=ETA_LINE)
    assert states(tmp_path)["wedge", 1].state == "left"


def test_time_left_by_hand(tmp_path):
    root = fake_study(tmp_path)
    piles = list(states(root).values())
    means, counted = sp.stage_means(root, piles_of(root), piles)
    assert counted == 2
    assert means == {"poured": 1200.0, "relaxed": 120.0, "reduced": 55.0}
    # wedge 3: its ETA 390 s, then relax 120 + probe 55; layered 2: relax 120
    # (no ETA yet) + probe 55; layered 1: a whole pile, 1375 s.
    work = (390 + 120 + 55) + (120 + 55) + 1375
    assert sp.time_left(piles, means, cores=1, threads=1) == (work, 1)
    # Two cores: the work over 2 jobs (1057.5 s) is less than the longest pile.
    assert sp.time_left(piles, means, cores=2, threads=1) == (1375.0, 2)
    # Many cores: no more jobs than unfinished piles.
    assert sp.time_left(piles, means, cores=16, threads=1) == (1375.0, 3)


def test_time_left_shared_work():
    """Without a long single pile the work is shared among the jobs; two
    threads per job use two cores each."""
    means = {"poured": 1000.0, "relaxed": 100.0, "reduced": 50.0}
    piles = [sp.PileState("wedge", s, "left", tuple(STAGES)) for s in range(1, 5)]
    piles.append(sp.PileState("wedge", 5, "running", tuple(STAGES), eta=200.0))
    work = 4 * 1150 + (200 + 150)
    assert sp.time_left(piles, means, cores=2, threads=1) == (work / 2, 2)
    work2 = 4 * 1150 + (2 * 200 + 150)  # ETA: wall seconds on 2 cores
    assert sp.time_left(piles, means, cores=4, threads=2) == (work2 / 4, 2)


def test_progress_line(tmp_path):
    root = fake_study(tmp_path)
    line = sp.progress_line(root, config_of(root), cores=1, now=NOW)
    # 2115 s of work left of 5 x 1375 s: 69 % done (see test_fraction_done_by_hand)
    assert line == ("study (results/study/): 2 of 5 piles done, 2 running (wedge 3: pour 78 %, ETA 0:06:30; "
                    "layered 2: relax), 1 left; 69 % of the simulation done, about 0:35:15 left "
                    "at 1 job at a time (mean of 2 finished piles: 0:22:55 of CPU per pile)")
    assert "done, about 0:22:55 left at 2 jobs" in sp.progress_line(root, config_of(root), 2, NOW)


def test_cost_model_before_a_pile_has_finished(tmp_path):
    """Before a pile has finished, the CPU seconds of a pile are the cost
    model's (workflow/resources.py), worked out here from its formula: the
    default piles (3500 particles at 100/s, Gear at its automatic step of the
    reference particles, 1.9 us; a relaxation and a gravity probe, step mode,
    of 2 s simulated each) take (1.5 x 3500 / 100 + 0.1) s / 1.9 us x 1750
    particles + 2 x 2 s / 1.9 us x 3500 particle-steps, each at the price of the
    run-time table's measured pour (workflow/run_times.json), which the line names."""
    from sim.durations import hms
    from workflow.resources import COST_BASIS

    table = json.loads((REPO / "workflow" / "run_times.json").read_text())
    pour = next(row for row in table["rows"] if row["id"] == table["cost_model"])
    price = pour["cpu_s"] / (pour["steps"] * pour["particles"] / 2)
    assert COST_BASIS["ns_per_particle_step"] == pytest.approx(price * 1e9)
    empty = tmp_path / "empty"
    write_config(empty)
    steps = (1.5 * 3500 / 100 + 0.1) / 1.9e-6 * 1750 + 2 * 2.0 / 1.9e-6 * 3500
    cpu = steps * price
    # 5 piles on 2 cores, one thread each: 2.5 piles' CPU in wall time
    assert sp.progress_line(empty, config_of(empty), 2, NOW) == (
        "study (results/study/): 0 of 5 piles done, 0 running, 5 left; 0 % of the simulation done, "
        f"about {hms(2.5 * cpu)} left at 2 jobs at a time (estimate from the cost model until a pile "
        f"has finished: {steps:.3g} particle-steps per pile, host-independent, from "
        "pour.n_particles = 3500, pour.rate = 100/s, automatic time step of gear about 1.9e-06 s "
        f"and 2 relaxing stages of about 2 s simulated, x {price * 1e9:.0f} ns per particle-step as "
        f"measured ({pour['id']}: {pour['commit']}, {pour['host']}, {pour['date']}; docs/run_times.md): "
        f"{hms(cpu)} of CPU per pile)")
    root = fake_study(tmp_path)
    for seed in (1, 2):  # the finished piles' last stage gone: none has finished
        (root / piles_of(root).paths.pile("wedge", seed, "reduced")).unlink()
    line = sp.progress_line(root, config_of(root), cores=2, now=NOW)
    assert line.startswith("study (results/study/): 0 of 5 piles done, 2 running "
                           "(wedge 3: pour 78 %, ETA 0:06:30;")
    assert "(estimate from the cost model until a pile has finished: " in line
    # wedge 1, 2: their probe; wedge 3: its pour's ETA (390 s), then a relaxation
    # and a probe; layered 2: a relaxation and a probe; layered 1: a whole pile.
    # A relaxation and a probe cost the same here, 2 s / 1.9 us x 3500 particle-steps.
    stage = 2.0 / 1.9e-6 * 3500 * price
    left = 2 * stage + (390 + 2 * stage) + 2 * stage + cpu
    assert left / 2 < cpu  # on 2 jobs the study waits for its longest pile, layered 1
    assert f"% of the simulation done, about {hms(cpu)} left at 2 jobs" in line
    assert f"{math.floor(100 * (1 - left / (5 * cpu)))} % of the simulation done" in line


def test_seed10_is_not_seed1(tmp_path):
    """A benchmark or log of seed 10 does not count for seed 1."""
    write_config(tmp_path, wedge=(1, 10), layered=())
    piles = piles_of(tmp_path)
    finished_pile(tmp_path, piles, "wedge", 10, (1000.0, 100.0, 50.0), NOW)
    touch(tmp_path / piles.paths.stage_log("wedge", 10, "poured"), mtime=NOW - 10, text=ETA_LINE)
    line = sp.progress_line(tmp_path, config_of(tmp_path), 2, NOW)
    assert line.startswith("study (results/study/): 1 of 2 piles done, 0 running, 1 left; "
                           "50 % of the simulation done, about 0:19:10 left")


def test_a_scenes_probes_are_stages_of_the_piles(tmp_path):
    """With a scene's probes (config/scenes/six_constants.yaml over
    config/config.yaml: tilts, the support stretch, restored gravity) a pile
    is done only with them all: one with only its gravity probe runs the next
    probe, and the work left counts the probes it misses (before the stages
    came from workflow/piles.py it counted as done)."""
    config = load_config([REPO / "config" / "config.yaml", REPO / "config" / "scenes" / "six_constants.yaml"])
    piles = Piles(config)
    stages = piles.stages.all_stages()
    assert stages == STAGES + ["tiltp05", "tiltm05", "stretched", "restored"]
    finished_pile(tmp_path, piles, "wedge", 1, [1000.0, 100.0] + [50.0] * 5, NOW, stages)
    finished_pile(tmp_path, piles, "wedge", 2, [1000.0, 100.0, 50.0], NOW)  # the gravity probe only
    touch(tmp_path / piles.paths.stage_log("wedge", 2, "tiltp05"), mtime=NOW - 60, text="INFO probing\n")
    pile = states(tmp_path, piles=piles)["wedge", 2]
    assert (pile.state, pile.missing) == ("running", ("tiltp05", "tiltm05", "stretched", "restored"))
    # 19 piles of 1350 s of CPU: wedge 2 needs 4 x 50 s, the 17 left all of it,
    # 23 150 s in all over 2 jobs; 1 - 23 150 / (19 x 1350) = 9.7 % done.
    assert sp.progress_line(tmp_path, config, cores=2, now=NOW) == (
        "study (results/study/): 1 of 19 piles done, 1 running (wedge 2: probe tiltp05), 17 left; "
        "9 % of the simulation done, about 3:12:55 left at 2 jobs at a time "
        "(mean of 1 finished pile: 0:22:30 of CPU per pile)")


def test_all_done(tmp_path):
    write_config(tmp_path, wedge=(1,), layered=())
    finished_pile(tmp_path, piles_of(tmp_path), "wedge", 1, (1000.0, 100.0, 50.0), NOW)
    assert sp.progress_line(tmp_path, config_of(tmp_path), 2, NOW) == (
        "study (results/study/): 1 of 1 piles done, 0 running, 0 left; all piles simulated")


def test_no_probe_levels(tmp_path):
    """Without gravity probes the last stage is relaxed."""
    path = write_config(tmp_path, wedge=(1,), layered=())
    config = yaml.safe_load(path.read_text())
    config["probe"] = {"levels": []}
    path.write_text(yaml.safe_dump(config))
    piles = piles_of(tmp_path)
    for stage in ("poured", "relaxed"):
        touch(tmp_path / piles.paths.pile("wedge", 1, stage))
    assert sp.progress_line(tmp_path, config_of(tmp_path), 2, NOW).startswith(
        "study (results/study/): 1 of 1 piles done")


def test_script_on_a_fake_tree(tmp_path):
    root = fake_study(tmp_path, now=time.time())
    result = subprocess.run([*TOOL, "--directory", str(root), "--cores", "2"],
                            capture_output=True, text=True, check=True, cwd=tmp_path)
    assert result.stderr == ""
    lines = result.stdout.splitlines()
    assert len(lines) == 1
    print(lines[0])
    assert re.fullmatch(
        r"config/config\.yaml \(results/study/\): 2 of 5 piles done, 2 running \(wedge 3: pour 78 %, ETA 0:0[56]:[0-5]\d; layered 2: "
        r"relax\), 1 left; 69 % of the simulation done, about 0:22:55 left at 2 jobs at a time "
        r"\(mean of 2 finished piles: 0:22:55 of CPU per pile\)", lines[0])
    other = write_config(tmp_path / "elsewhere", wedge=(1, 2), layered=())
    result = subprocess.run([*TOOL, "--directory", str(root),
                             "--configfile", str(other)],
                            capture_output=True, text=True, check=True)
    assert result.stdout.startswith("elsewhere/config/config.yaml (results/study/): 2 of 2 piles done, "
                                    "0 running, 0 left")


def test_every_prints_until_killed(tmp_path):
    root = fake_study(tmp_path, now=time.time())
    proc = subprocess.Popen([*TOOL, "--directory", str(root),
                             "--every", "0.2"], stdout=subprocess.PIPE, text=True)
    try:
        first, second = proc.stdout.readline(), proc.stdout.readline()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert first.startswith("config/config.yaml (results/study/): 2 of 5 piles done")
    assert second.startswith("config/config.yaml (results/study/): 2 of 5")


def test_counts_only_the_piles_of_its_own_results_folder(tmp_path):
    """The smoke run's piles (results/smoke) are not the study's: make progress
    after make smoke once said "4 of 19 piles done" (issue 29, item 2)."""
    write_config(tmp_path, wedge=(1, 2), layered=())
    smoke = tmp_path / "config" / "smoke.yaml"
    smoke.write_text(yaml.safe_dump({"protocols": {"wedge": {"seeds": [1, 2]}}, "threads": 1,
                                     "results": "results/smoke", "pour": {"n_particles": 150}}))
    for seed in (1, 2):
        finished_pile(tmp_path, Piles(load_config([smoke])), "wedge", seed, (10.0, 1.0, 1.0), NOW)
    assert sp.progress_line(tmp_path, config_of(tmp_path), 2, NOW).startswith(
        "study (results/study/): 0 of 2 piles done, 0 running, 2 left; 0 % of the simulation done")
    line = sp.progress_line(tmp_path, load_config([smoke]), 2, NOW, label="config/smoke.yaml")
    assert line == "config/smoke.yaml (results/smoke/): 2 of 2 piles done, 0 running, 0 left; all piles simulated"
    result = subprocess.run([*TOOL, "--directory", str(tmp_path), "--configfile",
                             str(tmp_path / "config" / "config.yaml"), str(smoke)],
                            capture_output=True, text=True, check=True, cwd=tmp_path)
    assert result.stdout.startswith("config/config.yaml, config/smoke.yaml (results/smoke/): 2 of 2 piles done")


def test_a_tree_from_before_the_results_folders_is_named(tmp_path):
    """Piles under results/piles/ (the layout before issue 29) are not counted, but named."""
    write_config(tmp_path, wedge=(1,), layered=())
    legacy = Piles(dict(config_of(tmp_path), results="results"))  # results/piles/..., results/logs/...
    finished_pile(tmp_path, legacy, "wedge", 1, (10.0, 1.0, 1.0), NOW)
    line = sp.progress_line(tmp_path, config_of(tmp_path), 2, NOW)
    assert line.startswith("study (results/study/): 0 of 1 piles done")
    assert "results/piles holds piles made before" in line and "move them to results/study/" in line


def test_committed_results_have_nothing_to_simulate(tmp_path):
    """make reproduction's configuration (committed results) pours no pile."""
    write_config(tmp_path)
    config = config_of(tmp_path)
    config.update(committed="docs/reproduction", results="results/reproduction")
    assert sp.progress_line(tmp_path, config, 2, NOW, label="config/reproduction.yaml") == (
        "config/reproduction.yaml (results/reproduction/): built from the per-pile results committed "
        "under docs/reproduction/, nothing to simulate")


def test_the_first_line_comes_within_a_minute(monkeypatch, capsys):
    """make run's first estimate comes after FIRST_LINE_S = 60 s, not after
    the interval of the lines (300 s in the Makefile)."""
    waits = []

    def sleep(seconds):
        waits.append(seconds)
        if len(waits) == 3:
            raise StopIteration

    monkeypatch.setattr(sp.time, "sleep", sleep)
    with pytest.raises(StopIteration):
        sp.watch(300.0, lambda: "the line")
    assert waits == [60.0, 300.0, 300.0]
    assert capsys.readouterr().out == "the line\nthe line\n"
