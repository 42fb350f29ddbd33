"""The table of run times: docs/run_times.md and the README's times, from workflow/run_times.json.

Every time the documents give for a ``make`` target or a pile is one row of
workflow/run_times.json, a measurement with the command that made it, the
host, the date and the commit (or "not recorded"); a target nobody has timed
has a row that says "not measured". This tool writes, from that file alone,

* docs/run_times.md: every row, then the estimate of ``make run`` by the
  cost model (:func:`workflow.tools.study_progress.cost_model`, priced by the
  table's row ``cost_model``), which is what ``make progress`` prints on a
  fresh clone;
* the README's table of times, between the lines :data:`BEGIN` and :data:`END`:
  the rows of :data:`README_ROWS` and that estimate, then the CPU per pile of
  the rows of :data:`README_PILES`.

So the README, ``make progress`` and the cost model read the same numbers.

Usage::

    .venv/bin/python -m workflow.tools run_times           # rewrite both
    .venv/bin/python -m workflow.tools run_times --check   # exit 1 when either is stale
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from sim.durations import hms
from workflow.piles import Piles
from workflow.resources import COST_BASIS, RUN_TIMES
from workflow.tools.study_progress import PileState, cost_model, time_left
from workflow.validation import load_config

from ._cli import ToolParser

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "run_times.md"
README = REPO / "README.md"
#: The study whose ``make run`` the cost model estimates, and the cores of the estimate.
STUDY = REPO / "config" / "config.yaml"
CORES = 2
#: The rows the README shows, in order (then the estimate of ``make run``).
README_ROWS = ("smoke", "test-xeon", "test-epyc", "reproduction")
#: The piles whose CPU the README shows, by source, size and step (the rows' ids), in order.
README_PILES = ("pile-1600-wedge-funnel-verlet099", "pile-1600-layered-rain29-verlet099",
                "pile-3500-wedge-funnel-equal-slope", "pile-3500-layered-rain29-equal-slope")
#: The measured piles that price the study's piles by protocol in :func:`measured_study` (row ids):
#: the equal-slope decision's sources at the study's size, the funnel and the rain at 29°.
MEASURED_STUDY = {"wedge": "pile-3500-wedge-funnel-equal-slope", "layered": "pile-3500-layered-rain29-equal-slope"}
BEGIN = "<!-- run times: written by python -m workflow.tools run_times from workflow/run_times.json -->"
END = "<!-- end of run times -->"
NOT_RECORDED = "not recorded"


def run_estimate(configfile=STUDY, cores=CORES):
    """``make run``'s simulations by the cost model, as ``make progress`` gives them before any pile.

    Parameters
    ----------
    configfile : path-like
        The study's configuration.
    cores : int
        Cores Snakemake runs on.

    Returns
    -------
    dict
        ``piles``; ``cpu_per_pile_s`` and ``cpu_s`` (all piles), CPU seconds;
        ``wall_s``, the wall seconds on `cores` (:func:`study_progress.time_left`
        with every pile left); ``jobs`` at a time; ``threads`` per job.
    """
    study = Piles(load_config([configfile]))
    means, _ = cost_model(study)
    stages = tuple(study.stages.all_stages())
    piles = [PileState(protocol, seed, "left", stages) for protocol, seed in study.each()]
    threads = study.config["threads"]
    wall, jobs = time_left(piles, means, cores, threads)
    per_pile = sum(means.values())
    return {"piles": len(piles), "cpu_per_pile_s": per_pile, "cpu_s": per_pile * len(piles),
            "wall_s": wall, "jobs": jobs, "threads": threads}


def measured_study(table, configfile=STUDY, cores=CORES):
    """The study's piles priced by whole piles measured at its size (:data:`MEASURED_STUDY`).

    Each protocol's piles cost the CPU of its measured pile (pour, relaxation
    and probes); one thread a pile, ``cores`` piles at a time, so the wall
    time is about the CPU over the cores (the last pile alone excepted).

    Returns
    -------
    dict
        ``counts`` (piles per protocol), ``cpu_s``, ``wall_s``, and ``rows``,
        the measured rows by protocol.
    """
    study = Piles(load_config([configfile]))
    rows = {row["id"]: row for row in table["rows"]}
    counts = {p: len(study.seeds(p)) for p in study.protocols}
    used = {p: rows[MEASURED_STUDY[p]] for p in counts}
    cpu = sum(counts[p] * used[p]["cpu_s"] for p in counts)
    return {"counts": counts, "cpu_s": cpu, "wall_s": cpu / cores, "rows": used}


def _time(seconds):
    """``h:mm:ss`` or "not measured"."""
    return "not measured" if seconds is None else hms(seconds)


def _cell(value):
    """A recorded field, or :data:`NOT_RECORDED` for a missing one."""
    return NOT_RECORDED if value is None else str(value)


def _where(row):
    """The host, date and commit of a row in words."""
    if row["wall_s"] is None and row["cpu_s"] is None:
        return "not measured"
    return (f"{_cell(row['host'])}; {row['date'] or 'date ' + NOT_RECORDED}; "
            f"commit {_cell(row['commit'])}")


def page(table, estimate):
    """docs/run_times.md.

    Parameters
    ----------
    table : dict
        workflow/run_times.json.
    estimate : dict
        :func:`run_estimate`.

    Returns
    -------
    str
    """
    basis = COST_BASIS
    lines = [
        "# Run times",
        "",
        "Written by `python -m workflow.tools run_times` from `workflow/run_times.json`; edit that file, "
        "not this page. Each row is one measurement, with the command, host, date and commit it was made "
        "with; a field nobody wrote down says \"not recorded\", a target nobody has timed \"not measured\". "
        "All hosts had 2 cores. Wall is elapsed time, CPU the processor time of the jobs (one thread each). "
        "The same code took twice as long in a slow hour of a shared host as in a fast one "
        "([performance.md](performance.md#what-a-pile-costs)), so only times from one host and hour compare.",
        "",
        "| id | what | wall | CPU | host; date; commit | command | recorded in |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in table["rows"]:
        cpu = _time(row["cpu_s"])
        if row.get("pour_cpu_s") is not None:
            cpu += f" (pour {hms(row['pour_cpu_s'])})"
        lines.append(f"| `{row['id']}` | {row['what']} | {_time(row['wall_s'])} | {cpu} | {_where(row)} | "
                     f"`{row['command']}` | {_cell(row['source'])} |")
    lines += [
        "",
        "## What `make run` takes: the cost model's estimate",
        "",
        f"No run of the whole study has been timed. Before a pile has finished, `make progress` estimates "
        f"the study by the cost model (`workflow/resources.py`): the particle-steps the configuration fixes, "
        f"times {basis['ns_per_particle_step']:.0f} ns of CPU per particle-step, the price of row "
        f"`{basis['id']}` ({basis['cpu_s']:.0f} CPU s for {basis['steps']} steps of a pour holding "
        f"{basis['particles'] // 2} particles on average). For `config/config.yaml` on {CORES} cores, "
        f"{estimate['threads']} thread per pile, {estimate['jobs']} piles at a time:",
        "",
        "| piles | CPU per pile | CPU in all | wall on 2 cores |",
        "|---|---|---|---|",
        f"| {estimate['piles']} | {hms(estimate['cpu_per_pile_s'])} | {hms(estimate['cpu_s'])} | "
        f"{hms(estimate['wall_s'])} |",
        "",
        "The model counts a pour as 1.5 × n_particles / rate of simulated time; the study's pours "
        "simulated 1.03–1.17 × n_particles / rate, 36–41 s for 35 s "
        "([performance.md](performance.md#how-long-full-size-pours-and-the-study)), so the estimate "
        "errs long. Once a pile has finished, `make progress` prices the rest by the "
        "finished piles' own benchmarks instead. SLURM jobs ask for the same estimate times a margin "
        "([cluster.md](cluster.md#what-each-job-asks-for)).",
        "",
        "## The study from measured piles of the decision's sources",
        "",
        _measured_text(measured_study(table)),
        "",
    ]
    return "\n".join(lines)


def _measured_text(measured):
    """The page's paragraph on :func:`measured_study`."""
    rows, counts = measured["rows"], measured["counts"]
    priced = "; ".join(f"{counts[p]} {p} piles at `{rows[p]['id']}`, {hms(rows[p]['cpu_s'])} each"
                       for p in counts)
    return (f"Priced by whole piles measured at the study's size ({priced}; "
            f"{_where(next(iter(rows.values())))}), the study's {sum(counts.values())} piles would take "
            f"{hms(measured['cpu_s'])} of CPU, about {hms(measured['wall_s'])} on {CORES} cores, one thread "
            "a pile. Those are the equal-slope decision's sources (the funnel and the rain at 29°), not "
            "`make run`'s (the drip and the top band, whose 3500-particle pours alone cost 36 and 33 min of CPU: "
            "rows `pour-3500-wedge`, `pour-3500-layered`); `make run` pours the study's own.")


def readme_block(table, estimate):
    """The README's table of times, :data:`BEGIN` and :data:`END` included.

    Parameters
    ----------
    table, estimate
        As for :func:`page`.

    Returns
    -------
    str
    """
    rows = {row["id"]: row for row in table["rows"]}
    lines = [BEGIN, "| command | wall time | host; date; commit |", "|---|---|---|"]
    for key in README_ROWS:
        row = rows[key]
        command = row["what"].split(":")[0]
        lines.append(f"| {command} | {_time(row['wall_s'])} | {_where(row)} |")
    lines += [f"| `make run` | about {hms(estimate['wall_s'])}, an estimate ({hms(estimate['cpu_s'])} of CPU "
              f"for {estimate['piles']} piles, {estimate['jobs']} at a time) | the cost model priced by "
              f"`{COST_BASIS['id']}`: {COST_BASIS['host']}; {COST_BASIS['date']}; commit "
              f"{COST_BASIS['commit']} |"]
    measured = measured_study(table)
    lines += [f"| the same {sum(measured['counts'].values())} piles from the equal-slope decision's sources "
              f"(funnel, rain at 29°) | about {hms(measured['wall_s'])}, from measured piles "
              f"({hms(measured['cpu_s'])} of CPU; [run_times.md](docs/run_times.md)) | "
              f"{_where(next(iter(measured['rows'].values())))} |", "",
              "What one pile costs, by source, size and step (CPU of its pour, relaxation and probes; "
              "[docs/run_times.md](docs/run_times.md) has every measured pile):", "",
              "| pile | CPU per pile | host; date; commit |", "|---|---|---|"]
    for key in README_PILES:
        row = rows[key]
        lines.append(f"| {row['what'].split(':')[0]} | {_time(row['cpu_s'])} | {_where(row)} |")
    lines.append(END)
    return "\n".join(lines)


def with_block(text, block):
    """`text` (the README) with its table of times replaced by `block`.

    Raises
    ------
    ValueError
        When the README lacks the lines :data:`BEGIN` and :data:`END`, in that order.
    """
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise ValueError(f"README.md has no table of run times: put the lines {BEGIN!r} and {END!r} "
                         "where it belongs")
    return text[:start] + block + text[end + len(END):]


def outputs(table_path=RUN_TIMES, readme=README):
    """{path: text} of the two files as the table makes them."""
    table = json.loads(Path(table_path).read_text(encoding="utf-8"))
    estimate = run_estimate()
    return {PAGE: page(table, estimate),
            Path(readme): with_block(Path(readme).read_text(encoding="utf-8"), readme_block(table, estimate))}


def main(argv=None):
    """Command line: write docs/run_times.md and the README's times, or check them."""
    parser = ToolParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 naming the files the table would change")
    args = parser.parse_args(argv)
    stale = []
    for path, text in outputs().items():
        current = path.read_text(encoding="utf-8") if path.exists() else None
        if current != text:
            stale.append(path)
            if not args.check:
                path.write_text(text, encoding="utf-8")
    if args.check and stale:
        print("stale: " + ", ".join(str(p.relative_to(REPO)) for p in stale)
              + " (run python -m workflow.tools run_times)", file=sys.stderr)
        return 1
    return 0
