"""The step against the decision's error: the paired bias of each statistic at coarser steps, and the step it picks.

Reads the plan (``config/step_error.yaml``: its candidate arms, each naming
its ``step`` and its ``reference`` arm; the reference's plan and records;
the statistics; ``quarter`` and ``level``), the candidates' records
(``docs/reproduction/step_error/``, each checked against the plan) and the
reference's (the equal-slope decision's, checked against its own plan), and
writes the table of docs/reproduction/step_error_plan.md's rule
(:func:`analysis.step_error.paired_bias`, :func:`analysis.step_error.choose_step`):
per arm and statistic, each candidate's bias against the reference paired by
seed, its 95 % bound in scatters and sd(d)/σ; the CPU per pile; and the step
the rule picks, with the largest bound among its cells.

Usage::

    .venv/bin/python -m workflow.tools step_error [--plan config/step_error.yaml] \\
        [--records docs/reproduction/step_error] [--out docs/reproduction/step_error.md]
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from analysis.step_error import choose_step, paired_bias

from ._cli import ToolParser, output_file, refuse, shown
from ._records import check_registered, read_records, read_registration

REPO = Path(__file__).resolve().parents[2]
PLAN = REPO / "config" / "step_error.yaml"
RECORDS = REPO / "docs" / "reproduction" / "step_error"


def value(record: dict, where: list) -> float:
    """The statistic at ``where`` (``[section, key]``) of a record; NaN when it is not there."""
    return float(record.get(where[0], {}).get(where[1], math.nan))


def by_seed(records: list, arm: str, where: list) -> dict[int, float]:
    """``{seed: statistic}`` of one arm's records."""
    return {r["seed"]: value(r, where) for r in records if r["arm"] == arm}


def read_plan(plan: Path) -> dict:
    """The plan, refused in one line where it lacks what the table reads."""
    reg = read_registration(plan)
    for key, kind in (("reference", dict), ("statistics", dict), ("quarter", float), ("level", float)):
        if not isinstance(reg.get(key), kind):
            refuse(f"{plan}: {key} = {reg.get(key)!r}; allowed is a {kind.__name__}")
    for arm, spec in reg["arms"].items():
        if not (isinstance(spec.get("step"), str) and isinstance(spec.get("reference"), str)):
            refuse(f"{plan}: arm {arm!r} names no step and reference arm; allowed: step: TEXT, reference: ARM")
    return reg


def cell_text(cell) -> str:
    """A table cell: the bias ± its standard error, the bound in scatters, sd(d)/σ and the pairs."""
    if cell.n < 2:
        return f"({cell.n} pairs)"
    return f"{cell.bias:+.3g} ± {cell.se:.2g}; ≤ {cell.bound:.2f} σ; sd(d)/σ {cell.pairing:.2f} ({cell.n})"


def page(plan: Path, records_folder: Path) -> str:
    """The table and the rule's choice, as a Markdown page."""
    reg = read_plan(plan)
    found = read_records(records_folder)
    check_registered(found, plan)
    records = list(found.values())
    ref_plan = REPO / reg["reference"]["plan"]
    ref_found = read_records(REPO / reg["reference"]["records"], "reference.records")
    check_registered(ref_found, ref_plan)
    reference = list(ref_found.values())
    steps = list(dict.fromkeys(spec["step"] for spec in reg["arms"].values()))
    ref_arms = list(dict.fromkeys(spec["reference"] for spec in reg["arms"].values()))
    arm_of = {(spec["step"], spec["reference"]): arm for arm, spec in reg["arms"].items()}
    cpu = ["cpu_s", "total"]
    paired_seeds = set(reg["seeds"])
    cells = {s: [] for s in steps}
    lines = []
    for ref_arm in ref_arms:
        ref_all = [r for r in reference if r["arm"] == ref_arm]
        ref_paired = [r for r in ref_all if r["seed"] in paired_seeds]
        lines += [f"\n## {ref_arm}\n", f"Reference: {reg['reference']['step']}, {len(ref_all)} piles for the "
                  f"scatter σ, {len(ref_paired)} of them paired (seeds {min(paired_seeds)}-{max(paired_seeds)}).\n",
                  "| statistic | σ | " + " | ".join(steps) + " |", "|---|---|" + "---|" * len(steps)]
        for name, where in reg["statistics"].items():
            row = []
            for step in steps:
                c = paired_bias(by_seed(records, arm_of[(step, ref_arm)], where), by_seed(ref_paired, ref_arm, where),
                                [value(r, where) for r in ref_all], reg["level"])
                cells[step].append(c)
                row.append(cell_text(c) + (" **fails**" if c.fails(reg["quarter"]) else ""))
            lines.append(f"| {name} | {cells[steps[0]][-1].scatter:.3g} | " + " | ".join(row) + " |")
        ref_cpu = np.mean([value(r, cpu) for r in ref_paired])
        row = []
        for step in steps:
            mine = by_seed(records, arm_of[(step, ref_arm)], cpu)
            ratio = [mine[s] / value(r, cpu) for r in ref_paired for s in [r["seed"]] if s in mine]
            row.append(f"{np.mean(list(mine.values())):.0f} ({len(mine)}); paired ratio "
                       f"{np.median(ratio):.2f}" if mine else "–")
        lines.append(f"| CPU s per pile | reference {ref_cpu:.0f} ({len(ref_paired)}) | " + " | ".join(row) + " |")
    cost = {}
    complete = {}
    for step in steps:
        mine = [r for r in records if reg["arms"][r["arm"]]["step"] == step]
        complete[step] = (len(mine), len(ref_arms) * len(reg["seeds"]))
        cost[step] = float(np.mean([np.mean([value(r, cpu) for r in mine if r["arm"] == arm_of[(step, a)]] or [math.nan])
                                    for a in ref_arms]))
    ref_cost = float(np.mean([np.mean([value(r, cpu) for r in reference if r["arm"] == a and r["seed"] in paired_seeds])
                              for a in ref_arms]))
    chosen, reasons = choose_step(cost, ref_cost, complete, cells, reg["quarter"])
    if chosen is None:
        verdict = f"**The step stays {reg['reference']['step']}**: no admissible candidate is cheaper."
    else:
        worst = max(c.bound for c in cells[chosen])
        verdict = (f"**The step chosen: {chosen}**, {cost[chosen]:.0f} against {ref_cost:.0f} CPU s per pile "
                   f"({cost[chosen] / ref_cost:.2f}). Its bias is not resolved in any statistic; biases above "
                   f"{worst:.2f} scatters are excluded at {100 * (1 - reg['level']):.0f} % in every cell, and "
                   "smaller ones are not (six seeds: the plan's section on what they can resolve).")
    head = (f"# {reg['title']}\n\nMade by `python -m workflow.tools step_error --plan {shown(plan)}` from the "
            f"records in {shown(records_folder)}/ and {reg['reference']['records']}/; the rule is "
            f"[{reg['registration']}]({reg['registration']}), committed before these piles. Each cell: the "
            "bias (candidate − reference, mean over the paired seeds) ± its standard error; the bound, the "
            f"largest bias in scatters σ the {100 * (1 - reg['level']):.0f} % interval does not exclude; sd(d)/σ "
            "(about 1.4 when the two steps give unrelated piles of one seed); the pairs. A cell **fails** when "
            f"the interval lies wholly beyond ±{reg['quarter']} σ. CPU seconds are each job's own (Snakemake's "
            "benchmark files), two piles side by side on a 2-core host; the paired ratio is the median over "
            "seeds of candidate over reference CPU, the reference poured in another window on the same host. "
            "Those files sample a job's CPU every 30 s after its first 15 s and miss its last seconds "
            "(docs/performance/pour_budget.md), so every CPU figure here is low by up to 30 s per job; the "
            "pile a candidate does not complete is named in the calibration tool's log (a refused step: "
            "its settings' own message).\n")
    return head + "\n".join(lines) + "\n\n## The rule\n\n" + "\n".join(f"- {r}" for r in reasons) + "\n\n" + verdict + "\n"


def main(argv=None) -> None:
    """Command line: print the table (``--out``: also write it)."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", type=Path, default=PLAN, help="the plan (config/step_error.yaml)")
    ap.add_argument("--records", type=Path, default=RECORDS, help="the candidates' records")
    ap.add_argument("--out", type=output_file, default=None, help="also write the page here")
    args = ap.parse_args(argv)
    if not args.plan.is_file():
        refuse(f"--plan {args.plan}: no such file; allowed is a plan like config/step_error.yaml")
    text = page(args.plan, args.records)
    if args.out:
        args.out.write_text(text)
    print(text)
