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
* **Fig. 2, vertical strain dip**: at each height, ``u_yy`` at the centre
  (mean of the columns with ``|x| <= 1.5`` grid spacings) and the largest
  ``|u_yy|`` off the centre, with its x.
* **Base pressure dip**: per pile, the mean normal force density under the
  centre (``|x| < 6 cm``) over its mean in the ring ``6 <= |x| < 24 cm``
  (below 1: a dip), mean and standard error over piles; bins of 2 cm alone
  scatter by tens of percent with the force chains.
* **Base pressure**: the normal force density at the centre (two bins next
  to x = 0) and its maximum, with the x of the maximum.
* **Fig. 3, fabric**: range of the trace and of the deviatoric fraction over
  the valid RVEs; mean orientation of the major axis over ``x < -10 cm`` and
  ``x > 10 cm`` in the two lowest rows; mean ``|stress_fabric_angle|`` there.
* **Fig. 4, moduli**: median over valid RVEs of Young's modulus ``E`` of the
  isotropic fit (m = 1) and of ``E_av`` of the cubic fit (m = 5), both the
  average of the two fitting methods.
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

from analysis.probes import reversibility  # noqa: E402


def _pm(v, s, spec=".3g"):
    s_txt = "n/a" if not np.isfinite(s) else format(s, ".2g")
    return f"{format(v, spec)} ± {s_txt}"


def _row_index(ds, h):
    return int(np.argmin(np.abs(ds["y"].values - h)))


def strain_dip(ds, heights):
    """Lines of the Fig. 2 measure for one protocol's ensemble fields."""
    x = ds["x"].values
    dx = float(np.median(np.diff(x)))
    u = ds["strain_increment"].sel(i="y", j="y").values
    su = ds["strain_increment_sem"].sel(i="y", j="y").values
    out = []
    for h in heights:
        k = _row_index(ds, h)
        row, srow = u[k], su[k]
        if not np.isfinite(row).any():
            continue
        centre = np.abs(x) <= 1.5 * dx
        c = float(np.nanmean(row[centre])) if np.isfinite(row[centre]).any() else np.nan
        ok = np.isfinite(srow[centre])
        sc = float(np.sqrt(np.sum(srow[centre][ok] ** 2)) / ok.sum()) if ok.any() else np.nan
        off = np.where(~centre & np.isfinite(row), np.abs(row), -np.inf)
        j = int(np.argmax(off))
        out.append(f"| {100 * ds['y'].values[k]:.1f} | {_pm(c, sc)} | {_pm(float(row[j]), float(srow[j]))} "
                   f"at x = {100 * x[j]:.0f} cm |")
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


def base_pressure_dip(bp, centre=0.06, ring=0.24):
    """Per-pile ratio of the centre's mean normal force density to the ring's, as mean ± SE."""
    x = np.abs(bp["x"].values)
    per_seed = bp["normal_force_density_per_seed"].values
    ratio = per_seed[:, x < centre].mean(axis=1) / per_seed[:, (x >= centre) & (x < ring)].mean(axis=1)
    se = float(np.std(ratio, ddof=1) / np.sqrt(ratio.size)) if ratio.size > 1 else float("nan")
    return (f"centre (|x| < {100 * centre:.0f} cm) / ring ({100 * centre:.0f}–{100 * ring:.0f} cm) "
            f"{_pm(float(ratio.mean()), se)} (per pile: {', '.join(f'{r:.3f}' for r in ratio)})")


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


def moduli(md):
    e1 = md["youngs_modulus"].sel(fit="average", points=1).values
    e5 = md["E_av"].sel(fit="average", points=5).values
    return (f"E (isotropic, m = 1): median {np.nanmedian(e1):.3g} N/m over {np.isfinite(e1).sum()} RVEs; "
            f"E_av (cubic, m = 5): median {np.nanmedian(e5):.3g} N/m over {np.isfinite(e5).sum()} RVEs")


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
    args = ap.parse_args(argv)
    out = ["# Numbers of the reproduction", "",
           "Made by `workflow/scripts/reproduction_numbers.py` from the ensembles (`make reproduction`); "
           "mean ± standard error over piles.", ""]
    for p in args.protocols:
        with xr.open_dataset(f"{args.ensemble}/{p}/fields.nc") as ds:
            n = int(ds.attrs.get("n_seeds", 0))
            out += [f"## {p} ({_piles(n)})", "", f"Slips: {slips(ds)}.", "", "Vertical strain increment u_yy (Fig. 2):", "",
                    "| y (cm) | centre | largest off the centre |", "|---|---|---|", *strain_dip(ds, args.heights),
                    "", "Fabric (Fig. 3): " + "; ".join(fabric(ds)) + "."]
        with xr.open_dataset(f"{args.ensemble}/{p}/base_pressure.nc") as bp:
            out += ["", f"Base pressure: {base_pressure(bp)}; {base_pressure_dip(bp)}."]
        with xr.open_dataset(f"{args.ensemble}/{p}/moduli.nc") as md:
            out += ["", f"Moduli (Fig. 4): {moduli(md)}."]
        with xr.open_dataset(f"{args.ensemble}/{p}/invariants.nc") as inv:
            out += ["", "tr Δσ against tr ε (Fig. 5): " + "; ".join(invariants(inv)) + ".", ""]
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
