"""Apply the pre-registration (docs/reproduction/preregistration.md): choose, then decide.

``select`` reads the calibration records (``docs/reproduction/calibration/``),
applies the registered rules (:func:`analysis.decision.select_arms`,
:func:`analysis.decision.piles_required`) and writes what they chose:
``config/decision.yaml`` (the two arms, the registered seeds 1001 ... 1000 + N,
read by ``python -m workflow.tools calibration --config config/decision.yaml
--records docs/reproduction/decision``) and ``docs/reproduction/decision_plan.md``
(the numbers the rules read).  Commit both before the first decision pile.

``verdict`` reads the decision records and writes ``docs/reproduction/decision.md``
(rebuilt by ``make reproduction``):
the registered test over the ensemble, or, short of N piles per protocol,
only how far the ensemble is (no test).

Usage::

    .venv/bin/python -m workflow.tools decision select
    .venv/bin/python -m workflow.tools decision verdict
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import yaml

from analysis import decision
from sim.settings_file import SettingsDumper, read_settings_file

REPO = Path(__file__).resolve().parents[2]

DOCS = REPO / "docs" / "reproduction"
CALIBRATION = REPO / "config" / "calibration.yaml"
PLAN = REPO / "config" / "decision.yaml"
FIRST_SEED = 1001


def read_records(folder: Path) -> list[dict]:
    """Every pile record (``*.json``) of a folder."""
    return [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))]


def select(records: Path) -> str:
    """Choose the arms and N; write config/decision.yaml and decision_plan.md; return the page."""
    recs = read_records(records)
    sel = decision.select_arms(recs)
    lines = ["# The decision's plan: what the registered rules chose",
             "",
             "Made by `python -m workflow.tools decision select` from the calibration records "
             f"({len(recs)} piles, docs/reproduction/calibration/) by the rules of "
             "[preregistration.md](preregistration.md).",
             "",
             "| arm | flanks flow (fraction of the growth) | growing flank, 90th percentile (deg) "
             "| angle of repose, relaxed (deg) |",
             "|---|---|---|---|"]
    for arm, m in sel["means"].items():
        lines.append(f"| {arm} | {m['flow_fraction']:.3f} | {m['flank_p90_deg']:.2f} | {m['angle_deg']:.2f} |")
    lines += ["", f"- Point source: **{sel['point']}** (flows the larger fraction); its angle of repose "
              f"{sel['repose_deg']:.2f}°, so a layered control must grow below "
              f"{sel['repose_deg'] - decision.REPOSE_MARGIN:.2f}°: qualified {sel['qualified'] or 'none'}."]
    if sel["layered"] is None:
        lines.append("- No layered control at these settings: the decision is not poured; the levers come first.")
        PLAN.unlink(missing_ok=True)
    else:
        need = decision.piles_required(recs, sel["point"], sel["layered"])
        lines += [f"- Layered control: **{sel['layered']}**.",
                  f"- D1 ({decision.DECISION[0]}) pooled scatter over the chosen arms' piles: {need['sd']:.4f} "
                  f"({need['df']} df); piles per protocol for {decision.POWER:.0%} power to find "
                  f"{decision.EFFECT:.0%} at {decision.LEVEL:.0%}/{len(decision.DECISION)}: {need['n_power']:.0f}; "
                  f"registered N = **{need['n']}** per protocol, seeds {FIRST_SEED}-{FIRST_SEED + need['n'] - 1}."]
        cal = read_settings_file(CALIBRATION)
        plan = {"piles": cal["piles"], "frame_interval": cal["frame_interval"],
                "seeds": list(range(FIRST_SEED, FIRST_SEED + need["n"])),
                "arms": {a: cal["arms"][a] for a in (sel["point"], sel["layered"])}}
        PLAN.write_text("# The decision ensemble, written by python -m workflow.tools decision select from the\n"
                        "# calibration records by the rules of docs/reproduction/preregistration.md.\n"
                        + yaml.dump(plan, Dumper=SettingsDumper, sort_keys=False))
    page = "\n".join(lines) + "\n"
    (DOCS / "decision_plan.md").write_text(page)
    return page


def _row(key: str, r: dict) -> str:
    (ma, sa, na), (mb, sb, nb) = r["point"], r["layered"]
    return (f"| {key} | {ma:.4g} ± {sa:.2g} ({na}) | {mb:.4g} ± {sb:.2g} ({nb}) | {r['diff']:+.4g} ± {r['se']:.2g} "
            f"| {r['t']:.2f}, {r['df']:.1f} df | {r['p']:.3g} | {r['p_holm']:.3g} | {r['power']:.2f} |")


def verdict(records: Path, out: Path) -> str:
    """Write the verdict page (docs/reproduction/decision.md) from the decision records to `out`; return it."""
    plan = read_settings_file(PLAN)
    point, layered = list(plan["arms"])
    n = len(plan["seeds"])
    recs = read_records(records)
    have = {a: sum(r["arm"] == a for r in recs) for a in (point, layered)}
    lines = ["# The decision: a pressure minimum under point-source piles?", "",
             f"Registered in [preregistration.md](preregistration.md); arms and N in "
             f"[decision_plan.md](decision_plan.md): {point} against {layered}, {n} piles per protocol. "
             "Made by `python -m workflow.tools decision verdict` from docs/reproduction/decision/.", ""]
    try:
        result = decision.verdict(recs, point, layered, n)
    except ValueError as exc:
        lines.append(f"**No verdict yet**: {exc} (piles recorded: {have}).")
        page = "\n".join(lines) + "\n"
        out.write_text(page)
        return page
    lines += [f"**Verdict: {result['sentence']}.**", "",
              f"| statistic | {point} | {layered} | difference | Welch t | p | Holm p | power at "
              f"{decision.EFFECT:.0%} |", "|---|---|---|---|---|---|---|---|"]
    lines += [_row(k, r) for k, r in result["decision"].items()]
    plan_sd = decision.piles_required(read_records(DOCS / "calibration"), point, layered)["sd"]
    lines += [""] + [f"- {k}: 95 % interval of the difference [{100 * r['ci95'][0]:+.1f} %, "
                     f"{100 * r['ci95'][1]:+.1f} %]; per-pile scatter {r['sd'][0]:.4f} ({point}), "
                     f"{r['sd'][1]:.4f} ({layered})" for k, r in result["decision"].items()]
    lines += [f"- N was set from D1's pooled calibration scatter {plan_sd:.4f}; the power column is at the "
              "ensemble's own scatter.",
              f"- Piles: seeds {plan['seeds'][0]}-{plan['seeds'][-1]}, {have[point]} {point} and "
              f"{have[layered]} {layered} recorded; missing: "
              + (", ".join(f"{r['arm']} seed {r['seed']}" for r in recs
                           if not math.isfinite(r["quantities"].get(decision.DECISION[0], math.nan))) or "none")
              + "."]
    lines += ["", "Secondary (own Holm family, not the verdict):", "",
              "| statistic | point | layered | difference | Welch t | p | Holm p | power |",
              "|---|---|---|---|---|---|---|---|"]
    lines += [_row(k, r) for k, r in result["secondary"].items()]
    page = "\n".join(lines) + "\n"
    out.write_text(page)
    return page


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=["select", "verdict"])
    ap.add_argument("--records", type=Path, default=None,
                    help="the records' folder (default: docs/reproduction/calibration for select, "
                         "docs/reproduction/decision for verdict)")
    ap.add_argument("--out", type=Path, default=DOCS / "decision.md", help="the verdict's page (verdict)")
    args = ap.parse_args(argv)
    folder = args.records or DOCS / ("calibration" if args.step == "select" else "decision")
    print(select(folder) if args.step == "select" else verdict(folder, args.out))
