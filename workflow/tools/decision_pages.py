"""The decision's pages: the registered rules of analysis/decision.py applied to the records.

The rules are :mod:`analysis.decision` (docs/reproduction/preregistration.md); this
module, the command ``python -m workflow.tools decision``, reads the records, checks
them against their plan and writes what the rules say.

``select`` reads the calibration records (``docs/reproduction/calibration/``,
each checked against ``config/calibration.yaml``), applies the registered rules
(:func:`analysis.decision.select_arms`, :func:`analysis.decision.piles_required`)
and writes what they chose to a new plan, ``--plan`` (the two arms, the
registered seeds 1001 ... 1000 + N, read by ``python -m workflow.tools
calibration --config PLAN --records docs/reproduction/PLAN-NAME``); it prints the
numbers the rules read (``--out``: the page of them, e.g.
``docs/reproduction/decision_plan.md``).  A plan is never rewritten or
deleted: ``select`` refuses a plan file that exists.  Commit the plan before
the first decision pile: that commit registers it.

``verdict`` reads a plan's decision records (``docs/reproduction/PLAN-NAME/``
by default), refuses any that the plan does not hold as one of its piles
(:func:`workflow.tools._records.check_registered`: arm, protocol and settings,
particles, seed, a copy of another record, the commit it was poured at) and
prints the registered test over the ensemble, or, short of N piles per
protocol, only how far the ensemble is (no test); ``--out`` writes it
(``docs/reproduction/decision.md`` under ``make reproduction``).

``pick`` applies the equal-slope decision's rule (docs/reproduction/equal_slope.md,
:func:`analysis.decision.pick_control`) to the pilot's records and prints
which layered control it picks (``--out``: the page,
``docs/reproduction/equal_slope/pick.md``).

Usage::

    .venv/bin/python -m workflow.tools decision pick [--records PILOT] [--plan PILOT-CONFIG] [--out PAGE]
    .venv/bin/python -m workflow.tools decision select --plan config/decision_NEW.yaml [--out PAGE]
    .venv/bin/python -m workflow.tools decision verdict [--plan config/decision.yaml] [--out PAGE]
"""

from __future__ import annotations

import math
from pathlib import Path

import yaml

from analysis import decision
from sim.settings_file import SettingsDumper, read_settings_file

from ._cli import ToolParser, output_file, refuse, shown
from ._records import check_registered, read_records

REPO = Path(__file__).resolve().parents[2]

DOCS = REPO / "docs" / "reproduction"
CALIBRATION = REPO / "config" / "calibration.yaml"
PLAN = REPO / "config" / "decision.yaml"
FIRST_SEED = 1001


def calibration_records(folder: Path, option: str) -> list[dict]:
    """The calibration records of `folder`, each checked against ``config/calibration.yaml``."""
    records = read_records(folder, option)
    check_registered(records, CALIBRATION)
    return list(records.values())


def select(records: Path, plan: Path) -> str:
    """Choose the arms and N by the registered rules; write them to the new plan file `plan`.

    Parameters
    ----------
    records : Path
        The calibration records' folder.
    plan : Path
        Where the plan goes: a file that does not exist yet.

    Returns
    -------
    str
        The page of the numbers the rules read and what they chose.

    Raises
    ------
    workflow.tools._cli.Refusal
        If `plan` exists (a registered plan is never rewritten), or a record
        is not one of the calibration's piles.
    """
    if plan.exists():
        refuse(f"--plan {plan}: exists; a registered plan is never rewritten, allowed is a new file")
    recs = calibration_records(records, "--records")
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
    else:
        need = decision.piles_required(recs, sel["point"], sel["layered"])
        lines += [f"- Layered control: **{sel['layered']}**.",
                  f"- `{decision.DECISION[0]}` pooled scatter over the chosen arms' piles: {need['sd']:.4f} "
                  f"({need['df']} df); piles per protocol for {decision.POWER:.0%} power to find "
                  f"{decision.EFFECT:.0%} at {decision.LEVEL:.0%}/{len(decision.DECISION)}: {need['n_power']:.0f}; "
                  f"registered N = **{need['n']}** per protocol, seeds {FIRST_SEED}-{FIRST_SEED + need['n'] - 1}."]
        cal = read_settings_file(CALIBRATION)
        chosen = {"piles": cal["piles"], "frame_interval": cal["frame_interval"],
                  "seeds": list(range(FIRST_SEED, FIRST_SEED + need["n"])),
                  "arms": {a: cal["arms"][a] for a in (sel["point"], sel["layered"])}}
        with open(plan, "x") as fh:   # "x": never over a plan that appeared meanwhile
            fh.write("# The decision ensemble, written by python -m workflow.tools decision select from the\n"
                     "# calibration records by the rules of docs/reproduction/preregistration.md.\n"
                     + yaml.dump(chosen, Dumper=SettingsDumper, sort_keys=False))
    return "\n".join(lines) + "\n"


def pick(pilot: Path, pilot_config: Path, reference: Path, point: str) -> str:
    """The equal-slope control by the rule of docs/reproduction/equal_slope.md; return its page.

    Parameters
    ----------
    pilot : Path
        The pilot's records, each checked against `pilot_config`.
    pilot_config : Path
        The settings file that registered the pilot's piles.
    reference : Path
        The first decision's records: its `point` piles' angles, with the
        pilot's, make the reference slope.
    point : str
        The point source's arm.
    """
    found = read_records(pilot, "--pilot")
    check_registered(found, pilot_config)
    recs = list(found.values())
    first = [r["quantities"]["angle_deg"] for r in read_records(reference, "--reference").values()
             if r["arm"] == point]
    angles = first + [r["quantities"]["angle_deg"] for r in recs if r["arm"] == point]
    out = decision.pick_control(recs, point, angles)
    funnel = decision.mean_sem([r["growth"]["interior_share"] for r in recs if r["arm"] == point])
    cpu = lambda arm: decision.mean_sem([r["cpu_s"]["total"] for r in recs if r["arm"] == arm])  # noqa: E731
    lines = ["# The equal-slope control: what the rule picked",
             "",
             f"Made by `python -m workflow.tools decision pick` from the pilot's records ({len(recs)} piles, "
             f"{shown(pilot)}/, settings {shown(pilot_config)}) by the rule of [equal_slope.md](../equal_slope.md). "
             f"Reference slope: the mean angle of {len(angles)} {point} piles ({len(first)} of the first decision, "
             f"{len(angles) - len(first)} of the pilot): **{out['reference']:.2f}°**; {point} interior share "
             f"{funnel[0]:.3f} ± {funnel[1]:.3f}, CPU s per pile {cpu(point)[0]:.0f} ± {cpu(point)[1]:.0f}.",
             "",
             "| arm | piles | angle (deg) | interior share | flanks flow | interior t against the point source "
             "| CPU s per pile | slope within 1° | interior |",
             "|---|---|---|---|---|---|---|---|---|"]
    for arm, m in out["arms"].items():
        (a, sa, n), (i, si, _), (f, sf, _) = m["angle_deg"], m["interior_share"], m["flow_fraction"]
        c = cpu(arm)
        lines.append(f"| {arm} | {n} | {a:.2f} ± {sa:.2f} | {i:.3f} ± {si:.3f} | {f:.3f} ± {sf:.3f} "
                     f"| {m['interior_t']:.1f} | {c[0]:.0f} ± {c[1]:.0f} | {'yes' if m['slope'] else 'no'} "
                     f"| {'yes' if m['interior'] else 'no'} |")
    lines += ["", f"**Control: {out['control']}**" if out["control"] else
              "**No arm qualifies**: the rule's step 5 comes next (equal_slope.md)."]
    return "\n".join(lines) + "\n"


def _row(key: str, r: dict, power: bool = True) -> str:
    """One table row of a statistic's test (its power last, unless `power` is False)."""
    (ma, sa, na), (mb, sb, nb) = r["point"], r["layered"]
    return (f"| {key} | {ma:.4g} ± {sa:.2g} ({na}) | {mb:.4g} ± {sb:.2g} ({nb}) | {r['diff']:+.4g} ± {r['se']:.2g} "
            f"| {r['t']:.2f}, {r['df']:.1f} df | {r['p']:.3g} | {r['p_holm']:.3g} |"
            + (f" {r['power']:.2f} |" if power else ""))


def verdict(records: Path, plan: Path) -> str:
    """The verdict page of the plan `plan` from its decision records; return it.

    Parameters
    ----------
    records : Path
        The decision records' folder.
    plan : Path
        The registered plan (``config/decision.yaml``): its two arms, its seeds.

    Raises
    ------
    workflow.tools._cli.Refusal
        If a record is not one of the plan's piles
        (:func:`workflow.tools._records.check_registered`), or the folder holds none.
    """
    reg = read_settings_file(plan)
    family = tuple(reg.get("primary", decision.DECISION))
    margin = reg.get("equivalence_margin")
    found = read_records(records)
    check_registered(found, plan, replaces=family[0])
    recs = list(found.values())
    point, layered = list(reg["arms"])
    n = len(reg["seeds"])
    have = {a: sum(r["arm"] == a for r in recs) for a in (point, layered)}
    page = reg.get("registration", "preregistration.md")
    lines = [f"# {reg.get('title', 'The decision: a pressure minimum under point-source piles?')}", "",
             f"Registered in [{page}]({page}); arms and N in "
             f"[{reg.get('plan_page', 'decision_plan.md')}]({reg.get('plan_page', 'decision_plan.md')}): "
             f"{point} against {layered}, {n} piles per protocol. "
             f"Made by `python -m workflow.tools decision verdict --plan {shown(plan)}` from {shown(records)}/.", ""]
    try:
        result = decision.verdict(recs, point, layered, n, family=family, margin=margin)
    except ValueError as exc:
        lines.append(f"**No verdict yet**: {exc} (piles recorded: {have}).")
        return "\n".join(lines) + "\n"
    shape = decision.shape_check(recs, point, layered, family[0])
    (pa, pse, _), (la, lse, _) = shape["angle"][point], shape["angle"][layered]
    built = (f" (of the sources as built, not of history: the arms rest {abs(shape['angle_diff']):.1f}° apart)"
             if shape["as_built"] else "")
    lines += [f"**Verdict{built}: {result['sentence']}.**", "",
              f"What the arms differ in besides the history: {point} piles rest at {pa:.1f}° ± {pse:.1f}°, "
              f"{layered} piles at {la:.1f}° ± {lse:.1f}° (`angle_deg`). Fitted on arm plus angle, the arm's "
              f"effect on {family[0]} is {100 * shape['arm_effect']:+.1f} % ± {100 * shape['arm_se']:.1f} % "
              f"and the angle's {100 * shape['slope_effect']:+.2f} % ± {100 * shape['slope_se']:.2f} % per degree "
              f"(arm and angle correlate at {shape['correlation']:.2f}"
              + ("; so close to 1 that the fit cannot part them" if abs(shape["correlation"]) > 0.9 else "")
              + ")." + (f" The arms' slopes differ by more than {decision.SLOPE_TOLERANCE}°, so a difference "
                        "between them is one of the two sources as built (shape and history together), not "
                        "attributable to history." if shape["as_built"] else ""), "",
              f"| statistic | {point} | {layered} | difference | Welch t | p | Holm p | power at "
              f"{decision.EFFECT:.0%} |", "|---|---|---|---|---|---|---|---|"]
    lines += [_row(k, r) for k, r in result["decision"].items()]
    plan_sd = reg["scatter"] if "scatter" in reg else decision.piles_required(
        calibration_records(DOCS / "calibration", "calibration records"), point, layered)["sd"]
    lines += [""] + [f"- {k}: 95 % interval of the difference [{100 * r['ci95'][0]:+.1f} %, "
                     f"{100 * r['ci95'][1]:+.1f} %]; per-pile scatter {r['sd'][0]:.4f} ({point}), "
                     f"{r['sd'][1]:.4f} ({layered})" for k, r in result["decision"].items()]
    d1 = result["decision"][family[0]]
    if margin is not None:
        eq = result["equivalence"]
        lines += [f"- Equivalence (two one-sided Welch tests, ±{100 * margin:.0f} %): p {eq['p']:.3g} "
                  f"(against ≤ −{100 * margin:.0f} %: {eq['p_low']:.3g}; against ≥ +{100 * margin:.0f} %: "
                  f"{eq['p_high']:.3g}); {'equivalent' if eq['equivalent'] else 'not shown equivalent'} at 5 %."]
    lines += [f"- {layered} alone: {family[0]} {100 * d1['layered'][0]:+.1f} % ± "
              f"{100 * d1['layered'][1]:.1f} % (t {d1['layered'][0] / d1['layered'][1]:.1f} against 0); the "
              "paper finds no dip under its layered piles."]
    low_power = [k for k, r in result["decision"].items() if r["rejected"] and r["power"] < decision.POWER]
    lines += [f"- N was set from {family[0]}'s scatter {plan_sd:.4f} "
              f"({reg.get('scatter_source', 'pooled over the calibration piles of the two arms')}); "
              "the power column is at the "
              "ensemble's own scatter" + (
                  f": below the planned {decision.POWER:.0%} for {', '.join(low_power)}, where a test that "
                  "rejects tends to overstate the effect, so the estimate is more likely too large than too "
                  "small." if low_power else "."),
              f"- Piles: seeds {reg['seeds'][0]}-{reg['seeds'][-1]}, {have[point]} {point} and "
              f"{have[layered]} {layered} recorded; missing: "
              + (", ".join(f"{r['arm']} seed {r['seed']}" for r in recs
                           if not math.isfinite(r["quantities"].get(family[0], math.nan))) or "none")
              + "."]
    lines += ["", "Secondary (own Holm family, not the verdict; no power column: the ensemble was powered for "
              f"{decision.EFFECT:.0%} in {family[0]} alone, and the secondaries' units differ, "
              "an angle in degrees among them):", "",
              "| statistic | point | layered | difference | Welch t | p | Holm p |",
              "|---|---|---|---|---|---|---|"]
    lines += [_row(k, r, power=False) for k, r in result["secondary"].items()]
    return "\n".join(lines + _covariate_lines(recs, point, layered, family[0])) + "\n"


#: How :func:`_covariate_lines` shows a covariate: its name on the page, the
#: factor from the record's unit to the page's, the page's unit, decimals.
_COVARIATE_UNITS = {"angle_deg": ("angle of repose", 1.0, "°", 1), "height": ("height", 100.0, " cm", 2),
                    "width": ("base width", 100.0, " cm", 1), "solid_fraction": ("core solid fraction", 1.0, "", 3)}


def _covariate_lines(recs, point, layered, key):
    """The page's table of what else differs between the arms (each of
    :data:`analysis.decision.COVARIATES` per arm) and `key` fitted on arm plus
    each one (:func:`analysis.decision.covariate_fit`), with the fit's conditioning."""
    lines = ["", f"What else differs between the arms (reported covariates, not tests), and {key} fitted on "
             "arm plus each one alone. Where a covariate goes with the arm (correlation r near ±1) the arm's "
             "coefficient is poorly determined: its variance grows by the inflation factor 1/(1 − r²); "
             "a covariate measured on the same piles may itself be an effect of the history.", "",
             f"| covariate | {point} | {layered} | difference | arm effect on {key} with it | the covariate's "
             "coefficient | r (inflation) |", "|---|---|---|---|---|---|---|"]
    for name in decision.COVARIATES:
        label, scale, unit, nd = _COVARIATE_UNITS[name]
        fit = decision.covariate_fit(recs, point, layered, key, name)
        (pm, pse, _), (lm, lse, _) = fit["arms"][point], fit["arms"][layered]
        step = 1.0 / scale if name != "solid_fraction" else 0.01
        per = f"per {step * scale:g}{unit}" if name != "solid_fraction" else "per 0.01"
        lines.append(f"| {label} (`{name}`) | {scale * pm:.{nd}f}{unit} ± {scale * pse:.{nd}f} | "
                     f"{scale * lm:.{nd}f}{unit} ± {scale * lse:.{nd}f} | {scale * fit['diff']:+.{nd}f}{unit} | "
                     f"{100 * fit['arm_effect']:+.1f} % ± {100 * fit['arm_se']:.1f} % | "
                     f"{100 * fit['effect'] * step:+.2f} % ± {100 * fit['se'] * step:.2f} % {per} | "
                     f"{fit['correlation']:.2f} ({fit['inflation']:.1f}) |")
    return lines


def main(argv=None) -> None:
    """Command line: ``select`` or ``verdict`` (the module's docstring); prints the page, writes it only to ``--out``."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=["select", "verdict", "pick"])
    ap.add_argument("--plan", type=Path, default=None,
                    help="the plan: read by verdict (default: config/decision.yaml), written anew by select; "
                         "for pick the pilot's settings (default: config/equal_slope_pilot2.yaml)")
    ap.add_argument("--records", type=Path, default=None,
                    help="the records' folder (default: docs/reproduction/calibration for select, "
                         "docs/reproduction/PLAN-NAME for verdict)")
    ap.add_argument("--out", type=output_file, default=None, help="also write the page to this file")
    args = ap.parse_args(argv)
    if args.step == "pick":
        page = pick(args.records or DOCS / "equal_slope" / "pilot2",
                    args.plan or REPO / "config" / "equal_slope_pilot2.yaml", DOCS / "decision", "wedge funnel")
    elif args.step == "select":
        page = select(args.records or DOCS / "calibration", args.plan or PLAN)
    else:
        plan = args.plan or PLAN
        page = verdict(args.records or DOCS / plan.stem, plan)
    if args.out:
        args.out.write_text(page)
    print(page, end="")
