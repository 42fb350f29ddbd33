"""All six elastic constants of a full-size variant's piles, and the paper's
statements on the elastic law tested with them.

For every pile recorded under ``--variant`` whose ``probes.nc`` has the
support stretch (stage ``stretched``, ``config/scenes/six_constants.yaml``),
:func:`analysis.anisotropy.pile_anisotropy` fits the general law of six
constants per RVE to that pile alone; :func:`analysis.anisotropy.pile_summary`
gives one number per pile over the core RVEs where all six are pinned.  This
prints, in Markdown:

* per pile: the core RVEs with a fit, the share that pin all six constants at
  m = 1 and m = 5 (condition number at most
  ``analysis.probes.SIX_CONSTANTS_MAX_CONDITION``, positive definite, with
  the stretch among the samples) and the median condition numbers of all
  probes and of the gravity probes alone;
* per protocol, mean ± standard error over piles (number of piles) of the
  per-pile medians: the anisotropy E_max/E_min, the stiffest and softest
  axes (mirrored: times the sign of x), the stiffest axis against the fabric
  and stress axes, the shares of the stress increments each law explains,
  the Voigt stiffness's anisotropy and axis;
* the paper's moduli (K, E_p, E_b, E_av, G_p, G_b, G_av) of the general law,
  and the ratios of the isotropic, cubic and Voigt laws' moduli to them at
  each RVE, with the cubic over the isotropic (the paper's comparison), for
  the laws fitted to all probes and to the gravity reduction alone (the
  paper's data);
* the centre-over-shoulders contrast of the moduli at the primary layer
  (``analysis.history``), the same contrast of the reduction's isotropic
  shear modulus over the study's piles (``--study``), and the smallest
  contrast that the variant's piles could tell from zero at two-sided 5 %
  with 80 % power, 2.8 SD/√n, with the SD of that study row (the study's
  piles have no stretch, so the general law's own scatter over piles is not
  known from one pile).

With ``--figure`` it also draws, for the first pile of each protocol, the
stiffest axes of the RVEs that pin all six constants over the fabric axes,
and the shear moduli along the primary layer.

Usage::

    .venv/bin/python -m workflow.tools six_constants_table \\
        --variant docs/reproduction/variants/support_friction_0.9 --study docs/reproduction \\
        --params '{}' --figure six_constants.png > six_constants.md
"""

import math
from pathlib import Path

import numpy as np
import xarray as xr

from analysis.anisotropy import (
    MODULI, has_stretch, pile_anisotropy, pile_summary, reduction_shear_contrast)
from analysis.ensemble_statistics import detection_factor, mean_sem, t_threshold
from analysis.probes import SIX_CONSTANTS_MAX_CONDITION

from ._cli import ToolParser, analysis_params, existing_folder, output_file, refuse

#: Fits of the tables by default (the paper's m for its cubic law; the reduction alone needs the neighbours).
POINTS = 5
AXES = {
    "anisotropy": "anisotropy E_max/E_min",
    "axis_mirrored": "stiffest axis × sign x (deg from the vertical)",
    "soft_axis_mirrored": "softest axis × sign x (deg)",
    "axis_to_fabric": "stiffest axis − fabric axis, × sign x (deg)",
    "abs_axis_to_fabric": "angle stiffest axis to fabric axis, unsigned (deg)",
    "axis_to_stress": "stiffest axis − stress axis, × sign x (deg)",
    "abs_axis_to_stress": "angle stiffest axis to stress axis, unsigned (deg)",
    "explained_general": "share of Δσ explained: general law",
    "explained_cubic": "share of Δσ explained: cubic law",
    "explained_isotropic": "share of Δσ explained: isotropic law",
    "voigt_anisotropy": "Voigt stiffness: anisotropy",
    "voigt_axis_to_fit": "Voigt stiffest axis − fitted, × sign x (deg)",
}
#: Ratio columns of the moduli table: (key prefix, heading).
RATIOS = (("isotropic/general", "isotropic / general"), ("cubic/general", "cubic / general"),
          ("cubic/isotropic", "cubic / isotropic"),
          ("reduced_isotropic/general", "reduction's isotropic / general"),
          ("reduced_cubic/general", "reduction's cubic / general"),
          ("reduced_cubic/reduced_isotropic", "reduction's cubic / isotropic"),
          ("voigt/general", "Voigt / general"), ("voigt/reduced_isotropic", "Voigt / reduction's isotropic"))
#: Rows of the centre table: (law, modulus, heading).
CENTRE = (("general", "K", "general law K"), ("general", "E_av", "general law E_av"),
          ("general", "G_p", "general law G_p (shear along x, y)"),
          ("general", "G_b", "general law G_b (shear along the bisectors)"),
          ("general", "G_av", "general law G_av"),
          ("isotropic", "G_av", "isotropic law G (all probes)"), ("cubic", "G_av", "cubic law G_av (all probes)"),
          ("reduced_isotropic", "G_av", "isotropic law G (reduction: the paper's)"),
          ("reduced_cubic", "G_av", "cubic law G_av (reduction: the paper's)"),
          ("reduced_cubic", "G_p", "cubic law G_p = λ3 (reduction)"),
          ("voigt", "G_av", "Voigt G_av"))


def stretched(folder: Path, protocol: str) -> list[int]:
    """Seeds under ``folder/protocol`` with fields and a probes file that has the stretch."""
    seeds = [int(p.name[4:-len(".probes.nc")]) for p in (folder / protocol).glob("seed*.probes.nc")]
    return sorted(s for s in seeds if (folder / protocol / f"seed{s}.fields.nc").exists()
                  and has_stretch(folder / protocol / f"seed{s}.probes.nc"))


def _cell(values, spec: str = ".3g") -> str:
    m, se, _, n = mean_sem(values)
    if n == 0:
        return "–"
    return f"{m:{spec}} ± {se:.2g} ({n})" if n > 1 else f"{m:{spec}} (1)"


def few_piles(piles: dict) -> str:
    """A sentence on the degrees of freedom of the standard errors where a protocol has 2–4 piles, else ''."""
    n = min(sum(1 for p, _ in piles if p == proto) for proto in {p for p, _ in piles})
    if not 2 <= n < 5:
        return ""
    return (f" With {n} piles a standard error has {n - 1} degree{'s' * (n > 2)} of freedom: a mean differs from "
            f"a value at two-sided 5 % beyond {t_threshold(n - 1):.3g} standard errors (Student's t), "
            "not 1.96.")


def identification(piles: dict) -> str:
    """Markdown: per pile, the core RVEs fitted, the share pinning all six constants and the median
    condition numbers (:func:`analysis.anisotropy.pile_summary`'s ``@1`` and ``@5`` keys)."""
    rows = ["| pile | core RVEs fitted (m = 1 / 5) | all six pinned, m = 1 | m = 5 "
            "| median condition, all probes / gravity alone, m = 1 | m = 5 |", "|---|---|---|---|---|---|"]
    for (p, s), q in piles.items():
        rows.append(f"| {p} seed {s} | {q['core_fitted@1']:.0f} / {q['core_fitted@5']:.0f} "
                    f"| {100 * q['six_share@1']:.0f} % | {100 * q['six_share@5']:.0f} % "
                    f"| {q['condition@1']:.3g} / {q['condition_gravity@1']:.3g} "
                    f"| {q['condition@5']:.3g} / {q['condition_gravity@5']:.3g} |")
    return "\n".join(rows) + "\n"


def by_protocol(piles: dict, protocols: list[str], names: dict, spec: str = ".3g") -> str:
    """Markdown: each quantity ``names`` (key: heading) per protocol, mean ± SE over its piles."""
    rows = ["| quantity | " + " | ".join(protocols) + " |", "|---|" + "---|" * len(protocols)]
    for key, text in names.items():
        cells = [_cell([q.get(key, math.nan) for (p, _), q in piles.items() if p == proto], spec)
                 for proto in protocols]
        rows.append(f"| {text} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def moduli_table(piles: dict, protocols: list[str]) -> str:
    """Markdown: per protocol and modulus, the general law's value and the ratios :data:`RATIOS`."""
    rows = ["| protocol | modulus | general law (N/m) | " + " | ".join(h for _, h in RATIOS) + " |",
            "|---|---|---|" + "---|" * len(RATIOS)]
    for proto in protocols:
        mine = [q for (p, _), q in piles.items() if p == proto]
        for k in MODULI:
            cells = [_cell([q[f"general_{k}"] for q in mine])]
            cells += [_cell([q.get(f"{r}:{k}", math.nan) for q in mine], ".2f") for r, _ in RATIOS]
            rows.append(f"| {proto} | {k} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


#: Rows of the laws' stability: (law, heading).
STABLE = (("isotropic", "isotropic law, all probes"), ("cubic", "cubic law, all probes"),
          ("reduced_isotropic", "isotropic law, reduction (the paper's)"),
          ("reduced_cubic", "cubic law, reduction (the paper's)"), ("voigt", "Voigt stiffness"))


def centre_table(piles: dict, protocols: list[str], study: dict) -> str:
    """Markdown: the laws' stable shares, the centre contrasts :data:`CENTRE`, the study's contrast
    ``study`` (protocol: per-pile values) and the smallest contrast the variant's piles could see."""
    k = detection_factor()
    rows = ["| core RVEs where the law is stable (K, G_p, G_b > 0) | " + " | ".join(protocols) + " |",
            "|---|" + "---|" * len(protocols)]
    for law, text in STABLE:
        rows.append(f"| {text} | " + " | ".join(
            _cell([q.get(f"stable:{law}", math.nan) for (p, _), q in piles.items() if p == proto], ".2f")
            for proto in protocols) + " |")
    rows += ["", "| centre / shoulders − 1 | " + " | ".join(protocols) + " |", "|---|" + "---|" * len(protocols)]
    for law, mod, text in CENTRE:
        cells = [_cell([q.get(f"centre:{law}_{mod}", math.nan) for (p, _), q in piles.items() if p == proto],
                       "+.2f") for proto in protocols]
        rows.append(f"| {text} | " + " | ".join(cells) + " |")
    rows.append("| the study's piles: isotropic law G (reduction) | "
                + " | ".join(_cell(study[proto], "+.2f") for proto in protocols) + " |")
    seen = []
    for proto in protocols:
        n = sum(1 for p, _ in piles if p == proto)
        sd = mean_sem(study[proto])[2]
        seen.append(f"±{k * sd / math.sqrt(n):.2f} (SD {sd:.2f}, {n} pile{'s' * (n > 1)})"
                    if n and np.isfinite(sd) else "–")
    rows.append("| *seen at 80 %* (2.8 SD/√n; SD: that of the study's piles in the row above) | "
                + " | ".join(seen) + " |")
    return "\n".join(rows) + "\n"


def figure(per_pile: dict, params: dict, path: Path, points: int = POINTS) -> None:
    """For the first pile of each protocol: stiffest axes over fabric axes, and the shear moduli at the
    primary layer."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = {}
    for (p, s), ds in per_pile.items():
        first.setdefault(p, (s, ds))
    fig, axes = plt.subplots(len(first), 2, figsize=(12, 3.6 * len(first)), squeeze=False,
                             gridspec_kw={"width_ratios": [2, 1]})
    h = params["history"]
    for row, (p, (s, (pile, fields))) in enumerate(first.items()):
        fit = pile.sel(points=points)
        x, y = pile["x"].values, pile["y"].values
        xx, yy = np.meshgrid(x, y)
        six = fit["six_constants"].values == 1
        ax = axes[row, 0]
        if "surface_height" in fields:
            ax.plot(100 * fields["x"].values, 100 * fields["surface_height"].values, color="0.6", lw=1)
        half = 0.45 * 100 * float(np.min(np.diff(x)))
        for name, colour, scale in (("fabric_orientation", "0.75", None), ("axis_deg", "C3", "anisotropy")):
            ang = np.radians(fields[name].transpose("y", "x").values if name in fields else fit[name].values)
            size = np.clip(np.log(fit[scale].values) / np.log(4.0), 0.15, 1.0) if scale else 0.6
            dx, dy = -np.sin(ang) * half * size, np.cos(ang) * half * size
            ok = six & np.isfinite(dx)
            ax.plot(np.stack([100 * xx - dx, 100 * xx + dx])[:, ok], np.stack([100 * yy - dy, 100 * yy + dy])[:, ok],
                    color=colour, lw=1.0 if scale else 2.6)
        ax.set_aspect("equal")
        ax.set_xlim(100 * x.min(), 100 * x.max())
        ax.set_ylim(0, 100 * y.max())
        ax.set_title(f"{p} seed {s}: stiffest axis (red, length ~ log E_max/E_min) over the fabric axis (grey),"
                     f" m = {points}, RVEs pinning all six", fontsize=8)
        ax.set_xlabel("x (cm)")
        ax.set_ylabel("y (cm)")
        r = int(np.argmin(np.abs(y - h["primary_height"])))
        ax = axes[row, 1]
        for var, label, style in (("general_G_p", "general G_p", "C3-"), ("general_G_b", "general G_b", "C3--"),
                                  ("general_G_av", "general G_av", "k-"),
                                  ("reduced_isotropic_G_av", "isotropic G (reduction)", "C0-"),
                                  ("reduced_cubic_G_av", "cubic G_av (reduction)", "C2-")):
            v = fit[var].values[r]
            ax.plot(100 * x, np.where(six[r] | var.startswith("reduced_"), v, np.nan), style, label=label, lw=1.2)
        for edge in (h["centre"], h["shoulder_inner"], h["shoulder_outer"]):
            for sgn in (-1, 1):
                ax.axvline(100 * sgn * edge, color="0.85", lw=0.8)
        ax.set_xlim(-100 * h["shoulder_outer"] - 3, 100 * h["shoulder_outer"] + 3)
        ax.set_title(f"shear moduli at y = {100 * y[r]:.1f} cm (lines: centre and shoulder windows)", fontsize=8)
        ax.set_xlabel("x (cm)")
        ax.set_ylabel("N/m")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=params["figures"]["dpi"])
    plt.close(fig)


def main(argv=None) -> None:
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", type=existing_folder, required=True, help="the variant's records")
    ap.add_argument("--study", type=existing_folder, required=True, help="the study's records (docs/reproduction)")
    ap.add_argument("--params", type=analysis_params, default="{}", help="analysis settings as JSON or YAML flow text")
    ap.add_argument("--protocols", nargs="+", default=["wedge", "layered"])
    ap.add_argument("--figure", type=output_file, help="the figure (PNG)")
    ap.add_argument("--points", type=int, choices=(1, 5), default=POINTS,
                    help="the fits (RVE points) of the tables but the first (default: %(default)s)")
    args = ap.parse_args(argv)
    params = args.params
    per_pile, piles = {}, {}
    for p in args.protocols:
        for s in stretched(args.variant, p):
            stem = args.variant / p / f"seed{s}"
            with xr.open_dataset(f"{stem}.probes.nc") as pr, xr.open_dataset(f"{stem}.fields.nc") as f:
                fields = f.load()
                per_pile[(p, s)] = (pile_anisotropy(pr.load(), fields, params), fields)
            piles[(p, s)] = pile_summary(per_pile[(p, s)][0], params, args.points)
    if not piles:
        refuse(f"--variant {args.variant}: no pile under it has probes with the stretch")
    protocols = [p for p in args.protocols if any(q == p for q, _ in piles)]
    study = {p: [] for p in protocols}
    for p in protocols:
        for f in sorted((args.study / p).glob("seed*.fields.nc")):
            with xr.open_dataset(f) as ds:
                study[p].append(reduction_shear_contrast(ds.load(), params))
    if args.figure:
        figure(per_pile, params, args.figure, args.points)
    h = params["history"]
    first = next(iter(per_pile.values()))[0]
    row = float(first["y"].values[int(np.argmin(np.abs(first["y"].values - h["primary_height"])))])
    text = (f"# {args.variant.name}: all six elastic constants\n\n"
            f"Made by `make reproduction` (`workflow/tools/six_constants_table.py`, `analysis/anisotropy.py`) "
            f"from the records in `{args.variant}` whose probes include the support stretch "
            f"(`config/scenes/six_constants.yaml`): "
            + "; ".join(f"{p} seed{'s' * (sum(q == p for q, _ in piles) > 1)} "
                        f"{', '.join(str(s) for q, s in piles if q == p)}" for p in protocols)
            + f". Each pile's own general fit (six constants, Mandel) per RVE from its probes "
            f"({first.attrs['loading_probes']}). An RVE pins all six constants where the stretch is among its "
            f"samples, the fit is positive definite and its condition number is at most "
            f"{SIX_CONSTANTS_MAX_CONDITION:g} (`analysis.probes.SIX_CONSTANTS_MAX_CONDITION`, docs/analysis.md). "
            f"The core: |x| ≤ {100 * h['shoulder_outer']:g} cm, y ≤ {100 * h['core_height']:g} cm "
            f"(`analysis.history`). Per pile, medians over the core RVEs that pin all six (m = {args.points} below the "
            "first table); then mean ± standard error over piles (number of piles); one pile has no standard "
            f"error.{few_piles(piles)}\n\n## Identification\n\n" + identification(piles)
            + "\n## Anisotropy and axes\n\n" + by_protocol(piles, protocols, AXES)
            + "\n## The paper's moduli of each law\n\nK, E_p (uniaxial along x and y), E_b (along the bisectors), "
            "E_av, G_p (shear along x, y), G_b (along the bisectors), G_av of each law's Mandel stiffness "
            "(`analysis.anisotropy.engineering_moduli`; for the cubic law the paper's expressions, for the "
            "isotropic law K, 4KG/(K+G), G): the general law's value and, RVE by RVE, the other laws' over it. "
            "*All probes*: the isotropic (S′, Eq. 21) and cubic (S, Eq. 16) laws fitted to the same samples as "
            "the general law; *reduction*: fitted to the gravity reduction alone, the paper's data.\n\n"
            + moduli_table(piles, protocols)
            + f"\n## Centre over shoulders at y = {100 * row:.1f} cm\n\nThe mean over the centre columns "
            f"(|x| ≤ {100 * h['centre']:g} cm) over that over the shoulders ({100 * h['shoulder_inner']:g}–"
            f"{100 * h['shoulder_outer']:g} cm) − 1, in the grid row nearest `analysis.history.primary_height`; "
            "the general law's and the laws fitted to all probes at the RVEs that pin all six constants, the "
            "reduction's laws wherever they are fitted, as the paper draws them; values ≤ 0 left out (no modulus). "
            "First, the share of the core RVEs with a fit where each law is stable.\n\n"
            + centre_table(piles, protocols, study))
    print(text, end="")
