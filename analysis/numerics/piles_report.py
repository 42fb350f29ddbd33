"""Markdown tables of the pile and ensemble numerics (``results/numerics/piles.md``).

Reads ``piles.nc`` (:mod:`analysis.numerics.pile_precision`) and ``ensemble.nc``
(:mod:`analysis.numerics.ensemble_cost`) and the configuration's ``model``
section, and writes the error of each observable per (integrator, dt factor)
with the run (CPU) time per pile, the cheapest run whose errors are all within
seed scatter, the standard error of the headline results against the number
of piles and compute time, and the piles a relative precision needs::

    python -m analysis.numerics.piles_report --piles piles.nc --ensemble ensemble.nc \
        --model JSON --out piles.md
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import xarray as xr

from .ensemble_cost import HEADLINES
from ..netcdf import write_text
from ..command_files import PathsError, check_paths
from .pile_precision import OBSERVABLES, RESOLVED


def _pm(value: float, bar: float, resolved: bool = False) -> str:
    if not np.isfinite(value):
        return "–"
    return f"{value:.3g} ± {bar:.2g}" + (" **" if resolved else "")


def consistent_runs(ds: xr.Dataset) -> dict[str, float | None]:
    """Per integrator, the largest dt factor from which on (at it and every smaller one) no error is resolved.

    Returns the factor, or None when even the smallest factor has a resolved error.
    """
    out = {}
    for a, integ in enumerate(ds.integrator.values):
        resolved = np.zeros(ds.sizes["dt_factor"], bool)
        for name in OBSERVABLES:
            resolved |= ds[f"{name}_error"].values[a] > RESOLVED * ds[f"{name}_error_bar"].values[a]
        factors = ds.dt_factor.values  # descending
        ok = None
        for b in range(factors.size - 1, -1, -1):
            if resolved[b]:
                break
            ok = float(factors[b])
        out[str(integ)] = ok
    return out


def piles_section(ds: xr.Dataset, model: dict) -> list[str]:
    """Lines of the error-against-run-time part."""
    names = [n.replace("_", " ") for n in OBSERVABLES]
    units = [ds[f"{n}_error"].attrs["units"] for n in OBSERVABLES]
    head = " | ".join(f"{n} ({u})" if u != "1" else n for n, u in zip(names, units))
    lines = [
        "## Error of pile observables against run time", "",
        f"{ds.attrs['n_particles']}-particle {ds.attrs['protocol']} piles, poured and relaxed with seeds "
        f"{', '.join(str(s) for s in ds.seed.values)} at each time step. Reference: "
        f"{ds.attrs['reference_integrator']} at dt factor {ds.attrs['reference_dt_factor']:g}. Error = "
        "|seed mean − reference seed mean| (base pressure: relative L2 distance of the seed-mean profiles) "
        f"± the seed scatter of that difference; ** marks an error above {RESOLVED:g} times its scatter "
        "(resolved). dt factor 1 is the automatic step (model.dt_safety × stability limit).", "",
        f"| integrator | dt factor | dt (s) | CPU time per pile (s) | wall time per pile (s) | {head} |",
        "|---" * (5 + len(OBSERVABLES)) + "|",
    ]
    ref = (list(ds.integrator.values).index(ds.attrs["reference_integrator"]), int(np.argmin(ds.dt_factor.values)))
    for a, integ in enumerate(ds.integrator.values):
        for b, f in enumerate(ds.dt_factor.values):
            cells = []
            for name in OBSERVABLES:
                e, bar = ds[f"{name}_error"].values[a, b], ds[f"{name}_error_bar"].values[a, b]
                cells.append("reference" if (a, b) == ref else _pm(e, bar, e > RESOLVED * bar))
            lines.append(f"| {integ} | {f:g} | {np.nanmean(ds['dt'].values[a, b]):.3g} | "
                         f"{ds['cpu_time_mean'].values[a, b]:.1f} | {np.mean(ds['wall_time'].values[a, b]):.1f} | "
                         + " | ".join(cells) + " |")
    lines += ["", "Seed means at the reference: " + ", ".join(
        f"{n.replace('_', ' ')} {ds[f'{n}_mean'].values[list(ds.integrator.values).index(ds.attrs['reference_integrator']), -1]:.4g}"
        for n in OBSERVABLES if f"{n}_mean" in ds) + ".", ""]
    orders = [f"{integ}: " + (", ".join(f"{n.replace('_', ' ')} {ds[f'{n}_order'].values[a]:.2g}"
                                         for n in OBSERVABLES if np.isfinite(ds[f"{n}_order"].values[a]))
                              or "none resolved")
              for a, integ in enumerate(ds.integrator.values)]
    lines += ["Order p of error ∝ dt^p from the resolved points (listed where at least two are resolved): "
              + "; ".join(orders) + ".", ""]
    verdict = []
    auto = {}
    for integ, f in consistent_runs(ds).items():
        a = list(ds.integrator.values).index(integ)
        if f is None:
            verdict.append(f"{integ}: an error is resolved even at the smallest dt factor")
            continue
        b = int(np.flatnonzero(ds.dt_factor.values == f)[0])
        auto[integ] = ds["cpu_time_mean"].values[a, b]
        verdict.append(f"{integ}: every dt factor up to {f:g} agrees with the reference within seed scatter "
                       f"({auto[integ]:.1f} s CPU per pile at {f:g})")
    lines += ["Within seed scatter: " + "; ".join(verdict) + "."]
    if auto:
        best = min(auto, key=auto.get)
        lines += [f"Cheapest run that agrees with the reference: {best} ({auto[best]:.1f} s CPU per pile)."]
    dt_rule = ("the automatic step (model.dt_safety = "
               f"{model.get('dt_safety')} × the stability limit)") if model.get("dt") is None else \
        f"the given dt = {model['dt']} s"
    lines += ["", f"The configuration these piles were run from uses model.integrator = "
              f"{model.get('integrator')} with {dt_rule}.", ""]
    return lines


def ensemble_section(ds: xr.Dataset) -> list[str]:
    """Lines of the standard-error-against-compute-time part."""
    lines = ["## Standard error of the headline results against compute time", "",
             f"Bulk and shear modulus: isotropic fit ({ds.attrs['fit']}, points = {ds.attrs['points']}) of each "
             f"pile at the RVE nearest ({ds.attrs['core_x']:g}, {ds.attrs['core_y']:g}) m; dip depth = "
             f"1 − mean base pressure within |x| < {ds.attrs['dip_half_width']:g} m / its maximum. "
             "Mean ± standard error of the first n piles; compute time = CPU time of their pour, relax "
             "and probe jobs (benchmark files).", ""]
    heads = [f"{n.replace('_', ' ')} ({ds[n].attrs['units']})" if ds[n].attrs["units"] != "1"
             else n.replace("_", " ") for n in HEADLINES]
    for a, proto in enumerate(ds.protocol.values):
        lines += [f"**{proto}**", "", "| n | compute time (s) | " + " | ".join(heads) + " |",
                  "|---" * (2 + len(HEADLINES)) + "|"]
        for k, n in enumerate(ds.n.values):
            if ds["seed"].values[a, k] < 0:
                continue
            cells = []
            for name in HEADLINES:
                m, se = ds[f"{name}_mean"].values[a, k], ds[f"{name}_se"].values[a, k]
                rel = f" ({100 * se / abs(m):.1f} %)" if np.isfinite(se) and m != 0 else ""
                cells.append(f"{m:.4g} ± {se:.2g}{rel}" if np.isfinite(se) else f"{m:.4g}")
            lines.append(f"| {n} | {ds['cumulative_compute_time'].values[a, k]:.0f} | " + " | ".join(cells) + " |")
        lines += ["", "Piles needed for a relative standard error (extrapolated as 1/√n from all piles; "
                  "compute time at the mean time per pile):", "",
                  "| relative SE | " + " | ".join(heads) + " |", "|---" * (1 + len(HEADLINES)) + "|"]
        for q, target in enumerate(ds.relative_target.values):
            cells = []
            for name in HEADLINES:
                need = int(ds[f"{name}_piles_needed"].values[a, q])
                cells.append(f"{need} ({ds[f'{name}_time_needed'].values[a, q] / 3600:.2g} h)" if need else "–")
            lines.append(f"| {100 * target:g} % | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def report(piles: xr.Dataset, ensemble: xr.Dataset, model: dict) -> str:
    """The whole markdown text."""
    return "\n".join(["# Numerics of whole piles", "", *piles_section(piles, model), *ensemble_section(ensemble)])


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m analysis.numerics.piles_report", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--piles", required=True)
    ap.add_argument("--ensemble", required=True)
    ap.add_argument("--model", default="{}", help="the configuration's model section as JSON")
    ap.add_argument("--out", required=True)
    return ap


def main(argv=None) -> int:
    """Command line; returns the exit status (2: an output that is an input or another output)."""
    ap = _parser()
    args = ap.parse_args(argv)
    try:
        check_paths(args, ap.prog)
    except PathsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with xr.open_dataset(args.piles) as p, xr.open_dataset(args.ensemble) as e:
        text = report(p.load(), e.load(), json.loads(args.model))
    write_text(text, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
