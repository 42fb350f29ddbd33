"""One line on the progress of the study: piles done, running and left, and
the time left (make run and make progress print it).

The piles, their stages and the paths of their files are those the
workflow makes (:class:`workflow.piles.Piles` of the configuration, as the
Snakefile reads it): the piles of ``protocols``, looked for in the
configuration's own results folder (config ``results``: ``results/study`` for
``config/config.yaml``, ``results/smoke`` for ``config/smoke.yaml``), so the
piles of another configuration never count; the line begins with the
configuration files and that folder. A pile is

* **done** when its last stages exist (``Stages.final_stages``): every probe,
  the gravity probes of ``probe.levels`` (``reduced.nc``, ``reducedNN.nc``)
  and those a scene adds (tilts, the support stretch, the restored gravity),
  or ``relaxed.nc`` when there is none. Before the stages came from ``Piles``
  the scene's probes were left out, so that a pile with only its gravity
  probes counted as done and the time left missed the other probes;
* **running** when it is not done and either pours, its pour's lock
  (``pour.checkpoint.nc.lock``, :class:`sim.lock.PourLock`) held by a live
  process, or has poured and one of its logs was written in the last
  :data:`RECENT_S` seconds;
* **interrupted (resumable)** when it has not poured, no live process holds
  its pour's lock, but a checkpoint or a stale lock is left of a pour that
  was killed: the next ``make run`` resumes it;
* **left** otherwise (not started, or waiting between stages).

The time left is the work still to do divided by the cores it can use. The
work is counted in CPU seconds: a stage not yet run costs the mean
``cpu_time`` of that stage in the Snakemake benchmark files
(``PilePaths.stage_benchmark``) of the finished piles; the stage
a running pile is in costs what the ETA of its log's last progress line
(``sim.progress.Progress``) says instead, when there is one. The cores it
can use are the jobs that run side by side, ``cores // threads``, but no more
than there are unfinished piles; and the study cannot end before its longest
single pile. The share done is one less the work left over the work of the
whole study (its piles times the mean CPU seconds of a finished pile). Before
any pile has finished (with benchmark files) the CPU seconds of each stage are
the estimate of the bench's cost model instead
(``workflow.resources.SimResources.stage_cpu_s``: the particle-steps the
configuration fixes times the nanoseconds per particle-step of a measured
pour, the run-time table's (workflow/run_times.json, docs/run_times.md)), and
the line says so. Only the simulations are counted, not
the analysis after them. Times are written ``h:mm:ss`` (``sim.durations.hms``).

Usage::

    .venv/bin/python -m workflow.tools study_progress [--configfile config/config.yaml [FILE ...]]
        [--cores N] [--directory DIR] [--every SECONDS]

Several ``--configfile`` files are merged in order, as Snakemake merges them.

``--every`` prints the line every SECONDS seconds until killed (``make run``
starts it in the background), or until the process that started it is gone;
the first line comes after at most :data:`FIRST_LINE_S` seconds.
"""

from __future__ import annotations

import csv
import math
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path


from sim.durations import hms, parse_hms
from sim.lock import PourLock
from workflow.piles import Piles
from workflow.stages import stage_rule
from workflow.resources import COST_BASIS, PARTICLE_STEP_S, SimResources
from workflow.validation import load_config

from ._cli import ToolParser, existing_file, existing_folder, positive_float, positive_int, refuse

# A pile whose log was written this recently (s) counts as running.
RECENT_S = 300.0
# How much of the end of a log (bytes) is searched for its last progress line.
LOG_TAIL_BYTES = 65536
# With --every, the first line comes this many seconds after the start (or
# sooner): make run's first estimate, once Snakemake has started the pours.
FIRST_LINE_S = 60.0

# Parts of a progress line of sim.progress.Progress, e.g.
# "pour wedge seed 3: released 2743 of 3500 (78 %), ETA 0:06:37; t = 31.9000 s
#  simulated, about 3.2000 s to go, 4705393 steps, 1100 ns per particle-step" or
# "relax ...: ETA at most 0:02:00; ..., 3500 particles, ..."; lines written
# before issue 29 say "ETA 397 s" and "2743 particles".
_ETA = re.compile(r"\bETA (?:at most )?(\S+?)(?: s)?(?=[;,]|$)")
_PARTICLES = re.compile(r"\breleased (\d+) of \d+\b|\b(\d+) particles\b")


@dataclass(frozen=True)
class PileState:
    """Where one pile stands.

    Attributes
    ----------
    protocol : str
    seed : int
    state : {"done", "running", "interrupted", "left"}
    missing : tuple of str
        Its stages without a state file, in order; the first one is the stage
        it is in (or waits for).
    eta : float or None
        Wall seconds still to go of the stage it is in, from the last progress
        line of that stage's log; None without one.
    at_most : bool
        The ETA is an upper bound (a relaxation stops once at rest).
    fraction : float or None
        Fraction of the particles released, for a pour with a progress line.
    """

    protocol: str
    seed: int
    state: str
    missing: tuple = ()
    eta: float | None = None
    at_most: bool = False
    fraction: float | None = None


def benchmark_cpu(path):
    """CPU seconds of a finished job from its Snakemake benchmark file.

    Parameters
    ----------
    path : path-like
        Tab-separated, a header line, one row per repeat (``--benchmark-repeats``).

    Returns
    -------
    float or None
        Mean ``cpu_time`` over the rows (the wall seconds ``s`` of a row
        without a number there); None when the file is missing or holds no
        number.
    """
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f, delimiter="\t"))
    except OSError:
        return None
    values = []
    for row in rows:
        for column in ("cpu_time", "s"):
            try:
                value = float(row.get(column) or "nan")
            except ValueError:
                continue
            if math.isfinite(value):
                values.append(value)
                break
    return sum(values) / len(values) if values else None


def parse_progress(line):
    """ETA and particle count of a progress line of ``sim.progress.Progress``.

    Parameters
    ----------
    line : str

    Returns
    -------
    tuple (float, int or None, bool) or None
        (ETA in wall seconds, particles (those released, for a pour), whether
        the ETA is an upper bound "at most"); None for a line without a
        known ETA (``ETA unknown``, ``ETA nan s``).
    """
    eta = _ETA.search(line.rstrip())
    if eta is None:
        return None
    seconds = parse_hms(eta.group(1))
    if seconds is None:  # a line written before issue 29: "ETA 397 s"
        try:
            seconds = float(eta.group(1))
        except ValueError:
            return None
    if not math.isfinite(seconds):
        return None
    particles = _PARTICLES.search(line)
    count = int(particles.group(1) or particles.group(2)) if particles else None
    return seconds, count, " at most " in line


def last_progress(path):
    """The last progress line of a log, parsed by :func:`parse_progress`.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    tuple or None
        As :func:`parse_progress`; None for a missing log or one without a
        progress line (in its last :data:`LOG_TAIL_BYTES` bytes).
    """
    try:
        with open(path, "rb") as f:
            f.seek(max(f.seek(0, os.SEEK_END) - LOG_TAIL_BYTES, 0))
            lines = f.read().decode("utf-8", "replace").splitlines()
    except OSError:
        return None
    for line in reversed(lines):
        parsed = parse_progress(line)
        if parsed is not None:
            return parsed
    return None


def _age(path, now):
    """Seconds since `path` was last written; None if it does not exist."""
    try:
        return now - Path(path).stat().st_mtime
    except OSError:
        return None


def pour_running(root, study, protocol, seed):
    """Whether a live process holds the pour lock of a pile.

    Parameters
    ----------
    root : path-like
        The workflow's directory, which the paths of `study` are relative to.
    study : workflow.piles.Piles
    protocol : str
    seed : int

    Returns
    -------
    bool
        False without a lock file, or when its holder ("host pid") is gone as
        the simulator judges it (:class:`sim.lock.PourLock`: no such process
        on this host; another host's lock not refreshed for three checkpoint
        intervals and a minute, the ``stale_after`` of ``sim.pour.pour``).
    """
    lock = Path(root) / pour_lock(study, protocol, seed)
    stale_after = 3 * float(study.config["pour"]["checkpoint_interval"]) + 60.0
    try:
        return PourLock(lock, stale_after)._holder_alive(lock.read_text().strip())
    except OSError:  # no lock (or gone while read)
        return False


def pour_lock(study, protocol, seed):
    """The pour's lock file: ``<checkpoint>.lock`` beside its checkpoint (``sim.pour.pour``)."""
    return study.paths.pour_checkpoint(protocol, seed) + ".lock"


def pile_state(root, study, protocol, seed, now):
    """Where one pile stands (see the module's docstring for the rules).

    Parameters
    ----------
    root : path-like
        The workflow's directory, which the paths of `study` are relative to.
    study : workflow.piles.Piles
        The piles of the configuration (its ``pour.n_particles`` for the
        fraction of a pour).
    protocol : str
    seed : int
    now : float
        Time (s since the epoch) the logs' ages are measured at.

    Returns
    -------
    PileState
        The ETA of a running stage is its last progress line's less the time
        since the log was written while the log is recent; that of an
        interrupted pour is taken as it stands, the work its stage still
        needs when it resumes.
    """
    root, stages = Path(root), study.stages.all_stages()
    missing = tuple(s for s in stages if not (root / study.paths.pile(protocol, seed, s)).exists())
    if not set(study.stages.final_stages()) & set(missing):
        return PileState(protocol, seed, "done")
    stage = missing[0]
    if stage != "poured":
        ages = [_age(root / study.paths.stage_log(protocol, seed, s), now) for s in stages]
        state = "running" if any(a is not None and a < RECENT_S for a in ages) else "left"
    elif pour_running(root, study, protocol, seed):
        state = "running"
    elif any((root / path).exists() for path in (study.paths.pour_checkpoint(protocol, seed),
                                                  pour_lock(study, protocol, seed))):
        state = "interrupted"
    else:
        state = "left"
    if state == "left":
        return PileState(protocol, seed, "left", missing)
    log = root / study.paths.stage_log(protocol, seed, stage)
    progress = last_progress(log)
    if progress is None:
        return PileState(protocol, seed, state, missing)
    eta, particles, at_most = progress
    age = _age(log, now)
    if state == "running" and age is not None and 0 < age < RECENT_S:
        eta = max(eta - age, 0.0)
    n_particles = int(study.config["pour"]["n_particles"])
    fraction = particles / n_particles if stage == "poured" and particles else None
    return PileState(protocol, seed, state, missing, eta, at_most, fraction)


def stage_means(root, study, piles):
    """Mean CPU seconds of each stage over the finished piles with benchmarks.

    Parameters
    ----------
    root : path-like
        The workflow's directory, which the paths of `study` are relative to.
    study : workflow.piles.Piles
        The piles of the configuration, for their stages and benchmark files.
    piles : list of PileState

    Returns
    -------
    (dict, int)
        Mean CPU seconds per stage (empty when no pile counts) and the number
        of piles averaged: the done ones with a benchmark of every stage.
    """
    rows, stages = [], study.stages.all_stages()
    for p in piles:
        if p.state == "done":
            cpu = [benchmark_cpu(Path(root) / study.paths.stage_benchmark(p.protocol, p.seed, s)) for s in stages]
            if None not in cpu:
                rows.append(cpu)
    means = {s: sum(r[i] for r in rows) / len(rows) for i, s in enumerate(stages)} if rows else {}
    return means, len(rows)


def pile_work(pile, means, cores_per_job):
    """CPU seconds a pile still needs: the mean of each missing stage, with
    the ETA (wall seconds on `cores_per_job` cores) for the stage it runs or
    was interrupted in."""
    work = [means[s] for s in pile.missing]
    if pile.eta is not None:
        work[0] = pile.eta * cores_per_job
    return sum(work)


def time_left(piles, means, cores, threads):
    """Wall seconds the simulations of the study still need.

    Parameters
    ----------
    piles : list of PileState
    means : dict
        :func:`stage_means`; empty: unknown.
    cores : int
        Cores Snakemake runs jobs on (``--cores``).
    threads : int
        Threads (cores) per simulation job (config ``threads``).

    Returns
    -------
    (float or None, int)
        Seconds (None when `means` is empty) and the jobs at a time: the
        unfinished work over the cores the jobs occupy, at least the longest
        single pile's work.
    """
    todo = [p for p in piles if p.state != "done"]
    per_job = _cores_per_job(cores, threads)
    jobs = min(max(int(cores) // per_job, 1), len(todo))
    if not means or not todo:
        return (None if not means and todo else 0.0), jobs
    work = [pile_work(p, means, per_job) for p in todo]
    return max(sum(work) / (jobs * per_job), max(work) / per_job), jobs


def _cores_per_job(cores, threads):
    """Cores one simulation job occupies: its threads, at most `cores`."""
    return max(min(int(threads), int(cores)), 1)


def fraction_done(piles, means, cores, threads):
    """Share of the study's simulation work done.

    Parameters
    ----------
    piles, means, cores, threads
        As for :func:`time_left` (`cores` and `threads` give the CPU seconds
        of a running stage's ETA).

    Returns
    -------
    float or None
        ``1 - work left / (piles × mean CPU seconds per pile)``, within [0, 1],
        the work left as :func:`pile_work` counts it; None when `means` is empty.
    """
    if not means or not piles:
        return None
    per_job = _cores_per_job(cores, threads)
    left = sum(pile_work(p, means, per_job) for p in piles if p.state != "done")
    return min(max(1.0 - left / (len(piles) * sum(means.values())), 0.0), 1.0)


def describe_running(pile):
    """A running pile in words: ``wedge 3: pour 78 %, ETA 0:06:30``; an
    interrupted one: ``wedge 3: pour 78 %, 0:06:37 to go``."""
    stage = pile.missing[0]
    what = stage_rule(stage) if stage in ("poured", "relaxed", "reduced") else f"probe {stage}"
    text = f"{pile.protocol} {pile.seed}: {what}"
    if pile.fraction is not None:
        text += f" {math.floor(100 * pile.fraction)} %"
    if pile.eta is not None:
        bound = "at most " if pile.at_most else ""
        text += (f", ETA {bound}{hms(pile.eta)}" if pile.state == "running"
                 else f", {bound}{hms(pile.eta)} to go")
    return text


def progress_line(root, config, cores, now, label="study"):
    """The line on the progress of the study.

    Parameters
    ----------
    root : path-like
        The workflow's directory; the piles, logs and benchmarks are in the
        configuration's results folder below it.
    config : dict
        Validated configuration (:func:`workflow.validation.load_config`).
    cores : int
    now : float
        Time (s since the epoch).
    label : str
        What the line begins with: the configuration files.

    Returns
    -------
    str
        E.g. ``config/config.yaml (results/study/): 3 of 19 piles done, 2
        running (wedge 3: pour 78 %, ETA 0:06:30; layered 2: relax), 14 left;
        26 % of the simulation done, about 9:30:00 left at 2 jobs at a time
        (mean of 3 finished piles: 1:22:00 of CPU per pile)``.
    """
    if config.get("committed"):
        return (f"{label} ({config['results']}/): built from the per-pile results committed under "
                f"{config['committed']}/, nothing to simulate")
    study = Piles(config)
    line = f"{label} ({study.paths.folder}/): " + _progress(root, study, cores, now)
    legacy = Path(root) / "results" / "piles"
    if not (Path(root) / study.paths.folder).is_dir() and legacy.is_dir():
        line += (f"; {legacy} holds piles made before each configuration had its results folder: "
                 f"move them to {config['results']}/ (docs/workflow.md, \"Results folders\")")
    return line


def _progress(root, study, cores, now):
    """:func:`progress_line` after its label, for the piles `study` (a
    :class:`workflow.piles.Piles`) in the workflow's directory `root`."""
    piles = [pile_state(root, study, protocol, seed, now) for protocol, seed in study.each()]
    done = [p for p in piles if p.state == "done"]
    running = [p for p in piles if p.state == "running"]
    interrupted = [p for p in piles if p.state == "interrupted"]
    left = len(piles) - len(done) - len(running) - len(interrupted)
    line = f"{len(done)} of {len(piles)} piles done, {len(running)} running"
    if running:
        line += " (" + "; ".join(describe_running(p) for p in running) + ")"
    if interrupted:
        line += (f", {len(interrupted)} interrupted (resumable: "
                 + "; ".join(describe_running(p) for p in interrupted) + ")")
    line += f", {left} left; "
    if len(done) == len(piles):
        return line + "all piles simulated"
    means, counted = stage_means(root, study, piles)
    if means:
        basis = (f"mean of {counted} finished pile{'s' * (counted != 1)}: "
                 f"{hms(sum(means.values()))} of CPU per pile")
    else:
        means, basis = cost_model(study)
    threads = study.config["threads"]
    seconds, jobs = time_left(piles, means, cores, threads)
    done_pct = math.floor(100 * fraction_done(piles, means, cores, threads))
    return (line + f"{done_pct} % of the simulation done, about {hms(seconds)} left at "
            f"{jobs} job{'s' * (jobs != 1)} at a time ({basis})")


def cost_model(study):
    """CPU seconds per stage by the bench's cost model, and the words that say so.

    Parameters
    ----------
    study : workflow.piles.Piles

    Returns
    -------
    (dict, str)
        :meth:`workflow.resources.SimResources.stage_cpu_s` of each stage of
        a pile, and what the estimate rests on: the particle-steps of a pile,
        which the configuration alone fixes (particles, the slowest source's
        flux, time step), times the ns per particle-step of the run-time table's
        measured pour (``workflow.resources.COST_BASIS``), named with its commit, host and date.
    """
    model = SimResources(study.config)
    stages = study.stages.all_stages()
    means = {s: model.stage_cpu_s(s) for s in stages}
    pour, m = study.config["pour"], study.config["model"]
    steps = sum(model.particle_steps(s) for s in stages)
    dt = (f"model.dt = {m['dt']:.3g} s" if m["dt"] is not None
          else f"automatic time step of {m['integrator']} about {model.estimated_dt():.3g} s")
    relax_s = model.relax_simulated_s()
    return means, (f"estimate from the cost model until a pile has finished: "
                   f"{steps:.3g} particle-steps per pile, host-independent, from "
                   f"pour.n_particles = {pour['n_particles']}, {model.rate_text()}, "
                   f"{dt} and {len(stages) - 1} relaxing stage{'s' * (len(stages) != 2)} of "
                   f"about {relax_s:g} s simulated, x {PARTICLE_STEP_S * 1e9:.0f} ns per "
                   f"particle-step as measured ({COST_BASIS['id']}: {COST_BASIS['commit']}, "
                   f"{COST_BASIS['host']}, {COST_BASIS['date']}; docs/run_times.md): "
                   f"{hms(sum(means.values()))} of CPU per pile")


def _shown(path, root):
    """A configuration file's path as the line names it: relative to the
    workflow's directory `root` or to this one when it lies below, else as given."""
    path = Path(path)
    for base in (Path(root), Path.cwd()):
        try:
            return str(path.absolute().relative_to(base.absolute()))
        except ValueError:
            pass
    return str(path)


def available_cores():
    """Cores this process may run on (what ``snakemake --cores all`` uses)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def watch(every, line):
    """Print ``line()`` every `every` seconds until killed or until the
    process that started this one has gone (this one is then re-parented).

    Parameters
    ----------
    every : float
        Seconds between lines; the first comes after `every` seconds or
        :data:`FIRST_LINE_S`, whichever is less.
    line : callable
        Returns the line to print.
    """
    parent = os.getppid()
    wait = min(every, FIRST_LINE_S)
    while True:
        time.sleep(wait)
        wait = every
        if os.getppid() != parent:
            return
        print(line(), flush=True)


def main(argv=None):
    """Command line: print the line once, or every ``--every`` seconds."""
    parser = ToolParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--configfile", nargs="+", type=existing_file,
                        help="configuration files, merged in order (default: DIR/config/config.yaml)")
    parser.add_argument("--cores", type=positive_int, default=available_cores(),
                        help="cores Snakemake runs on (default: all of this machine)")
    parser.add_argument("--directory", type=existing_folder, default=Path("."),
                        help="the workflow's directory DIR (default: .)")
    parser.add_argument("--every", type=positive_float, help="print the line every EVERY seconds until killed")
    args = parser.parse_args(argv)
    root = args.directory
    files = args.configfile or [root / "config" / "config.yaml"]
    try:
        config = load_config(files)
    except ValueError as exc:   # the configuration's own message, naming the file and setting
        refuse(" ".join(str(exc).split()))
    label = ", ".join(_shown(f, root) for f in files)

    def line():
        try:
            return progress_line(root, config, args.cores, time.time(), label)
        except (OSError, ValueError, KeyError) as exc:  # one line, also mid-write
            return f"{label}: progress unknown ({type(exc).__name__}: {exc})"

    if args.every:
        watch(args.every, line)
    else:
        print(line(), flush=True)
