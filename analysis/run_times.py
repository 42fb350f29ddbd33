"""Run times of workflow jobs: Snakemake benchmark files, the stages' own CPU lines, and bash ``times``.

A Snakemake benchmark file (``benchmark:`` of a rule) is a TSV with the
wall-clock time in column ``s`` and the CPU time in ``cpu_time``; bash
``times`` after a command prints the CPU time of the shell's children,
which, unlike the wall time, does not grow when other processes share the
cores.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np


def benchmark_time(path, column: str = "s") -> float:
    """A time in s from a Snakemake benchmark file: ``column`` ``s`` (wall clock) or
    ``cpu_time`` (sampled every 0.5 s for 15 s, then every 30 s); mean of its rows.

    Raises
    ------
    ValueError
        If the column is missing or not a number (``NA``).
    """
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh, delimiter="\t"))
    try:
        return float(np.mean([float(r[column]) for r in rows])) if rows else float("nan")
    except (KeyError, ValueError):
        raise ValueError(f"benchmark file {path}: no number in column {column!r}") from None


#: The end of a stage's summary line (:func:`sim.progress.summary`): its process's own CPU.
_STAGE_CPU = re.compile(r" done: wall .*; CPU ([0-9.]+) s in this process$")


def stage_cpu_time(path) -> float:
    """CPU seconds of a simulation stage (pour, relaxation, probe) from its log: the
    count its summary line gives (``... done: wall ...; CPU X s in this process``,
    the process's own getrusage, all threads) on the last such line; NaN when the
    log has none (a stage that failed, or a log from before the line existed).

    Unlike a Snakemake benchmark file, which samples every 30 s after a job's
    first 15 s and misses its last seconds, the line counts the whole stage up
    to the writing of its state file; a pour resumed from a checkpoint counts
    only its last process.
    """
    found = [m.group(1) for line in Path(path).read_text().splitlines()
             if (m := _STAGE_CPU.search(line))]
    return float(found[-1]) if found else float("nan")


def _minutes_seconds(text: str) -> float:
    minutes, seconds = text.rstrip("s").split("m")
    return 60.0 * float(minutes) + float(seconds)


def children_cpu_time(path) -> float:
    """User + system CPU seconds of a shell's children, from the output of bash ``times``.

    ``times`` prints two lines, ``XmY.YYYs XmY.YYYs`` for the shell itself and
    for its children; the second line is the command the shell ran.
    """
    lines = Path(path).read_text().split("\n")
    try:
        user, system = lines[1].split()
        return _minutes_seconds(user) + _minutes_seconds(system)
    except (IndexError, ValueError):
        raise ValueError(f"{path}: not the output of bash 'times' (two lines 'XmY.YYYs XmY.YYYs')") from None


def benchmark_row(path) -> dict:
    """Wall time, CPU time (s) and peak memory (MB) of one job's benchmark file
    (means over its rows); ``cores`` is CPU time over wall time, NaN where
    either is missing.

    Raises
    ------
    ValueError
        If the file has no row with a wall time in column ``s``: it is not a
        Snakemake benchmark file (or an empty one).
    """
    wall = benchmark_time(path, "s")  # raises for a file without the column
    if not wall == wall:
        raise ValueError(f"benchmark file {path}: no rows (a Snakemake benchmark file has a header "
                         "line and one row per run, with the wall time in column 's')")
    out = {"wall_s": wall}
    for key, column in (("cpu_s", "cpu_time"), ("max_rss_mb", "max_rss")):
        try:
            out[key] = benchmark_time(path, column)
        except ValueError:
            out[key] = float("nan")
    out["cores"] = out["cpu_s"] / out["wall_s"] if out["wall_s"] > 0 else float("nan")
    return out


def job_label(path) -> str:
    """``"<rule> <protocol> <name>"`` of a benchmark file
    ``benchmarks/<rule>/<protocol>/<name>.tsv`` (e.g. ``pour wedge seed1``)."""
    p = Path(path)
    return f"{p.parent.parent.name} {p.parent.name} {p.stem}"


def run_times_html(jobs: dict[str, str], title: str) -> str:
    """An HTML page with one table row per job and the totals per kind of job.

    Parameters
    ----------
    jobs : dict
        Label ``"<kind> <pile>"`` (e.g. ``"pour wedge seed1"``) to the job's
        benchmark file.
    title : str
        Heading of the page.
    """
    import html

    rows = {label: benchmark_row(path) for label, path in jobs.items()}

    def row(head, wall, cpu, memory):
        cores = f"{cpu / wall:.2f}" if wall > 0 else "nan"
        return (f"<tr>{head}<td>{wall / 60:.2f}</td><td>{cpu / 60:.2f}</td><td>{cores}</td>"
                f"<td>{memory:.0f}</td></tr>")

    body = [row(f"<td>{html.escape(label)}</td>", r["wall_s"], r["cpu_s"], r["max_rss_mb"])
            for label, r in rows.items()]
    for kind in sorted({label.split()[0] for label in rows}):
        group = [r for label, r in rows.items() if label.split()[0] == kind]
        body.append(row(f"<th>{html.escape(kind)}: {len(group)} jobs</th>",
                        float(np.nansum([r["wall_s"] for r in group])),
                        float(np.nansum([r["cpu_s"] for r in group])),
                        float(np.nanmax([r["max_rss_mb"] for r in group]))))
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title><style>"
        "table{border-collapse:collapse;font-family:sans-serif;font-size:14px}"
        "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}</style></head><body>\n"
        f"<h3>{html.escape(title)}</h3>\n<table>\n"
        "<tr><th>job</th><th>wall (min)</th><th>CPU (min)</th><th>cores used</th>"
        "<th>peak memory (MB)</th></tr>\n" + "\n".join(body) + "\n</table>\n</body></html>\n")
