"""A full-size variant against the study, side by side: does the changed setting move the piles?

A *variant* is the study (``config/config.yaml``) with a few settings changed,
given by ``config/variants/{name}.yaml``; its full-size piles are recorded
under ``docs/reproduction/variants/{name}/{protocol}/`` exactly as the study's
are under ``docs/reproduction/{protocol}/`` (rule ``record_pile``).  This
script compares the two sets of records, pile by pile, in the quantities of
:mod:`analysis.pile_quantities` (the pile's shape, the core solid fraction,
the primary construction-history statistics, the core moduli) and the pour's
CPU time:

* each set's mean ± standard error over its piles;
* the difference variant − study, ± the standard error of the difference
  (``sqrt(se_v^2 + se_s^2)``; with one variant pile, whose scatter is not
  measured, the study's standard deviation over piles stands for it), in
  standard errors, and the smallest
  difference those piles could have seen (2.8 SE: two-sided 5 %, 80 % power);
* the same difference *paired* by seed over the seeds both sets hold (a
  seed draws the same particle shapes in both, so the pairing removes the
  scatter the shapes cause); n/a below two common seeds;
* the exact two-sided Mann–Whitney p of variant against study, a rank test
  that needs no standard error and so holds at two or three variant piles;
* the construction history: wedge − layered in each set;
* how far a z computed from few piles can be trusted: a standard error from
  n piles has n − 1 degrees of freedom, so the text gives Student's t
  quantile that two-sided 5 % needs at the variant's fewest piles
  (:func:`small_sample_note`).

The CPU times come from different runs on shared machines and are given for
the cost, not compared.  Prints Markdown (``make reproduction`` writes it to
``docs/reproduction/variants/{name}.md``).

Usage::

    .venv/bin/python -m workflow.tools variant_table --study docs/reproduction \\
        --variant docs/reproduction/variants/support_friction_0.9 \\
        --overlay config/variants/support_friction_0.9.yaml --params '{}'
"""

import math
from pathlib import Path

import numpy as np

from analysis.ensemble_statistics import (against_reference, compare, detection_factor, paired_difference, rank_test,
                                          t_threshold)
from analysis.pile_quantities import MODULI, SHAPE, pile_quantities, quantities
from sim.settings_file import read_settings_file

from ._cli import ToolParser, analysis_params, existing_file, existing_folder

COST = {"pour_cpu_min": "pour CPU (min; separate runs, not compared)"}
#: A recorded pile's files: ``{protocol}/seed{seed}`` plus these suffixes.
NEEDED = (".summary.json", ".fields.nc", ".base_pressure.nc")


def flat(layer: dict, prefix: str = "") -> dict:
    """``{"model": {"support_friction": 0.9}}`` → ``{"model.support_friction": 0.9}``."""
    out = {}
    for key, value in layer.items():
        name = f"{prefix}{key}"
        out.update(flat(value, name + ".") if isinstance(value, dict) else {name: value})
    return out


def recorded(folder: Path, protocol: str) -> list[int]:
    """The seeds whose pile has every file of :data:`NEEDED` under ``folder/protocol``."""
    seeds = [int(p.name[4:-len(".summary.json")]) for p in (folder / protocol).glob("seed*.summary.json")]
    return sorted(s for s in seeds if all((folder / protocol / f"seed{s}{x}").exists() for x in NEEDED))


def pour_cpu_minutes(folder: Path, protocol: str, seed: int) -> float:
    """The pour job's CPU minutes from its Snakemake benchmark (``pour.tsv``); NaN without one."""
    f = folder / protocol / f"seed{seed}.pour.tsv"
    if not f.exists():
        return math.nan
    header, row = f.read_text().splitlines()[:2]
    return float(dict(zip(header.split("\t"), row.split("\t")))["cpu_time"]) / 60


def pile_set(folder: Path, protocols: list[str], params: dict) -> dict:
    """``{protocol: {seed: {quantity: value}}}`` of every recorded pile under ``folder``."""
    out = {}
    for p in protocols:
        out[p] = {}
        for s in recorded(folder, p):
            stem = folder / p / f"seed{s}"
            q = pile_quantities(Path(f"{stem}.summary.json"), Path(f"{stem}.fields.nc"),
                                Path(f"{stem}.base_pressure.nc"), params)
            q["pour_cpu_min"] = pour_cpu_minutes(folder, p, s)
            out[p][s] = q
    return out


def _cell(m: float, se: float, n: int) -> str:
    return f"{m:.4g} ± {se:.2g} ({n})" if n > 1 else (f"{m:.4g} (1)" if n == 1 else "–")


def _difference(d: float, se: float) -> str:
    if se == 0 and d == 0:
        return "0 ± 0 (identical)"
    return f"{d:+.3g} ± {se:.2g} ({d / se:+.1f})" if se > 0 and np.isfinite(se) else "n/a"


def side_by_side(study: dict, variant: dict, names: dict) -> str:
    """Markdown: per protocol and quantity, both sets, their difference and the paired difference."""
    k = detection_factor()
    rows = ["| protocol | quantity | study | variant | variant − study (z) | seen at 80 % | paired by seed (z) "
            "| rank test p |",
            "|---|---|---|---|---|---|---|---|"]
    for p in study:
        for q, text in names.items():
            mine = {s: v[q] for s, v in variant.get(p, {}).items()}
            theirs = {s: v[q] for s, v in study[p].items()}
            c = against_reference(list(mine.values()), list(theirs.values()))
            (mv, sv, _, nv), (ms, ss, _, ns), se = c["a"], c["reference"], c["se"]
            if q in COST:
                rows.append(f"| {p} | {text} | {_cell(ms, ss, ns)} | {_cell(mv, sv, nv)} | | | | |")
                continue
            md, sd, _, nd = paired_difference(mine, theirs)
            seen = f"{k * se:.2g}" if np.isfinite(se) else "n/a"
            diff = _difference(c["diff"], se) + (" †" if c["single"] and np.isfinite(se) else "")
            rows.append(f"| {p} | {text} | {_cell(ms, ss, ns)} | {_cell(mv, sv, nv)} | {diff} "
                        f"| {seen} | {_difference(md, sd) if nd > 1 else 'n/a'} "
                        f"| {rank_p(list(mine.values()), list(theirs.values()))} |")
    return "\n".join(rows) + "\n"


def rank_p(a: list, b: list) -> str:
    """:func:`analysis.ensemble_statistics.rank_test` of two sets of per-pile numbers, as text:
    ``p`` to two significant digits, or ``n/a`` when either set is empty."""
    p = rank_test(a, b)
    return "n/a" if np.isnan(p) else f"{p:.2g}"


def history_versus(study: dict, variant: dict, names: dict, a: str = "wedge", b: str = "layered") -> str:
    """Markdown: ``a − b`` in each history statistic, in the study and in the variant."""
    if not ({a, b} <= set(study) and {a, b} <= set(variant)):
        return ""
    history = [q for q in names if q not in SHAPE and q not in MODULI and q not in COST]
    rows = [f"| {a} − {b} | study | variant |", "|---|---|---|"]
    for q in history:
        cells = []
        for piles in (study, variant):
            c = compare(*([v[q] for v in piles[x].values()] for x in (a, b)))
            cells.append(_difference(c["diff"], c["se"]))
        rows.append(f"| {names[q]} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def small_sample_note(variant: dict) -> str:
    """A sentence on the reference distribution of the z values at the variant's fewest piles.

    A standard error over ``n`` piles is itself estimated, with ``n − 1``
    degrees of freedom, so ``z = d / se`` follows Student's t, not the
    normal law: at ``n = 2`` two-sided 5 % needs ``|z| > 12.7``.  The
    sentence gives that quantile for the smallest set of variant piles with
    at least two (none with one pile, whose scatter is the study's), and below
    five piles a reminder that the z values are only a guide.

    Parameters
    ----------
    variant : dict
        ``{protocol: {seed: quantities}}`` of the variant's piles.

    Returns
    -------
    str
        The sentence, or ``""`` when every protocol has one pile or none.
    """
    counts = [len(v) for v in variant.values() if len(v) > 1]
    if not counts:
        return ""
    n = min(counts)
    guide = "; read the z values as a guide until each protocol has five piles (2.78)" if n < 5 else ""
    return (f" With {n} variant piles of a protocol a standard error has {n - 1} degree"
            f"{'s' if n > 2 else ''} of freedom, so a z of these tables is significant at two-sided 5 % "
            f"beyond {t_threshold(n - 1):.3g} (Student's t), not 1.96{guide}.")


def seeds_text(piles: dict) -> str:
    """``wedge 1–9, layered 1, 2``: the seeds of each protocol."""
    return "; ".join(f"{p} {', '.join(map(str, sorted(v))) or 'none'}" for p, v in piles.items())


def main(argv=None) -> None:
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=existing_folder, required=True, help="the study's records (docs/reproduction)")
    ap.add_argument("--variant", type=existing_folder, required=True, help="the variant's records")
    ap.add_argument("--overlay", type=existing_file, required=True,
                    help="the variant's settings (config/variants/NAME.yaml)")
    ap.add_argument("--params", type=analysis_params, default="{}",
                    help="analysis settings as JSON (the study's `analysis`)")
    ap.add_argument("--protocols", nargs="+", default=["wedge", "layered"])
    args = ap.parse_args(argv)
    layer = read_settings_file(args.overlay)
    changed = {k: v for k, v in flat(layer).items() if not k.startswith(("protocols.", "outputs", "threads"))}
    params = args.params
    study = pile_set(args.study, args.protocols, params)
    variant = pile_set(args.variant, args.protocols, params)
    names = {**quantities(params), **COST}
    settings = ", ".join(f"`{k}` = {v}" for k, v in changed.items())
    text = (f"# Variant {args.overlay.stem}: {settings}, against the study\n\n"
            f"Made by `make reproduction` (`workflow/tools/variant_table.py`) from the records in "
            f"`{args.study}` (the study) and `{args.variant}` (the variant, `{args.overlay}`). "
            f"Piles: study {seeds_text(study)}; variant {seeds_text(variant)}. "
            "Each cell: mean ± standard error over piles (number of piles). Variant − study: the difference of "
            "the means ± its standard error (in standard errors); *seen at 80 %*: the smallest difference these "
            "piles see at two-sided 5 % with 80 % power (2.8 SE); *paired by seed*: the mean of the per-seed "
            "differences over the seeds both hold (a seed draws the same particle shapes in both), ± its "
            "standard error; *rank test p*: the exact two-sided Mann–Whitney p of the variant's piles against "
            "the study's, which needs no standard error. †: one variant pile, whose scatter is taken as the study's standard deviation "
            "over piles (the difference's standard error is sqrt(se² + sd²) of the study)."
            + small_sample_note(variant) + "\n\n" + side_by_side(study, variant, names))
    versus = history_versus(study, variant, names)
    if versus:
        text += ("\nThe construction history, wedge − layered (docs/reproduction/numbers.md defines the "
                 "statistics): the difference of the means ± its standard error (in standard errors).\n\n" + versus)
    print(text, end="")
