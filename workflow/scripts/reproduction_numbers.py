"""The numbers that docs/reproduction.md sets against the paper's, from the ensembles.

Usage::

    python workflow/scripts/reproduction_numbers.py --ensemble results/ensemble \\
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
  pre-registered statistics of :mod:`analysis.history`, per pile, then wedge
  against layered with the standard error of the difference, ``z``, the
  minimum detectable difference and the piles needed for a 5 and a 10 %
  difference; how many comparisons were made.
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
import sys

from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from analysis.elastic import mask_counts  # noqa: E402
from analysis.history import (UNITS, bonferroni_z, compare, detection_factor, pile_history,  # noqa: E402
                              primary_names, windows)
from analysis.params import parse_params  # noqa: E402
from analysis.probes import reversibility  # noqa: E402


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
    ts, te = inv["trace_stress_increment"].values, inv["trace_strain_increment"].values
    x = np.broadcast_to(inv["x"].values, ts.shape)
    out = []
    for label, sel in (("|x| <= 10 cm", np.abs(x) <= 0.10), ("all RVEs", np.ones_like(x, bool))):
        ok = sel & np.isfinite(ts) & np.isfinite(te)
        if ok.sum() < 3:
            out.append(f"{label}: fewer than 3 RVEs")
            continue
        r = np.corrcoef(te[ok], ts[ok])[0, 1]
        out.append(f"{label}: R² = {r * r:.3f} over {int(ok.sum())} RVEs")
    return out


def convergence(paths):
    """Table rows of Fig. 1 over the convergence files ``paths`` (same sizes in each), and the number of points."""
    sets = [xr.open_dataset(path).load() for path in paths]
    sizes = sets[0]["rve_size"].values
    if any(not np.array_equal(ds["rve_size"].values, sizes) for ds in sets):
        raise SystemExit(f"the convergence files {paths} do not share their RVE sizes")

    def deviation(name):
        v = np.concatenate([ds[name].sel(i="y", j="y").values for ds in sets], axis=1)  # (size, pile x point)
        return np.abs(v / v[-1] - 1.0)

    dev, dev_inc = deviation("stress"), deviation("stress_increment")
    n = np.concatenate([ds["n_particles"].values for ds in sets], axis=1)
    rows = []
    for k, size in enumerate(sizes[:-1]):
        rows.append(f"| {100 * size:.1f} | {int(n[k].min())}–{int(n[k].max())} | "
                    f"{100 * np.median(dev[k]):.1f} / {100 * dev[k].max():.1f} | "
                    f"{100 * np.median(dev_inc[k]):.1f} / {100 * dev_inc[k].max():.1f} |")
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


def _axis_gap(a, b):
    """Angles between axes a and b (degrees), folded into [0, 90]."""
    return np.abs((a - b + 90.0) % 180.0 - 90.0)


def general_fit(gm):
    """Lines of the extra probes' measures for one protocol's general_moduli.nc."""
    out = [f"{_piles(int(gm.attrs.get('n_seeds', 0)))}, loading probes {gm.attrs.get('loading_probes', '?')}, "
           f"slips left out {int(gm['slip_left_out'].sum())} pile-probe-RVEs"]
    flags = gm["general_flag"].attrs
    few = int(dict(zip(flags["flag_meanings"].split(), flags["flag_masks"]))["insufficient_samples"])
    for m in (1, 5):
        fit = gm.sel(points=m)
        tried = (fit["general_flag"].values & few) == 0           # enough samples for a fit
        ok = fit["general_flag"].values == 0
        out.append(f"m = {m}: identified and positive definite at {int(ok.sum())} of {int(tried.sum())} "
                   f"RVEs, median condition number {np.median(fit['condition'].values[tried]):.3g}")
    fit = gm.sel(points=5)
    ok = fit["general_flag"].values == 0
    if ok.any():
        expl = ", ".join(f"{law} {np.median(fit[f'explained_{law}'].values[ok]):.2f}"
                         for law in ("general", "cubic", "isotropic"))
        out.append(f"m = 5, over those RVEs: median fraction of the stress increments explained: {expl}; "
                   f"median anisotropy E_max/E_min {np.median(fit['anisotropy'].values[ok]):.3g}")
        axis = np.where(ok, fit["axis_deg"].values, np.nan)
        for name in ("fabric_orientation", "stress_orientation"):
            if name in gm:
                gap = _axis_gap(axis, gm[name].values)
                out.append(f"mean angle between the stiffness axis and the {name.split('_')[0]} axis "
                           f"{_mean_deg(gap)} over {int(np.isfinite(gap).sum())} RVEs")
    rev = gm["reversibility"].values
    if np.isfinite(rev).any():
        lo, med, hi = np.nanpercentile(rev, [10, 50, 90])
        out.append(f"reversibility 1 − |u(restored)|/|u(reduced)|: median {med:.2f} (10–90 %: {lo:.2f} – {hi:.2f}) "
                   f"over {int(np.isfinite(rev).sum())} RVEs; by depth below the surface: "
                   + "; ".join(reversibility_by_depth(gm)))
    return out


#: Depth bands (m below the top filled RVE of each grid column) of the reversibility.
DEPTHS = (0.0, 0.03, 0.06, 0.10, np.inf)


def reversibility_by_depth(gm):
    """Median reversibility (and its 10 % quantile) per band of :data:`DEPTHS`."""
    rev, y = gm["reversibility"].values, gm["y"].values
    filled = np.isfinite(rev)
    top = np.array([y[filled[:, j]].max() if filled[:, j].any() else np.nan for j in range(rev.shape[1])])
    depth = top[None, :] - y[:, None]
    out = []
    for lo, hi in zip(DEPTHS[:-1], DEPTHS[1:]):
        band = filled & (depth >= lo) & (depth < hi)
        name = f"over {100 * lo:g} cm" if np.isinf(hi) else f"{100 * lo:g}–{100 * hi:g} cm"
        if band.any():
            out.append(f"{name} median {np.median(rev[band]):.2f} (10 %: {np.percentile(rev[band], 10):.2f}, "
                       f"{int(band.sum())} RVEs)")
    return out


def tilt_asymmetry(pr, name):
    """``|Δ(+) + Δ(−)| / (|Δ(+)| + |Δ(−)|)`` per RVE of the increment ``name`` of a pile's
    opposite tilts (the first pair of tiltpNN / tiltmNN stages); None without one."""
    probes = [str(p) for p in pr["probe"].values]
    plus = [p for p in probes if p.startswith("tiltp")]
    minus = [p.replace("tiltp", "tiltm") for p in plus]
    if not plus or minus[0] not in probes:
        return None
    a, b = pr[name].sel(probe=plus[0]).values, pr[name].sel(probe=minus[0]).values
    norm_a, norm_b = np.linalg.norm(a, axis=(-2, -1)), np.linalg.norm(b, axis=(-2, -1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.norm(a + b, axis=(-2, -1)) / (norm_a + norm_b)


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
        sem = np.std(medians, ddof=1) / np.sqrt(len(medians)) if len(medians) > 1 else np.nan
        out.append(f"median reversibility, mean over the {_piles(len(medians))}: {_pm(np.mean(medians), sem, '.2f')}")
    return out


#: Differences whose power is given: relative contrasts 5 and 10 %, the angle 2 and 5 degrees.
DELTAS = {"": (0.05, 0.10), "deg": (2.0, 5.0)}


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
        with xr.open_dataset(path) as ds:
            bp = xr.open_dataset(bp_path) if bp_path else None
            try:
                out.setdefault(p, []).append(pile_history(ds.load(), params, heights, bp))
            finally:
                if bp is not None:
                    bp.close()
    return out


def history(values, params, heights, a="wedge", b="layered"):
    """Lines of the pre-registered history statistics: ``a`` against ``b``."""
    h = params["history"]
    primary = primary_names(h)
    names = list(dict.fromkeys(k for piles in values.values() for v in piles for k in v))
    rows = []
    for name in primary + [n for n in names if n not in primary]:
        c = compare([v.get(name, np.nan) for v in values.get(a, [])], [v.get(name, np.nan) for v in values.get(b, [])],
                    deltas=DELTAS[UNITS.get(name, "")])
        if c["a"][3] + c["b"][3] == 0:
            continue
        unit = UNITS.get(name, "")
        scale = 1.0 if unit else 100.0
        d1, d2 = DELTAS[unit]
        need = "n/a" if not np.isfinite(c["n_2se"][d1]) else \
            f"{c['n_2se'][d1]:.0f} / {c['n_2se'][d2]:.0f} ({c['n_power'][d1]:.0f} / {c['n_power'][d2]:.0f})"
        rows.append(f"| {'**' + name + '**' if name in primary else name} | {_history_cell(name, *c['a'][:2])} "
                    f"({c['a'][3]}; {c['z_a']:+.1f}) | {_history_cell(name, *c['b'][:2])} ({c['b'][3]}; {c['z_b']:+.1f}) | "
                    f"{_history_cell(name, c['diff'], c['se'])} | {c['z']:+.1f} | "
                    f"{scale * c['mdd_2se']:.2g} / {scale * c['mdd_power']:.2g} | {need} |")
    k = detection_factor()
    return [
        f"Windows (analysis.history, fixed before the piles they decide): centre |x| <= {100 * h['centre']:g} cm, "
        f"shoulders {100 * h['shoulder_inner']:g}–{100 * h['shoulder_outer']:g} cm; core |x| <= "
        f"{100 * h['shoulder_outer']:g} cm, y <= {100 * h['core_height']:g} cm; flanks "
        f"{100 * h['flank_inner']:g}–{100 * h['flank_outer']:g} cm, y <= {100 * h['flank_height']:g} cm. "
        "Per pile (analysis/history.py), then the mean ± standard error over piles, "
        "(piles; mean in SE from 0), the difference {a} − {b} with its standard error and z = difference / SE.".format(a=a, b=b),
        "",
        f"Power: the minimum detectable difference with these piles, 2 SE (a difference that size stands at "
        f"2 SE) / {k:.2f} SE (seen at two-sided 5 % with 80 % probability), in % (degrees for the angle); "
        "piles per protocol that put a difference of 5 / 10 % (2 / 5 degrees for the angle) at 2 SE "
        "(in brackets: that see it with 80 % probability), from the measured scatter.",
        "",
        f"| statistic | {a} | {b} | {a} − {b} | z | detectable | piles for 5 / 10 % |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"{len(rows)} statistics, each compared three ways ({a} and {b} against 0, {a} − {b}): {3 * len(rows)} "
        f"comparisons. The {len(primary)} in bold are the primary ones, one per question; over them a "
        f"family-wise 5 % asks |z| > {bonferroni_z(len(primary)):.2f} "
        "(Bonferroni) for each difference.",
    ]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ensemble", required=True, help="folder of results/ensemble/{protocol}/")
    ap.add_argument("--protocols", nargs="+", required=True)
    ap.add_argument("--convergence", nargs="+", required=True, help="the convergence files of the piles")
    ap.add_argument("--checks", nargs="+", required=True, help="checks.json of every pile")
    ap.add_argument("--heights", nargs="+", type=float, required=True, help="rows of Fig. 2, m")
    ap.add_argument("--general", nargs="*", default=[], metavar="PROTOCOL=FILE",
                    help="general_moduli.nc of the protocols with the extra probes")
    ap.add_argument("--probes", nargs="*", default=[], metavar="PROTOCOL=FILE",
                    help="the probes.nc of every pile with the extra probes")
    ap.add_argument("--fields", nargs="*", default=[], metavar="PROTOCOL=FILE",
                    help="every pile's fields.nc (the history statistics)")
    ap.add_argument("--base-pressure", nargs="*", default=[], metavar="PROTOCOL=FILE",
                    help="every pile's base_pressure.nc")
    ap.add_argument("--params", default=None, help="the analysis section as JSON (the history windows)")
    args = ap.parse_args(argv)
    params = parse_params(args.params)
    out = ["# Numbers of the reproduction", "",
           "Made by `workflow/scripts/reproduction_numbers.py` from the ensembles (`make reproduction`); "
           "mean ± standard error over piles.", ""]
    for p in args.protocols:
        with xr.open_dataset(f"{args.ensemble}/{p}/fields.nc") as ds:
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
        out += ["## Construction history: centre against shoulders, pre-registered", "",
                *history(history_values(args.fields, args.base_pressure, params, args.heights), params, args.heights),
                ""]
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


if __name__ == "__main__":
    main()
