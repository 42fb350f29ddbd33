"""Standard error of the headline results against compute time as seeds are added (issue #5).

Headline results of one pile, read from the analysis outputs
(docs/formats.md#ensembles) of the configured study:

``bulk_modulus``, ``shear_modulus`` (N/m)
    Isotropic fit (paper Eqs 21–22, :func:`analysis.elastic.fit_all`) to the
    pile's own incremental stress and strain at the RVE nearest to
    ``numerics.ensemble.core``, with ``points`` data points and the fitting
    method ``fit``.
``dip_depth`` (1)
    Depth of the pressure dip under the apex, :func:`dip_depth`:
    ``1 - mean(P(|x| < dip_half_width)) / max(P)`` with ``P`` the pile's
    normal force per unit length on the support (``base_pressure.nc``).
    0 means no dip, 1 no load under the apex.

Compute time of a pile: the CPU time of its pour, relax and probe jobs
(column ``cpu_time`` of their Snakemake benchmark files, all threads; it does
not grow when other processes share the cores, but Snakemake samples it every
0.5 s for 15 s and then every 30 s, so a long job loses up to 30 s at its
end). Their wall-clock time (column ``s``) is kept alongside. For n = 2, 3, ... the first n seeds (config
order) give the ensemble a user would have after n piles: its mean, standard
error ``SE_n = s_n / sqrt(n)`` and cumulative compute time. Extrapolating
with the standard deviation s_N of all N piles, a relative standard error q
needs ``n = ceil((s_N / (q |mean_N|))^2)`` piles (at least 2).

Command line (rules ``numerics_ensemble`` and ``numerics_piles_figures``)::

    python -m analysis.numerics.ensemble_cost data --params JSON --analysis-params TEXT \
        --protocol wedge --fields ... --base-pressure bp.nc --pour-benchmarks ... \
        --relax-benchmarks ... --probe-benchmarks ... [--protocol layered ...] --out ensemble.nc
    python -m analysis.numerics.ensemble_cost figure --data ensemble.nc --out a.png a.pdf

The figure is :func:`analysis.numerics.figures.ensemble_error_figure`.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys

import numpy as np
import xarray as xr

from ..elastic import FITS, POINTS, fit_all
from ..ensemble import nan_mean_sem
from ..netcdf import var, write_dataset
from ..params import resolve_params, settings_from_text
from .command import data_or_figure, module_command
from .figures import ensemble_error_figure
from ..run_times import benchmark_time

log = logging.getLogger("analysis.numerics")

HEADLINES = {
    "bulk_modulus": ("bulk modulus K at the pile's core (isotropic fit)", "N m-1"),
    "shear_modulus": ("shear modulus G at the pile's core (isotropic fit)", "N m-1"),
    "dip_depth": ("depth of the pressure dip, 1 - P(centre) / max P", "1"),
}


def core_moduli(fields: xr.Dataset, core, points: int, fit: str, min_points: int, rtol: float):
    """Bulk and shear modulus of one pile at the RVE nearest to ``core``.

    Parameters
    ----------
    fields : xarray.Dataset
        The pile's fields file (``stress_increment``, ``strain_increment`` on
        the ``(y, x)`` grid).
    core : (float, float)
        Point (x, y) in m.
    points : {1, 5}
        Data points per fit (the RVE, or with its four grid neighbours).
    fit : {"compliance", "modulus", "average"}
    min_points, rtol : int, float
        ``analysis.moduli.min_points`` and ``degenerate_rtol``.

    Returns
    -------
    (float, float)
        K and G in N/m (NaN where the fit is not possible).
    """
    x, y = fields["x"].values, fields["y"].values
    ix, iy = int(np.argmin(np.abs(x - core[0]))), int(np.argmin(np.abs(y - core[1])))
    spacing = max(float(np.max(np.diff(x))) if x.size > 1 else 0.0,
                  float(np.max(np.diff(y))) if y.size > 1 else 0.0)
    if max(abs(x[ix] - core[0]), abs(y[iy] - core[1])) > spacing:
        raise ValueError(f"numerics.ensemble.core = {list(core)}: outside the analysis grid "
                         f"(x in [{x.min():g}, {x.max():g}], y in [{y.min():g}, {y.max():g}] m)")
    sig = fields["stress_increment"].transpose("y", "x", "i", "j").values
    u = fields["strain_increment"].transpose("y", "x", "i", "j").values
    res = fit_all(sig, u, min_points, rtol)
    k = (FITS.index(fit), POINTS.index(points), iy, ix)
    return float(res["bulk_modulus"][k]), float(res["shear_modulus"][k])


def dip_depth(x: np.ndarray, profile: np.ndarray, half_width: float) -> float:
    """``1 - mean(profile[|x| < half_width]) / max(profile)`` of one base pressure profile.

    Raises
    ------
    ValueError
        If no bin centre lies within ``half_width`` of the axis.
    """
    inner = np.abs(x) < half_width
    if not inner.any():
        raise ValueError(f"numerics.ensemble.dip_half_width = {half_width} m: no base pressure bin "
                         f"centre within it (nearest {np.min(np.abs(x)):g} m); make it larger")
    return float(1.0 - np.mean(profile[inner]) / np.max(profile))


def standard_error_curve(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of the first n values, for n = 1 .. len(values).

    NaN values count as missing; the standard error needs two finite values.
    """
    values = np.asarray(values, float)
    out = [nan_mean_sem(values[:n]) for n in range(1, values.size + 1)]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def piles_needed(values: np.ndarray, relative_se: float) -> int:
    """Piles for a relative standard error ``relative_se``, from the scatter of ``values`` (SE ∝ 1/sqrt(n)).

    Returns 0 when fewer than two values are finite or the mean is zero.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size < 2 or np.mean(v) == 0:
        return 0
    exact = (np.std(v, ddof=1) / (relative_se * abs(np.mean(v)))) ** 2
    return max(2, math.ceil(exact * (1 - 1e-12)))  # 8.000000001 from rounding is 8 piles


def check_params(params: dict) -> None:
    """Raise ValueError naming the setting if ``numerics.ensemble`` cannot be evaluated."""
    allowed = {"core": "a point [x, y] in m", "points": f"one of {list(POINTS)}", "fit": f"one of {list(FITS)}",
               "dip_half_width": "a length > 0 in m", "relative_targets": "a list of numbers in (0, 1)"}
    for key, what in allowed.items():
        if key not in params:
            raise ValueError(f"numerics.ensemble.{key} is missing: must be {what}")
    p = params
    bad = {"core": len(p["core"]) != 2, "points": p["points"] not in POINTS, "fit": p["fit"] not in FITS,
           "dip_half_width": not p["dip_half_width"] > 0,
           "relative_targets": not p["relative_targets"] or not all(0 < q < 1 for q in p["relative_targets"])}
    for key, wrong in bad.items():
        if wrong:
            raise ValueError(f"numerics.ensemble.{key} = {p[key]!r}: must be {allowed[key]}")


def ensemble_dataset(protocols: dict, params: dict, analysis_params: dict) -> xr.Dataset:
    """Per-pile headline results, their standard error against n and compute time.

    Parameters
    ----------
    protocols : dict
        Protocol name -> dict with ``seeds`` (list of int), ``fields`` (list
        of datasets, one per seed), ``base_pressure`` (dataset with
        ``normal_force_density_per_seed``), ``compute_time`` and ``wall_time``
        (lists of s, per seed).
    params : dict
        The ``numerics.ensemble`` settings.
    analysis_params : dict
        The ``analysis`` section (for ``moduli.min_points`` and ``degenerate_rtol``).

    Returns
    -------
    xarray.Dataset
        Dimensions ``protocol``, ``n`` (piles in the ensemble, 1..N) and
        ``relative_target``.
    """
    check_params(params)
    mp = resolve_params(analysis_params)["moduli"]
    names = list(protocols)
    n_max = max(len(p["seeds"]) for p in protocols.values())
    shape = (len(names), n_max)
    per = {k: np.full(shape, np.nan) for k in (*HEADLINES, "compute_time", "wall_time")}
    seed = np.full(shape, -1, dtype=np.int64)
    for a, name in enumerate(names):
        p = protocols[name]
        if not (len(p["seeds"]) == len(p["fields"]) == len(p["compute_time"])):
            raise ValueError(f"protocol {name}: {len(p['seeds'])} seeds, {len(p['fields'])} fields files and "
                             f"{len(p['compute_time'])} compute times do not match")
        bp = p["base_pressure"]
        bp_seeds = [str(s) for s in bp["seed"].values]
        for b, (s, fields) in enumerate(zip(p["seeds"], p["fields"])):
            if str(s) not in bp_seeds:
                raise ValueError(f"protocol {name}: seed {s} is not in its base_pressure.nc (seeds {bp_seeds})")
            seed[a, b] = s
            per["bulk_modulus"][a, b], per["shear_modulus"][a, b] = core_moduli(
                fields, params["core"], params["points"], params["fit"], mp["min_points"], mp["degenerate_rtol"])
            profile = bp["normal_force_density_per_seed"].values[bp_seeds.index(str(s))]
            per["dip_depth"][a, b] = dip_depth(bp["x"].values, profile, params["dip_half_width"])
            per["compute_time"][a, b] = p["compute_time"][b]
            per["wall_time"][a, b] = p["wall_time"][b]
    targets = np.array(params["relative_targets"], float)
    ds = xr.Dataset(coords={
        "protocol": var("protocol", np.array(names), "pouring protocol", "1"),
        "n": var("n", np.arange(1, n_max + 1), "piles in the ensemble (the first n seeds)", "1"),
        "relative_target": var("relative_target", targets, "relative standard error aimed at", "1"),
    })
    ds["seed"] = var(("protocol", "n"), seed, "seed of the n-th pile (-1: none)", "1")
    ds["compute_time"] = var(("protocol", "n"), per["compute_time"],
                             "CPU time of the n-th pile's pour, relax and probe jobs", "s")
    ds["wall_time"] = var(("protocol", "n"), per["wall_time"],
                          "wall-clock time of the n-th pile's pour, relax and probe jobs", "s")
    ds["cumulative_compute_time"] = var(("protocol", "n"), np.cumsum(per["compute_time"], axis=1),
                                        "CPU time of the first n piles", "s")
    for name, (long_name, units) in HEADLINES.items():
        mean, se = zip(*(standard_error_curve(per[name][a]) for a in range(len(names))))
        ds[name] = var(("protocol", "n"), per[name], f"{long_name}, of the n-th pile", units)
        ds[f"{name}_mean"] = var(("protocol", "n"), np.array(mean), f"{long_name}, mean of the first n piles",
                                  units)
        ds[f"{name}_se"] = var(("protocol", "n"), np.array(se),
                                f"{long_name}, standard error of the mean of the first n piles", units)
        need = np.array([[piles_needed(per[name][a], q) for q in targets] for a in range(len(names))])
        ds[f"{name}_piles_needed"] = var(("protocol", "relative_target"), need,
                                          f"{name}: piles for the relative standard error, "
                                          "extrapolated as 1/sqrt(n) from all piles (0: undetermined)", "1")
        mean_time = np.nanmean(per["compute_time"], axis=1)
        ds[f"{name}_time_needed"] = var(("protocol", "relative_target"), need * mean_time[:, None],
                                         f"{name}: compute time of those piles at the mean time per pile", "s")
    ds.attrs.update({"core_x": float(params["core"][0]), "core_y": float(params["core"][1]),
                     "points": int(params["points"]), "fit": params["fit"],
                     "dip_half_width": float(params["dip_half_width"])})
    return ds


def _parser():
    ap = argparse.ArgumentParser(prog="python -m analysis.numerics.ensemble_cost", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("data", help="headline results, standard error and compute time (netCDF)")
    p.add_argument("--params", required=True, help="the numerics.ensemble settings as JSON")
    p.add_argument("--analysis-params", default="{}", help="the analysis section as JSON or YAML text")
    p.add_argument("--protocol", action="append", required=True,
                   help="a protocol; the per-seed options after it belong to it")
    for opt in ("--seeds", "--fields", "--pour-benchmarks", "--relax-benchmarks", "--probe-benchmarks"):
        p.add_argument(opt, nargs="+", action="append", required=True)
    p.add_argument("--base-pressure", action="append", required=True)
    p.add_argument("--out", required=True)
    p = sub.add_parser("figure", help="standard error against compute time (PNG/PDF)")
    p.add_argument("--data", required=True)
    p.add_argument("--out", nargs="+", required=True)
    return ap


def _protocol_inputs(args) -> dict:
    """Group the per-protocol options (one occurrence each per --protocol) and read the files."""
    groups = (args.seeds, args.fields, args.pour_benchmarks, args.relax_benchmarks, args.base_pressure)
    if any(len(g) != len(args.protocol) for g in groups):
        raise ValueError(f"{len(args.protocol)} --protocol options: give --seeds, --fields, --pour-benchmarks, "
                         "--relax-benchmarks, --probe-benchmarks and --base-pressure once per protocol")
    out = {}
    for k, name in enumerate(args.protocol):
        seeds = [int(s) for s in args.seeds[k]]
        probes = args.probe_benchmarks[k]
        if len(probes) % len(seeds):
            raise ValueError(f"protocol {name}: {len(probes)} probe benchmarks for {len(seeds)} seeds; "
                             "give the same number of probes for every seed, seed after seed")
        per_seed = len(probes) // len(seeds)
        jobs = [[args.pour_benchmarks[k][b], args.relax_benchmarks[k][b], *probes[b * per_seed:(b + 1) * per_seed]]
                for b in range(len(seeds))]
        cpu = [sum(benchmark_time(j, "cpu_time") for j in files) for files in jobs]
        wall = [sum(benchmark_time(j, "s") for j in files) for files in jobs]
        fields = []
        for path in args.fields[k]:
            log.info("reading %s", path)
            with xr.open_dataset(path) as ds:
                fields.append(ds.load())
        with xr.open_dataset(args.base_pressure[k]) as ds:
            bp = ds.load()
        out[name] = {"seeds": seeds, "fields": fields, "base_pressure": bp, "compute_time": cpu, "wall_time": wall}
    return out


def _data(args) -> None:
    params = json.loads(args.params)
    analysis_params = settings_from_text(args.analysis_params, "--analysis-params")
    check_params(params)
    resolve_params(analysis_params)
    ds = ensemble_dataset(_protocol_inputs(args), params, analysis_params)
    write_dataset(ds, args.out, title="Standard error of the headline results against compute time",
                  params={"numerics": {"ensemble": params}, "analysis": analysis_params},
                  command=module_command(__name__))


def main(argv=None) -> int:
    """Command line; returns the exit status."""
    return data_or_figure(argv, _parser(), _data,
                          lambda ds, outputs: ensemble_error_figure(ds, outputs, tuple(HEADLINES)))


if __name__ == "__main__":
    sys.exit(main())
