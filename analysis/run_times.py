"""Run times of workflow jobs: Snakemake benchmark files and the output of bash ``times``.

A Snakemake benchmark file (``benchmark:`` of a rule) is a TSV with the
wall-clock time in column ``s`` and the CPU time in ``cpu_time``; bash
``times`` after a command prints the CPU time of the shell's children,
which, unlike the wall time, does not grow when other processes share the
cores.
"""

from __future__ import annotations

import csv
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
