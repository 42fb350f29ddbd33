"""The numbers that docs/reproduction.md sets against the paper's, from the ensembles.

Usage::

    python -m workflow.tools reproduction_numbers --ensemble results/ensemble \\
        --protocols wedge layered --convergence FILE... --checks FILE... --heights 0.045 0.09 ...

prints Markdown (``docs/reproduction/numbers.md`` under ``make reproduction``).
Every value is a mean over the piles of a protocol with its standard error
over piles (``_sem`` of the ensemble files; "n/a" with a single pile).  The
measures:

* **Slips left out**: the pile-RVEs whose probe response the ensemble left
  out as slipped (``analysis.ensemble.slip_strain_ratio``), in all and per
  pile, and where.
* **Fig. 2, vertical strain**: at each height, ``u_yy`` of the ensemble in
  the centre and shoulder windows of ``analysis.history`` (mean of the
  columns; error: the mean of their standard errors).
* **Construction history** (``--fields``, ``--base-pressure``): the
  statistics of :mod:`analysis.history` (windows fixed after the study's
  piles were read: not pre-registered for them), per pile, then wedge
  against layered with the standard error of the difference, Welch's t and
  its degrees of freedom, and the piles needed for a 5 and a 10 % difference
  at 80 % power; how many comparisons were made; the decision on the five
  primary statistics (:func:`analysis.decision.primary_tests`: p from Student's t, Holm over
  the five, the piles for 80 % power at the family-wise level).
* **Checks of the report's verdicts** (:func:`report_checks`): the numbers
  of docs/reproduction.md's verdict table that are printed nowhere else
  (stress increment and stiffness contrasts, the σ_yy contrast of the
  lowest row, Fig. 1 against the 12 cm RVE, Fig. 5's secant over strain
  deciles, the end state of the two protocols, the line source's cap).
* **Base pressure**: the normal force density at the centre (two bins next
  to x = 0) and its maximum, with the x of the maximum.
* **Fig. 3, fabric**: range of the trace and of the deviatoric fraction over
  the valid RVEs; mean orientation of the major axis over ``x < -10 cm`` and
  ``x > 10 cm`` in the two lowest rows; mean ``|stress_fabric_angle|`` there.
* **Fig. 4, moduli** (:func:`moduli`): per layer of Fig. 4 and over all
  RVEs, the share of the RVEs with a fit whose fit is masked (condition
  number above ``analysis.moduli.max_condition`` or not positive definite,
  :mod:`analysis.elastic`) for Fig. 4's isotropic (S′, m = 1) and cubic
  (S̃, m = 5) fits: the fit of the ensemble mean, the piles' own fits (over
  pile-RVEs) and their mean over piles; then the medians of Fig. 4's moduli,
  and of ``E`` (m = 1) and ``E_av`` (m = 5) of the average of the two
  fitting methods, over the RVEs kept, each with the RVEs kept of those
  with a fit.
* **Fig. 5**: ``R²`` of a straight line through ``tr Δσ`` against ``tr ε``,
  over RVEs with ``|x| <= 10 cm`` and over all RVEs.
* **Fig. 1**: over every pile with a convergence file and its fixed points,
  per RVE size: the particles in the RVE, and the relative deviation of
  ``σ_yy`` and of ``Δσ_yy`` from their values in the largest RVE (median and
  largest over piles and points).
* **Balance laws**: the largest ``|support reaction / weight − 1|`` over the
  piles, relaxed, reduced and for the increment.
* **Extra probes** (``--general``, the ``general_moduli.nc`` of the protocols
  with tilted and restored probes): per m, the RVEs whose general fit is
  identified (condition number at most ``max_condition``) and positive
  definite among those with enough samples for a fit, and their median
  condition number; at m = 5 the median fractions of
  the stress increments that the general, cubic and isotropic laws explain,
  the median anisotropy ``E_max / E_min`` and the mean angle between the
  stiffness axis and the fabric and stress axes; the reversibility of the
  reduction (median and 10–90 % range over RVEs), also by depth below the
  surface (the top filled RVE of each grid column); the slips left out.
  With ``--probes`` (each pile's ``probes.nc``), per pile: its median
  reversibility over its RVEs, and the mean of those medians with its
  standard error over the piles; how far the two opposite tilts are from
  opposite increments, ``|Δ(+) + Δ(−)| / (|Δ(+)| + |Δ(−)|)`` per RVE (0 in a
  linear pile), for the strain and the stress, median and 10–90 % range.
"""

import argparse
import json
import math
import sys
import warnings

from pathlib import Path

import numpy as np
import xarray as xr


from analysis.convergence import deviations
from analysis.decision import DELTAS, primary_tests
from analysis.elastic import mask_counts
from analysis.ensemble_statistics import LEVEL, POWER, compare, mean_sem, piles_for_power, welch
from analysis.fields import read_fields
from analysis.history import UNITS, flank_fabric, pile_history, pile_stress_contrasts, primary_names, windows
from analysis.invariants import pile_secants, secant_deciles, trace_line_r2
from analysis.probes import general_fit_summary, reversibility, tilt_asymmetry
from sim.settings_file import read_settings_file

from ._cli import ToolParser, analysis_params, existing_file, existing_folder, positive_float, refuse


def _pm(v, s, spec=".3g"):
    s_txt = "n/a" if not np.isfinite(s) else format(s, ".2g")
    return f"{format(v, spec)} ± {s_txt}"


def _row_index(ds, h):
    return int(np.argmin(np.abs(ds["y"].values - h)))


def strain_profile(ds, heights, history):
    """Lines of Fig. 2 for one protocol's ensemble fields: ``u_yy`` in the centre and
    shoulder windows of ``analysis.history`` at each height.

    A window's value is the mean of its columns, its error the mean of their
    standard errors (neighbouring RVEs share most of their particles, so their
    errors are not independent); the test of a dip is the per-pile contrast of
    :func:`history`, not this table."""
    x = ds["x"].values
    centre, shoulders = windows(x, history)
    u = ds["strain_increment"].sel(i="y", j="y").values
    su = ds["strain_increment_sem"].sel(i="y", j="y").values
    out = []
    for h in heights:
        k = _row_index(ds, h)
        row, srow = u[k], su[k]
        if not np.isfinite(row).any():
            continue
        cells = []
        for w in (centre, shoulders):
            ok = w & np.isfinite(row)
            cells.append(_pm(float(row[ok].mean()), float(np.nanmean(srow[ok]))) if ok.any() else "n/a")
        out.append(f"| {100 * ds['y'].values[k]:.1f} | {cells[0]} | {cells[1]} |")
    return out


def slips(ds):
    """The pile-RVEs the ensemble ``ds`` left out as slipped under the probe, and where."""
    ratio = json.loads(ds.attrs["config"])["ensemble"]["slip_strain_ratio"]
    if ratio is None:
        return "none left out (analysis.ensemble.slip_strain_ratio = null)"
    n = ds["slip_left_out"].values
    text = (f"{int(ds.attrs['slip_left_out_total'])} pile-RVEs left out as slipped under the probe "
            f"(|u| above {ratio:g} times the pile's median; per seed {ds.attrs['seeds']}: "
            f"{ds.attrs['slip_left_out_per_seed']})")
    if not n.any():
        return text
    iy, ix = np.nonzero(n)
    x, y = 100 * ds["x"].values[ix], 100 * ds["y"].values[iy]
    return text + f", at y = {y.min():.1f}–{y.max():.1f} cm, x = {x.min():.1f}–{x.max():.1f} cm"


def base_pressure(bp):
    x = bp["x"].values
    p, s = bp["normal_force_density"].values, bp["normal_force_density_sem"].values
    c = np.argsort(np.abs(x))[:2]
    j = int(np.nanargmax(p))
    return (f"centre {_pm(float(p[c].mean()), float(np.sqrt((s[c] ** 2).sum()) / 2))} N/m, maximum "
            f"{_pm(float(p[j]), float(s[j]))} N/m at x = {100 * x[j]:.0f} cm ({_piles(int(bp.attrs['n_seeds']))})")


def _piles(n):
    return f"{n} pile{'s' if n != 1 else ''}"


def fabric(ds):
    tr, dev = ds["fabric_trace"].values, ds["fabric_deviatoric_fraction"].values
    ori, ang = ds["fabric_orientation"].values, ds["stress_fabric_angle"].values
    x = ds["x"].values
    low = slice(0, 2)
    left, right = x < -0.10, x > 0.10
    return [f"trace {np.nanmin(tr):.3g} – {np.nanmax(tr):.3g}",
            f"deviatoric fraction {np.nanmin(dev):.3g} – {np.nanmax(dev):.3g} (median {np.nanmedian(dev):.3g})",
            f"orientation of the major axis, two lowest rows: {_mean_deg(ori[low][:, left])} for x < −10 cm, "
            f"{_mean_deg(ori[low][:, right])} for x > 10 cm",
            f"mean |angle between stress and fabric axes| there: {_mean_deg(np.abs(ang[low]))}"]


def _mean_deg(a):
    return f"{np.nanmean(a):.1f}°" if np.isfinite(a).any() else "no valid RVE"


#: Fig. 4's fits (law, fit, m, label) and the moduli whose medians are quoted (label, quantity, fit column).
MODULI_FITS = (("isotropic", "modulus", 1, "isotropic S′, m = 1"), ("cubic", "compliance", 5, "cubic S̃, m = 5"))
MODULI_MEDIANS = (("K (isotropic, m = 1)", "bulk_modulus", 0, "modulus"),
                  ("E (isotropic, m = 1)", "youngs_modulus", 0, "modulus"),
                  ("G (isotropic, m = 1)", "shear_modulus", 0, "modulus"),
                  ("K (cubic, m = 5)", "bulk_modulus_cubic", 1, "compliance"),
                  ("E_av (cubic, m = 5)", "E_av", 1, "compliance"),
                  ("G_av (cubic, m = 5)", "G_av", 1, "compliance"),
                  ("E (isotropic, m = 1)", "youngs_modulus", 0, "average"),
                  ("E_av (cubic, m = 5)", "E_av", 1, "average"))


def _share_cell(reason, why="masked"):
    """The share of the fits made that are masked (for ``why``), of :func:`analysis.elastic.mask_counts`."""
    counts = mask_counts(reason)
    return f"{100 * counts[why] / counts['fitted']:.0f} %" if counts["fitted"] else "n/a"


def _fit_masks(md, law, fit, m):
    """The mask bits of the fit of the ensemble mean, of each pile's fit and of the mean over piles (y first)."""
    sub = md.sel(fit=fit, points=m)
    return (sub[f"{law}_mask_reason"].values, sub[f"{law}_mask_reason_piles"].transpose("y", "seed", "x").values,
            sub[f"{law}_mask_reason_pile_mean"].values)


def moduli(md, heights):
    """Lines of Fig. 4's numbers for one protocol's ``moduli.nc``: the shares masked per layer, then the medians."""
    out = [f"Moduli (Fig. 4): a fit is masked where its condition number exceeds {md.attrs['max_condition']:g} "
           "(analysis.moduli.max_condition) or it is not positive definite (isotropic: K > 0 and G > 0; cubic: "
           "λ1 > |λ2| and λ3 > 0); the mean over piles is masked where fewer than "
           f"{100 * md.attrs['min_valid_piles']:.0f} % of the piles' own fits are valid. Masked, of the RVEs with a "
           "fit: the fit of the ensemble mean / the piles' own fits (pile-RVEs) / their mean over piles:", "",
           "| y (cm) | " + " | ".join(label for *_, label in MODULI_FITS) + " |", "|---|---|---|"]
    masks = [_fit_masks(md, law, fit, m) for law, fit, m, _ in MODULI_FITS]
    y = md["y"].values
    rows = list(dict.fromkeys(_row_index(md, h) for h in heights))
    for label, sel in [(f"{100 * y[k]:.1f}", np.s_[k]) for k in rows] + [("all RVEs", np.s_[:])]:
        cells = []
        for ens, piles, mean in masks:
            n = mask_counts(ens[sel])["fitted"]
            cells.append(f"{_share_cell(ens[sel])} / {_share_cell(piles[sel])} / {_share_cell(mean[sel])} of {n}"
                         if n else "no fit")
        if any(c != "no fit" for c in cells):
            out.append(f"| {label} | " + " | ".join(cells) + " |")
    own = []
    for (law, fit, m, label), (_, piles, _) in zip(MODULI_FITS, masks):
        own.append(f"{label}: {_share_cell(piles, 'not_positive_definite')} not positive definite, "
                   f"{_share_cell(piles, 'ill_conditioned')} ill-conditioned")
    out += ["", "Why the piles' own fits are masked (a fit may be both): " + "; ".join(own) + ".", "",
            "Medians over the RVEs kept (kept / with a fit):", "",
            "| modulus | fit | fit of the ensemble mean | mean over piles |", "|---|---|---|---|"]
    for label, name, col, fit in MODULI_MEDIANS:
        law, _, m, _ = MODULI_FITS[col]
        sub = md.sel(fit=fit, points=m)
        cells = []
        for var, reason in ((name, f"{law}_mask_reason"), (f"{name}_pile_mean", f"{law}_mask_reason_pile_mean")):
            v = sub[var].values
            tried = mask_counts(sub[reason].values)["fitted"]
            kept = int(np.isfinite(v).sum())
            cells.append(f"{np.nanmedian(v):.3g} N/m ({kept} / {tried})" if kept else f"all masked (0 / {tried})")
        fit_label = {"modulus": "S′", "compliance": "S̃", "average": "average of both"}[fit]
        out.append(f"| {label} | {fit_label} | {cells[0]} | {cells[1]} |")
    return out


def invariants(inv):
    """Lines of Fig. 5: the straight line's R² (:func:`analysis.invariants.trace_line_r2`) near the axis and over all RVEs."""
    ts, te = inv["trace_stress_increment"].values, inv["trace_strain_increment"].values
    x = np.broadcast_to(inv["x"].values, ts.shape)
    out = []
    for label, sel in (("|x| <= 10 cm", np.abs(x) <= 0.10), ("all RVEs", np.ones_like(x, bool))):
        r2, n = trace_line_r2(ts[sel], te[sel])
        out.append(f"{label}: R² = {r2:.3f} over {n} RVEs" if n >= 3 else f"{label}: fewer than 3 RVEs")
    return out


def convergence(paths):
    """Table rows of Fig. 1 over the convergence files ``paths`` (same sizes in each), and the number of points:
    the deviation from the largest RVE (:func:`analysis.convergence.deviations`)."""
    sets = [xr.open_dataset(path).load() for path in paths]
    sizes = sets[0]["rve_size"].values
    if any(not np.array_equal(ds["rve_size"].values, sizes) for ds in sets):
        refuse(f"--convergence {' '.join(map(str, paths))}: the files do not share their RVE sizes")
    dev = deviations(sets, ref=-1)
    (stress, stress_max), (inc, inc_max), n = dev["stress"], dev["stress_increment"], dev["n"]
    rows = []
    for k, size in enumerate(sizes[:-1]):
        rows.append(f"| {100 * size:.1f} | {int(n[k].min())}–{int(n[k].max())} | "
                    f"{stress[k]:.1f} / {stress_max[k]:.1f} | {inc[k]:.1f} / {inc_max[k]:.1f} |")
    return rows, n.shape[1]


def balance(paths):
    worst = {"relaxed": 0.0, "reduced": 0.0, "increment": None}
    for path in paths:
        rep = json.load(open(path))
        for stage in ("relaxed", "reduced"):
            e = rep["stages"].get(stage, {}).get("support_reaction_rel_error")
            if e is not None:
                worst[stage] = max(worst[stage], abs(e))
        inc = rep.get("increment", {}).get("support_reaction_rel_error")
        if inc is not None:
            worst["increment"] = max(worst["increment"] or 0.0, abs(inc))
    inc = "not recorded" if worst["increment"] is None else f"{worst['increment']:.2g}"
    return (f"largest |support reaction / weight − 1| over {len(paths)} piles: relaxed "
            f"{worst['relaxed']:.2g}, reduced {worst['reduced']:.2g}; increment {inc}")


def general_fit(gm):
    """Lines of the extra probes' measures for one protocol's general_moduli.nc (:func:`analysis.probes.general_fit_summary`)."""
    g = general_fit_summary(gm)
    out = [f"{_piles(int(gm.attrs.get('n_seeds', 0)))}, loading probes {gm.attrs.get('loading_probes', '?')}, "
           f"slips left out {g['slips']} pile-probe-RVEs"]
    for m, fit in g["fits"].items():
        out.append(f"m = {m}: identified and positive definite at {fit['identified']} of {fit['tried']} "
                   f"RVEs, median condition number {fit['condition']:.3g}")
    if g["m5"]:
        expl = ", ".join(f"{law} {v:.2f}" for law, v in g["m5"]["explained"].items())
        out.append(f"m = 5, over those RVEs: median fraction of the stress increments explained: {expl}; "
                   f"median anisotropy E_max/E_min {g['m5']['anisotropy']:.3g}")
        for name, (mean, n) in g["m5"]["axes"].items():
            out.append(f"mean angle between the stiffness axis and the {name.split('_')[0]} axis "
                       f"{f'{mean:.1f}°' if n else 'no valid RVE'} over {n} RVEs")
    if g["reversibility"]:
        lo, med, hi, n = g["reversibility"]
        out.append(f"reversibility 1 − |u(restored)|/|u(reduced)|: median {med:.2f} (10–90 %: {lo:.2f} – {hi:.2f}) "
                   f"over {n} RVEs; by depth below the surface: " + "; ".join(_depth_lines(g["by_depth"])))
    return out


#: The files of each protocol's ensemble that the numbers are read from.
ENSEMBLE_FILES = ("fields.nc", "base_pressure.nc", "moduli.nc", "invariants.nc")


def _depth_lines(bands):
    """Median reversibility (and its 10 % quantile) per depth band (:func:`analysis.probes.reversibility_by_depth`)."""
    return [f"{f'over {100 * lo:g} cm' if np.isinf(hi) else f'{100 * lo:g}–{100 * hi:g} cm'} median {med:.2f} "
            f"(10 %: {p10:.2f}, {n} RVEs)" for lo, hi, med, p10, n in bands]


def per_pile_probes(paths):
    """Lines for the piles' probes files: per pile its median reversibility
    (:func:`analysis.probes.reversibility` over its RVEs) and the asymmetry of
    its opposite tilts; last, the mean of the piles' median reversibilities
    and its standard error over the piles."""
    out, medians = [], []
    for path in paths:
        with xr.open_dataset(path) as pr:
            parts = []
            rev = reversibility(pr["strain_increment"].values, [str(p) for p in pr["probe"].values])
            if np.isfinite(rev).any():
                medians.append(float(np.nanmedian(rev)))
                parts.append(f"median reversibility {medians[-1]:.2f}")
            for name, label in (("strain_increment", "strain"), ("stress_increment", "stress")):
                r = tilt_asymmetry(pr, name)
                if r is not None and np.isfinite(r).any():
                    lo, med, hi = np.nanpercentile(r, [10, 50, 90])
                    parts.append(f"opposite tilts, {label} {med:.2f} ({lo:.2f} – {hi:.2f})")
            out.append(f"seed {pr.attrs.get('seed', '?')}: " + ("; ".join(parts) if parts else "no reduction and restoration, no pair of opposite tilts"))
    if medians:
        m, sem, _, n = mean_sem(medians)
        out.append(f"median reversibility, mean over the {_piles(n)}: {_pm(m, sem, '.2f')}")
    return out


def _history_cell(name, m, se):
    if UNITS.get(name) == "deg":
        return _pm(m, se, ".2f") + "°"
    if not np.isfinite(m):
        return "n/a"
    return f"{100 * m:+.1f} ± " + ("n/a" if not np.isfinite(se) else f"{100 * se:.1f}") + " %"


def history_values(fields, bases, params, heights):
    """Per protocol, each pile's history statistics (:func:`analysis.history.pile_history`).

    ``fields`` and ``bases`` are ``PROTOCOL=FILE`` items; a pile's base pressure
    is used where its file is among ``bases`` (the same seed)."""
    by_seed = {}
    for item in bases:
        p, path = item.split("=", 1)
        by_seed[(p, Path(path).name.split(".")[0])] = path
    out = {}
    for item in fields:
        p, path = item.split("=", 1)
        bp_path = by_seed.get((p, Path(path).name.split(".")[0]))
        with read_fields(path) as ds:
            bp = xr.open_dataset(bp_path) if bp_path else None
            try:
                out.setdefault(p, []).append(pile_history(ds.load(), params, heights, bp))
            finally:
                if bp is not None:
                    bp.close()
    return out


def _piles_cell(n):
    if np.isinf(n):
        return "> 100000"
    return "n/a" if not np.isfinite(n) else f"{n:.0f}"


def _scaled(name, v, spec=".1f"):
    return f"{v:{spec}}°" if UNITS.get(name) == "deg" else f"{100 * v:{spec}} %"


def primary_lines(tests, a="wedge", b="layered"):
    """Markdown of :func:`analysis.decision.primary_tests`."""
    k = len(tests)
    out = [f"Decision on the {k} primary statistics, {a} − {b}: Welch's t (difference over its standard error), "
           "its degrees of freedom (Welch–Satterthwaite) and two-sided p from Student's t; the |t| that a "
           f"family-wise {100 * LEVEL:g} % over the {k} asks at those degrees of freedom (Bonferroni, Holm's first "
           f"step); the Holm-adjusted p and the verdict at a family-wise {100 * LEVEL:g} %.",
           "", "| statistic | difference | t | df | p | Bonferroni \\|t\\| | Holm p | verdict |",
           "|---|---|---|---|---|---|---|---|"]
    for t in tests:
        verdict = "different" if t["rejected"] else "not resolved"
        out.append(f"| {t['name']} | {_history_cell(t['name'], t['diff'], t['se'])} | {t['t']:+.2f} | {t['df']:.1f} | "
                   f"{t['p']:.4f} | {t['t_bonferroni']:.2f} | {t['holm_p']:.3f} | {verdict} |")
    out += ["", f"Power: per-pile scatter (SD over piles, {a} / {b}) and the piles per protocol with which Welch's "
            f"test finds a difference of 5 % (2° for the angle) with {100 * POWER:g} % probability, at a family-wise "
            f"{100 * LEVEL:g} % over the {k} (Bonferroni, a bound for Holm) and for one test alone; and the piles that "
            "find a difference of the measured size at the family-wise level (noncentral t at Welch's degrees of "
            "freedom, the scatter taken as measured).", "",
            "| statistic | SD per pile | piles: 5 % (2°), family-wise | 5 % (2°), one test "
            "| measured difference, family-wise |",
            "|---|---|---|---|---|"]
    for t in tests:
        sd = " / ".join(_scaled(t["name"], v) for v in t["sd"])
        out.append(f"| {t['name']} | {sd} | {_piles_cell(t['n_delta'])} | {_piles_cell(t['n_delta_single'])} | "
                   f"{_piles_cell(t['n_measured'])} |")
    return out


def history(values, params, heights, a="wedge", b="layered"):
    """Lines of the history statistics: ``a`` against ``b``."""
    h = params["history"]
    primary = primary_names(h)
    names = list(dict.fromkeys(k for piles in values.values() for v in piles for k in v))
    rows = []
    for name in primary + [n for n in names if n not in primary]:
        va = [v.get(name, np.nan) for v in values.get(a, [])]
        vb = [v.get(name, np.nan) for v in values.get(b, [])]
        c = compare(va, vb, deltas=DELTAS[UNITS.get(name, "")])
        if c["a"][3] + c["b"][3] == 0:
            continue
        w = welch(va, vb)
        unit = UNITS.get(name, "")
        d1, d2 = DELTAS[unit]
        need = " / ".join(_piles_cell(piles_for_power(c["a"][2], c["b"][2], d, POWER, 1, LEVEL)) for d in (d1, d2))
        df = "n/a" if not np.isfinite(w["df"]) else f"{w['df']:.1f}"
        rows.append(f"| {'**' + name + '**' if name in primary else name} | {_history_cell(name, *c['a'][:2])} "
                    f"({c['a'][3]}; {c['z_a']:+.1f}) | {_history_cell(name, *c['b'][:2])} ({c['b'][3]}; {c['z_b']:+.1f}) | "
                    f"{_history_cell(name, c['diff'], c['se'])} | {c['z']:+.1f} | {df} | {need} |")
    return [
        f"Windows (analysis.history): centre |x| <= {100 * h['centre']:g} cm, "
        f"shoulders {100 * h['shoulder_inner']:g}–{100 * h['shoulder_outer']:g} cm; core |x| <= "
        f"{100 * h['shoulder_outer']:g} cm, y <= {100 * h['core_height']:g} cm; flanks "
        f"{100 * h['flank_inner']:g}–{100 * h['flank_outer']:g} cm, y <= {100 * h['flank_height']:g} cm. "
        "They were committed (8fb4149, 2026-12-03) after these piles were recorded and read (2026-12-01/02): "
        "not pre-registered for them. "
        "Per pile (analysis/history.py), then the mean ± standard error over piles, "
        "(piles; mean in SE from 0), the difference {a} − {b} with its standard error and Welch's "
        "t = difference / SE with its degrees of freedom.".format(a=a, b=b),
        "",
        f"Piles per protocol that find a difference of 5 / 10 % (2 / 5 degrees for the angle) with "
        f"{100 * POWER:g} % probability in one two-sided test at {100 * LEVEL:g} % (Welch, noncentral t), "
        "from the measured scatter; the primary statistics at the family-wise level are below.",
        "",
        f"| statistic | {a} | {b} | {a} − {b} | t | df | piles for 5 / 10 % |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"{len(rows)} statistics, each compared three ways ({a} and {b} against 0, {a} − {b}): {3 * len(rows)} "
        f"comparisons. The {len(primary)} in bold are the primary ones, one per question.",
        "",
        *primary_lines(primary_tests(values, params["history"], a, b), a, b),
    ]


# ---------------------------------------------------------------------------
# Checks of the report's verdicts (docs/reproduction.md), from the per-pile
# files: each function returns numbers, and :func:`checks_lines` the text.

def _pile_items(items):
    """``PROTOCOL=FILE`` items as ``{protocol: [path, ...]}``."""
    out = {}
    for item in items:
        p, path = item.split("=", 1)
        out.setdefault(p, []).append(path)
    return out


def end_state(fields_items, history, surface_half_width=0.20):
    """How alike the two protocols' relaxed piles end: per protocol the flanks of
    the relaxed summaries (mean ± SE over flanks), and per pile its flank
    fabric (:func:`analysis.history.flank_fabric`, mean ± SE over piles), and the
    mean surface; the largest gap between the protocols' mean surfaces over
    ``|x| <= surface_half_width``."""
    out, surfaces, x = {}, {}, None
    for p, paths in _pile_items(fields_items).items():
        flanks, dev, axis, surf = [], [], [], []
        for path in paths:
            with xr.open_dataset(path) as ds:
                x = ds["x"].values
                fabric = flank_fabric(ds, history)
                dev.append(fabric["fabric_deviator"])
                axis.append(fabric["fabric_axis_deg"])
                surf.append(ds["surface_height"].values)
            summary = Path(path.replace(".fields.nc", ".summary.json"))
            if summary.exists():
                relaxed = [json.loads(line) for line in summary.read_text().splitlines() if line.strip()]
                relaxed = [r for r in relaxed if r["stage"] == "relaxed"][0]
                flanks += [relaxed["flank_left_deg"], relaxed["flank_right_deg"]]
        out[p] = {"flanks": mean_sem(flanks), "fabric_deviator": mean_sem(dev), "fabric_axis": mean_sem(axis)}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)          # columns off every pile
            surfaces[p] = np.nanmean(np.array(surf), axis=0)
    a, b = list(surfaces)[:2]
    sel = np.abs(x) <= surface_half_width + 1e-9
    gap = np.abs(surfaces[a][sel] - surfaces[b][sel])
    out["surface_gap"] = (float(gap.max()), float(x[sel][np.argmax(gap)]))
    return out


def line_source_cap(bases_items, fields_items, density, slope_deg, gravity):
    """The height H of the layered source's target pile (:func:`sim.release.target_pile`:
    the particles' area at a solid fraction of 0.8 in a triangle of flanks
    ``slope_deg``), the particles' area from each pile's weight ``W = ρ A g``;
    above a top of H the line is one circumradius long (a point source).
    Returns the range of H over the piles and the range of the layered piles'
    relaxed heights."""
    heights = []
    for p, paths in _pile_items(bases_items).items():
        for path in paths:
            with xr.open_dataset(path) as bp:
                area = float(bp["weight"].values[0]) / (density * gravity) / 0.8
            heights.append(math.sqrt(area * math.tan(math.radians(slope_deg))))
    tops = []
    for path in _pile_items(fields_items).get("layered", []):
        summary = Path(path.replace(".fields.nc", ".summary.json"))
        if summary.exists():
            tops += [json.loads(line)["height"] for line in summary.read_text().splitlines()
                     if line.strip() and json.loads(line)["stage"] == "relaxed"]
    span = (min(heights), max(heights)) if heights else (math.nan, math.nan)
    return span, (min(tops), max(tops)) if tops else (math.nan, math.nan)


def report_checks(fields_items, bases_items, convergence_paths, invariants, params, study):
    """Every number of the report's verdict table that numbers.md does not print elsewhere,
    as ``{key: text}``: the text docs/reproduction.md quotes (tests/test_reproduction_report.py
    recomputes them from the committed files and finds them in the report)."""
    h = params["history"]
    piles = _pile_items(fields_items)
    t = {}
    contrasts = {}
    for p, paths in piles.items():
        for path in paths:
            with read_fields(path) as ds:
                c = pile_stress_contrasts(ds, params)
                c["secant_low"], c["secant_high"], c["secant_low_strain"] = pile_secants(ds, params)
            contrasts.setdefault(p, []).append(c)
    values = history_values(fields_items, bases_items, params, [h["primary_height"]])
    for p, cs in contrasts.items():
        for key in ("stress_increment", "vertical_stiffness", "stress_column"):
            m, se, sd, n = mean_sem([c[key] for c in cs])
            t[f"{p}.{key}"] = f"{100 * m:+.1f} ± {100 * se:.1f} %"
            t[f"{p}.{key}.sd"] = f"{100 * sd:.1f} %"
        m, se, sd, n = mean_sem([v.get("base_pressure_column", np.nan) for v in values[p]])
        t[f"{p}.base_pressure_column.sd"] = f"{100 * sd:.1f} %"
        lo, hi = mean_sem([c["secant_low"] for c in cs]), mean_sem([c["secant_high"] for c in cs])
        ratio = mean_sem([c["secant_high"] / c["secant_low"] for c in cs])
        t[f"{p}.secant_piles"] = (f"{lo[0]:.2g} ± {lo[1]:.1g} to {hi[0]:.2g} ± {hi[1]:.1g} N/m, "
                                  f"ratio {ratio[0]:.2f} ± {ratio[1]:.2f}")
        t[f"{p}.secant_ratio_se_from_1"] = f"{(ratio[0] - 1) / ratio[1]:.1f}"
        t[f"{p}.stiffness_strain_min"] = f"{min(c['strain_min'] for c in cs):.1e}"
        t[f"{p}.secant_piles_strain_min"] = f"{min(c['secant_low_strain'] for c in cs):.1e}"
        t[f"{p}.lowest_row"] = f"{100 * cs[0]['lowest_row_y']:g} cm"
    a, b = list(contrasts)[:2]
    sd_col = [mean_sem([c["stress_column"] for c in contrasts[p]])[2] for p in (a, b)]
    sd_bp = [mean_sem([v.get("base_pressure_column", np.nan) for v in values[p]])[2] for p in (a, b)]
    t["stress_column.sd_ratio"] = f"{math.hypot(*sd_col) / math.hypot(*sd_bp):.2f}"
    col = {p: [c["stress_column"] for c in contrasts[p]] for p in (a, b)}
    w, diff = welch(col[a], col[b]), compare(col[a], col[b])["diff"]
    t["stress_column.diff"] = f"{100 * diff:+.1f} %, t = {w['t']:+.2f} ({w['df']:.1f} df)"
    t["stress_column.piles"] = f"{piles_for_power(*sd_col, 0.05, POWER, 5, LEVEL):.0f}"
    t["base_pressure_column.piles"] = f"{piles_for_power(*sd_bp, 0.05, POWER, 5, LEVEL):.0f}"
    for p, inv in invariants.items():
        sec, strain = secant_deciles(inv["trace_stress_increment"].values.ravel(),
                                     inv["trace_strain_increment"].values.ravel())
        t[f"{p}.secant_deciles"] = ", ".join(f"{v:.2g}" for v in sec)
        t[f"{p}.secant_range"] = f"{sec[0]:.2g} to {sec[-1]:.2g} N/m"
        t[f"{p}.decile_strain_min"] = f"{strain.min():.1e}"
        t[f"{p}.secant_factor"] = f"{sec[-1] / sec[0]:.1f}"
        t[f"{p}.secant_rises"] = f"{int(np.sum(np.diff(sec) > 0))} of {sec.size - 1}"
        t[f"{p}.trace_strain_max"] = f"{np.nanmax(inv['trace_strain_increment'].values):.1e}"
    conv = deviations([xr.open_dataset(path).load() for path in convergence_paths])
    sizes, ref = conv["sizes"], conv["ref"]
    t["fig1.reference"] = f"{100 * sizes[ref]:g} cm"
    t["fig1.cut_points"] = ", ".join(f"{100 * v:g}" for v in conv["cut_points"]) + " cm"
    t["fig1.largest_cut"] = f"{100 * (conv['stress_largest_cut'] - 1):+.1f} %"  # nan: no point cut
    for k, size in enumerate(sizes[:ref]):
        n = conv["n"][k]
        t[f"fig1.{100 * size:g}"] = (f"{int(n.min())}–{int(n.max())} particles: σ_yy {conv['stress'][0][k]:.1f} % "
                                     f"(largest {conv['stress'][1][k]:.1f} %), Δσ_yy {conv['stress_increment'][0][k]:.1f} % "
                                     f"(largest {conv['stress_increment'][1][k]:.1f} %)")
    end = end_state(fields_items, h)
    for p in (a, b):
        e = end[p]
        t[f"{p}.flanks"] = f"{e['flanks'][0]:.1f}° ± {e['flanks'][1]:.1f}°"
        t[f"{p}.fabric_deviator"] = f"{e['fabric_deviator'][0]:.3f} ± {e['fabric_deviator'][1]:.3f}"
        t[f"{p}.fabric_axis"] = f"{e['fabric_axis'][0]:.1f}° ± {e['fabric_axis'][1]:.1f}°"
    t["surface_gap"] = f"{1000 * end['surface_gap'][0]:.1f} mm (at x = {100 * end['surface_gap'][1]:.1f} cm)"
    (h_lo, h_hi), (top_lo, top_hi) = line_source_cap(bases_items, fields_items, study["density"],
                                                     study["layered_slope_deg"], study["gravity"])
    t["line_source.H"] = f"{100 * h_lo:.1f}–{100 * h_hi:.1f} cm"
    t["line_source.tops"] = f"{100 * top_lo:.1f}–{100 * top_hi:.1f} cm"
    return t


def checks_lines(t):
    return ["## Checks of the report's verdicts", "",
            "Made from the per-pile files by `report_checks`; docs/reproduction.md quotes them "
            "(tests/test_reproduction_report.py recomputes them). Contrasts are centre over shoulders − 1 in the "
            "windows of analysis.history, per pile, then mean ± standard error over piles.", "",
            *[f"- `{k}`: {v}" for k, v in t.items()], ""]


def protocol_file(text: str) -> str:
    """An argument type: ``PROTOCOL=FILE`` of a file that exists (kept as the text)."""
    protocol, sep, path = text.partition("=")
    if not (sep and protocol and Path(path).is_file()):
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is PROTOCOL=FILE, of a file that exists")
    return text


def main(argv=None):
    """Command line: print the numbers (Markdown)."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ensemble", type=existing_folder, required=True, help="folder of results/ensemble/{protocol}/")
    ap.add_argument("--protocols", nargs="+", required=True)
    ap.add_argument("--convergence", nargs="+", type=existing_file, required=True,
                    help="the convergence files of the piles")
    ap.add_argument("--checks", nargs="+", type=existing_file, required=True, help="checks.json of every pile")
    ap.add_argument("--heights", nargs="+", type=positive_float, required=True, help="rows of Fig. 2, m")
    ap.add_argument("--general", nargs="*", type=protocol_file, default=[], metavar="PROTOCOL=FILE",
                    help="general_moduli.nc of the protocols with the extra probes")
    ap.add_argument("--probes", nargs="*", type=protocol_file, default=[], metavar="PROTOCOL=FILE",
                    help="the probes.nc of every pile with the extra probes")
    ap.add_argument("--fields", nargs="*", type=protocol_file, default=[], metavar="PROTOCOL=FILE",
                    help="every pile's fields.nc (the history statistics)")
    ap.add_argument("--base-pressure", nargs="*", type=protocol_file, default=[], metavar="PROTOCOL=FILE",
                    help="every pile's base_pressure.nc")
    ap.add_argument("--params", type=analysis_params, default="{}",
                    help="the analysis section as JSON (the history windows)")
    ap.add_argument("--study-config", type=existing_file,
                    default=str(Path(__file__).resolve().parents[2] / "config" / "config.yaml"),
                    help="the study's configuration (model.density, pour.layered_slope_deg): the line source's cap")
    args = ap.parse_args(argv)
    params = args.params
    for p in args.protocols:
        for name in ENSEMBLE_FILES:
            if not (args.ensemble / p / name).is_file():
                refuse(f"--ensemble {args.ensemble} --protocols ... {p}: no {p}/{name} in it; allowed are the "
                       "protocols whose ensemble it holds")
    out = ["# Numbers of the reproduction", "",
           "Made by `workflow/tools/reproduction_numbers.py` from the ensembles (`make reproduction`); "
           "mean ± standard error over piles.", ""]
    for p in args.protocols:
        with read_fields(f"{args.ensemble}/{p}/fields.nc") as ds:
            n = int(ds.attrs.get("n_seeds", 0))
            out += [f"## {p} ({_piles(n)})", "", f"Slips: {slips(ds)}.", "", "Vertical strain increment u_yy (Fig. 2):", "",
                    f"| y (cm) | centre (|x| <= {100 * params['history']['centre']:g} cm) | shoulders "
                    f"({100 * params['history']['shoulder_inner']:g}–{100 * params['history']['shoulder_outer']:g} cm) |",
                    "|---|---|---|", *strain_profile(ds, args.heights, params["history"]),
                    "", "Fabric (Fig. 3): " + "; ".join(fabric(ds)) + "."]
        with xr.open_dataset(f"{args.ensemble}/{p}/base_pressure.nc") as bp:
            out += ["", f"Base pressure: {base_pressure(bp)}."]
        with xr.open_dataset(f"{args.ensemble}/{p}/moduli.nc") as md:
            out += ["", *moduli(md, args.heights)]
        with xr.open_dataset(f"{args.ensemble}/{p}/invariants.nc") as inv:
            out += ["", "tr Δσ against tr ε (Fig. 5): " + "; ".join(invariants(inv)) + ".", ""]
    if args.fields:
        out += ["## Construction history: centre against shoulders", "",
                *history(history_values(args.fields, args.base_pressure, params, args.heights), params, args.heights),
                ""]
    if args.fields:
        study = read_settings_file(args.study_config)
        with xr.open_dataset(args.fields[0].split("=", 1)[1]) as first:
            gravity = float(first.attrs["gravity_relaxed"])
        inv_sets = {}
        for p in args.protocols:
            with xr.open_dataset(f"{args.ensemble}/{p}/invariants.nc") as inv:
                inv_sets[p] = inv.load()
        out += checks_lines(report_checks(args.fields, args.base_pressure, args.convergence, inv_sets, params,
                                          {"density": study["model"]["density"],
                                           "layered_slope_deg": study["pour"]["layered_slope_deg"],
                                           "gravity": gravity}))
    rows, points = convergence(args.convergence)
    out += [f"## RVE convergence (Fig. 1; {len(args.convergence)} piles, {points} points in all)", "",
            "Deviation from the value in the largest RVE, %: median / largest over the piles and points.", "",
            "| RVE side (cm) | particles | σ_yy | Δσ_yy |", "|---|---|---|---|", *rows, ""]
    out += ["## Balance laws", "", balance(args.checks) + ".", ""]
    for item in args.general:
        p, path = item.split("=", 1)
        with xr.open_dataset(path) as gm:
            out += [f"## Extra probes, {p}: the general elastic fit", "", *[f"- {line}." for line in general_fit(gm)], ""]
        mine = [f for q, f in (item.split("=", 1) for item in args.probes) if q == p]
        if mine:
            out += ["Per pile: the median reversibility over its RVEs; opposite tilts, "
                    "|Δ(+) + Δ(−)| / (|Δ(+)| + |Δ(−)|) per RVE (0: linear), median (10 – 90 %):", "",
                    *[f"- {line}." for line in per_pile_probes(mine)], ""]
    sys.stdout.write("\n".join(out))
