"""Error of macroscopic pile observables against run time (issue #5).

A small pile is chaotic: two time steps give different grain trajectories
from the first collision on, so pointwise errors mean nothing. What a time
step can change systematically is the *statistics* of the relaxed pile. The
piles of one (integrator, dt factor) are poured and relaxed with several
seeds; each observable is averaged over the seeds, and its error is the
distance of that mean from the mean of the reference run (the reference
integrator at the smallest dt factor), with the combined standard error of
both means as the level of seed-to-seed scatter below which an integration
error cannot be resolved.

Observables of one relaxed pile (:func:`pile_observables`):

``angle_of_repose`` (deg)
    Mean of the two flank angles of the pile's summary line
    (``python -m sim summary``: ``flank_left_deg``, ``flank_right_deg``).
``solid_fraction`` (1)
    Polygon area inside a strip of square windows along the base of the
    core, centred on the pouring axis (:func:`solid_fraction_strip`).
``mean_coordination`` (1)
    Particle–particle contacts per particle, 2 N_c / N (the summary line's
    ``mean_coordination``).
``base_pressure`` (N/m, a profile)
    Normal force per unit length on the support in x bins
    (:func:`analysis.base_pressure.support_force_density`).

Errors (:func:`scalar_error`, :func:`profile_error`): for a scalar,
``|mean - mean_ref|`` with error bar ``sqrt(SE² + SE_ref²)``; for the
profile, the relative L2 norm ``||P - P_ref|| / ||P_ref||`` of the
seed-mean profiles, with the noise floor ``sqrt(Σ_x (SE(x)² +
SE_ref(x)²)) / ||P_ref||`` (the norm that seed scatter alone gives). An error
is *resolved* when it exceeds twice its error bar.

Run time of a pile: the CPU time (user + system, from bash ``times``) of its
pour and relax jobs, which includes a fixed start-up cost per job (imports,
loading the kernels); their wall time (Snakemake benchmark files) is kept
too but grows when other processes share the cores (:mod:`analysis.run_times`).

Command line (run by the rule ``numerics_piles_data``; ``figure`` by
``numerics_piles_figures``)::

    python -m analysis.numerics.pile_precision data --params JSON --states ... --summaries ... \
        --pour-benchmarks ... --relax-benchmarks ... --pour-cpu ... --relax-cpu ... --out piles.nc
    python -m analysis.numerics.pile_precision figure --data piles.nc --out a.png a.pdf

The figure is :func:`analysis.numerics.figures.pile_error_figure`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

import numpy as np
import xarray as xr

from ..base_pressure import support_force_density
from ..ensemble import nan_mean_sem
from ..netcdf import var, write_dataset
from ..solid_fraction import solid_fraction
from ..states import State, load_state
from .command import data_or_figure, module_command
from .figures import pile_error_figure
from ..run_times import benchmark_time, children_cpu_time

log = logging.getLogger("analysis.numerics")

SCALARS = {
    "angle_of_repose": ("angle of repose (mean slope of both flanks)", "degree"),
    "solid_fraction": ("solid fraction in a strip of square windows at the base of the core", "1"),
    "mean_coordination": ("particle-particle contacts per particle", "1"),
}
PROFILE = ("base_pressure", "normal force per unit length on the support", "N m-1")
OBSERVABLES = (*SCALARS, PROFILE[0])
# Raster pixel of the solid fraction, m: 1/14 of a mean particle diameter.
SOLID_FRACTION_PIXEL = 5e-4
# An error is resolved when it exceeds this many error bars.
RESOLVED = 2.0


def profile_edges(half_width: float, bin_width: float) -> np.ndarray:
    """Bin edges of the base pressure profile: symmetric about x = 0, ``bin_width`` apart."""
    n = int(np.ceil(half_width / bin_width - 1e-9))
    return bin_width * np.arange(-n, n + 1)


def solid_fraction_strip(state: State, side: float, height: float, half_width: float) -> float:
    """Solid fraction of a strip along the base of the core.

    Square windows of side ``side`` centred at ``(k side, height)`` for every
    integer k with ``|k side| <= half_width``
    (:func:`analysis.solid_fraction.solid_fraction`); their mean, which is
    the solid fraction of the strip they tile.
    """
    k = int(np.floor(half_width / side + 1e-9))
    centres = np.column_stack([side * np.arange(-k, k + 1), np.full(2 * k + 1, height)])
    return float(np.mean(solid_fraction(state, centres, "square", side, SOLID_FRACTION_PIXEL)))


def pile_observables(state: State, summary: dict, params: dict) -> dict:
    """The observables of one relaxed pile.

    Parameters
    ----------
    state : analysis.states.State
    summary : dict
        The pile's line of ``python -m sim summary`` (``flank_left_deg``,
        ``flank_right_deg``, ``mean_coordination``).
    params : dict
        The ``numerics.piles`` settings (``bin_width``, ``half_width``,
        ``solid_fraction_window``, ``solid_fraction_height``,
        ``solid_fraction_half_width``).

    Returns
    -------
    dict
        Scalars ``angle_of_repose``, ``solid_fraction``,
        ``mean_coordination`` and the profile ``base_pressure`` (array).
    """
    return {
        "angle_of_repose": float(np.mean([summary["flank_left_deg"], summary["flank_right_deg"]])),
        "solid_fraction": solid_fraction_strip(state, params["solid_fraction_window"],
                                               params["solid_fraction_height"], params["solid_fraction_half_width"]),
        "mean_coordination": float(summary["mean_coordination"]),
        "base_pressure": support_force_density(
            state, profile_edges(params["half_width"], params["bin_width"]))[0],
    }


def scalar_error(values: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Error of a seed mean against the reference's seed mean, and its error bar.

    Parameters
    ----------
    values, reference : numpy.ndarray
        Per-seed values of the run and of the reference (NaN = missing).

    Returns
    -------
    (float, float)
        ``|mean - mean_ref|`` and ``sqrt(SE² + SE_ref²)`` (standard errors
        over seeds; NaN with fewer than two finite seeds on either side).
    """
    m, s, _ = nan_mean_sem(values)
    mr, sr, _ = nan_mean_sem(reference)
    return float(abs(m - mr)), float(np.hypot(s, sr))


def profile_error(profiles: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Relative L2 distance of two seed-mean profiles, and its noise floor.

    Parameters
    ----------
    profiles, reference : numpy.ndarray
        ``(seed, bin)`` profiles of the run and of the reference.

    Returns
    -------
    (float, float)
        ``||P - P_ref|| / ||P_ref||`` of the seed means, and
        ``sqrt(Σ (SE² + SE_ref²)) / ||P_ref||`` with SE the standard errors
        over seeds per bin: the expected distance from seed scatter alone.
    """
    m, s, _ = nan_mean_sem(profiles)
    mr, sr, _ = nan_mean_sem(reference)
    scale = float(np.linalg.norm(mr))
    if not scale > 0:
        raise ValueError("the reference base pressure profile is zero: no support contacts "
                         "in numerics.piles [-half_width, half_width]")
    return float(np.linalg.norm(m - mr)) / scale, float(np.sqrt(np.sum(s ** 2 + sr ** 2))) / scale


def convergence_order(dt: np.ndarray, error: np.ndarray, error_bar: np.ndarray) -> float:
    """Order p of ``error ∝ dt^p`` from the resolved points (least squares in log-log).

    Points whose error does not exceed ``RESOLVED`` error bars are left out
    (they measure seed scatter, not the time step). NaN with fewer than two
    resolved points.
    """
    dt, error, error_bar = (np.asarray(a, float) for a in (dt, error, error_bar))
    ok = np.isfinite(error) & (error > RESOLVED * error_bar) & (error > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(dt[ok]), np.log(error[ok]), 1)[0])


def check_params(params: dict) -> None:
    """Raise ValueError naming the setting if ``numerics.piles`` cannot be evaluated."""
    p = params
    for key in ("integrators", "dt_factors", "seeds", "reference_integrator", "bin_width", "half_width",
                "solid_fraction_window", "solid_fraction_height", "solid_fraction_half_width"):
        if key not in p:
            raise ValueError(f"numerics.piles.{key} is missing")
    if p["reference_integrator"] not in p["integrators"]:
        raise ValueError(f"numerics.piles.reference_integrator = {p['reference_integrator']!r}: must be one "
                         f"of numerics.piles.integrators {p['integrators']}")
    if len(p["seeds"]) < 2:
        raise ValueError(f"numerics.piles.seeds = {p['seeds']}: need at least 2 seeds for standard errors")
    if len(p["dt_factors"]) < 2 or not all(0 < f <= 1 for f in p["dt_factors"]):
        raise ValueError(f"numerics.piles.dt_factors = {p['dt_factors']}: need at least 2 factors, "
                         "each in (0, 1]")


def runs(params: dict) -> list[tuple[str, float, int]]:
    """(integrator, dt factor, seed) of every pile, in the order the workflow lists them."""
    return [(i, float(f), int(s)) for i in params["integrators"] for f in params["dt_factors"]
            for s in params["seeds"]]


def piles_dataset(states: list[State], summaries: list[dict], wall: list[float], cpu: list[float],
                  params: dict) -> xr.Dataset:
    """Per-pile observables and run times, and the errors against the reference.

    Parameters
    ----------
    states : list of State
        Relaxed piles, in the order of :func:`runs`.
    summaries : list of dict
        Their summary lines (``python -m sim summary``), same order.
    wall, cpu : list of float
        Wall-clock and CPU time of each pile's pour and relax jobs together, s.
    params : dict
        The ``numerics.piles`` settings.

    Returns
    -------
    xarray.Dataset
        Dimensions ``integrator``, ``dt_factor``, ``seed``, ``x``.
    """
    check_params(params)
    order = runs(params)
    if not (len(states) == len(summaries) == len(wall) == len(cpu) == len(order)):
        raise ValueError(f"{len(order)} piles expected (integrators x dt_factors x seeds), got "
                         f"{len(states)} states, {len(summaries)} summaries, {len(wall)} wall and "
                         f"{len(cpu)} CPU times")
    integrators = list(params["integrators"])
    factors = np.array(sorted({f for _, f, _ in order}, reverse=True))
    seeds = np.array(params["seeds"], dtype=np.int64)
    edges = profile_edges(params["half_width"], params["bin_width"])
    shape = (len(integrators), factors.size, seeds.size)
    per = {k: np.full(shape, np.nan) for k in (*SCALARS, "dt", "wall_time", "cpu_time", "steps", "sim_time")}
    profile = np.full(shape + (edges.size - 1,), np.nan)
    for state, summary, t_wall, t_cpu, (integ, f, seed) in zip(states, summaries, wall, cpu, order):
        attrs = state.attrs
        if str(attrs.get("integrator")) != integ or int(attrs.get("seed", -1)) != seed:
            raise ValueError(f"{state.path}: integrator {attrs.get('integrator')!r}, seed "
                             f"{attrs.get('seed')} where {integ!r}, seed {seed} was expected")
        k = (integrators.index(integ), int(np.flatnonzero(factors == f)[0]), int(np.flatnonzero(seeds == seed)[0]))
        obs = pile_observables(state, summary, params)
        for name in SCALARS:
            per[name][k] = obs[name]
        profile[k] = obs["base_pressure"]
        per["dt"][k] = float(attrs["dt"])
        per["steps"][k] = float(attrs["step"])
        per["sim_time"][k] = float(attrs["time"])
        per["wall_time"][k] = t_wall
        per["cpu_time"][k] = t_cpu
    ref = (integrators.index(params["reference_integrator"]), int(np.argmin(factors)))
    err = {name: np.full(shape[:2], np.nan) for name in OBSERVABLES}
    bar = {name: np.full(shape[:2], np.nan) for name in OBSERVABLES}
    for a in range(len(integrators)):
        for b in range(factors.size):
            for name in SCALARS:
                err[name][a, b], bar[name][a, b] = scalar_error(per[name][a, b], per[name][ref])
            err[PROFILE[0]][a, b], bar[PROFILE[0]][a, b] = profile_error(profile[a, b], profile[ref])
    ds = xr.Dataset(coords={
        "integrator": var("integrator", np.array(integrators), "time integrator", "1"),
        "dt_factor": var("dt_factor", factors, "time step as a fraction of the integrator's automatic step", "1"),
        "seed": var("seed", seeds, "seed of the pile", "1"),
        "x": var("x", 0.5 * (edges[:-1] + edges[1:]), "centre of the x bin on the support "
                  "(0 at the pouring axis)", "m", axis="X"),
    })
    dims3 = ("integrator", "dt_factor", "seed")
    dims2 = ("integrator", "dt_factor")
    for name, (long_name, units) in SCALARS.items():
        ds[name] = var(dims3, per[name], long_name, units)
        ds[f"{name}_mean"] = var(dims2, nan_mean_sem(per[name].transpose(2, 0, 1))[0],
                                  f"{long_name}, mean over seeds", units)
    ds[PROFILE[0]] = var(dims3 + ("x",), profile, PROFILE[1], PROFILE[2])
    ds["dt"] = var(dims3, per["dt"], "time step", "s")
    ds["steps"] = var(dims3, per["steps"], "time steps of pouring and relaxing", "1")
    ds["sim_time"] = var(dims3, per["sim_time"], "simulated time of pouring and relaxing", "s")
    ds["wall_time"] = var(dims3, per["wall_time"], "wall-clock time of the pour and relax jobs", "s")
    ds["cpu_time"] = var(dims3, per["cpu_time"], "CPU time (user + system) of the pour and relax jobs", "s")
    ds["cpu_time_mean"] = var(dims2, per["cpu_time"].mean(axis=2),
                               "CPU time per pile (pour and relax), mean over seeds", "s")
    for name in OBSERVABLES:
        units = "1" if name == PROFILE[0] else SCALARS[name][1]
        what = ("relative L2 distance of the seed-mean profile from the reference's" if name == PROFILE[0]
                else "absolute difference of the seed mean from the reference's")
        ds[f"{name}_error"] = var(dims2, err[name], f"{name}: {what}", units)
        ds[f"{name}_error_bar"] = var(dims2, bar[name], f"{name}: level of seed scatter of the error "
                                       "(combined standard error of both means)", units)
        ds[f"{name}_order"] = var("integrator", np.array([
            convergence_order(factors, err[name][a], bar[name][a]) for a in range(len(integrators))]),
            f"{name}: order p of error ~ dt^p from the resolved points (NaN: fewer than two)", "1")
    ds.attrs.update({
        "reference_integrator": params["reference_integrator"],
        "reference_dt_factor": float(factors[ref[1]]),
        "resolved_factor": RESOLVED,
        "n_particles": int(states[0].n_particles),
        "protocol": str(states[0].attrs.get("protocol", "")),
    })
    return ds


def _parser():
    ap = argparse.ArgumentParser(prog="python -m analysis.numerics.pile_precision", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("data", help="observables and errors of the small piles (netCDF)")
    p.add_argument("--params", required=True, help="the numerics.piles settings as JSON")
    p.add_argument("--states", nargs="+", required=True, help="relaxed state files, integrators x dt "
                   "factors x seeds in config order")
    p.add_argument("--summaries", nargs="+", required=True, help="their summary lines (python -m sim "
                   "summary, one JSON line per file), same order")
    for step in ("pour", "relax"):
        p.add_argument(f"--{step}-benchmarks", nargs="+", required=True,
                       help=f"Snakemake benchmark files of the {step} jobs (wall time), same order")
        p.add_argument(f"--{step}-cpu", nargs="+", required=True,
                       help=f"output of bash 'times' after each {step} job (CPU time), same order")
    p.add_argument("--out", required=True)
    p = sub.add_parser("figure", help="error against wall time (PNG/PDF)")
    p.add_argument("--data", required=True)
    p.add_argument("--out", nargs="+", required=True)
    return ap


def _data(args) -> None:
    params = json.loads(args.params)
    check_params(params)
    states = []
    for k, path in enumerate(args.states):
        log.info("reading %s (%d of %d)", path, k + 1, len(args.states))
        states.append(load_state(path))
    summaries = []
    for path in args.summaries:
        with open(path, encoding="utf-8") as fh:
            summaries.append(json.loads(fh.readline()))
    wall = [benchmark_time(a) + benchmark_time(b) for a, b in zip(args.pour_benchmarks, args.relax_benchmarks)]
    cpu = [children_cpu_time(a) + children_cpu_time(b) for a, b in zip(args.pour_cpu, args.relax_cpu)]
    ds = piles_dataset(states, summaries, wall, cpu, params)
    write_dataset(ds, args.out, title="Error of pile observables against run time",
                  params={"numerics": {"piles": params}}, command=module_command(__name__))


def main(argv=None) -> int:
    """Command line; returns the exit status."""
    return data_or_figure(argv, _parser(), _data,
                          lambda ds, outputs: pile_error_figure(ds, outputs, OBSERVABLES))


if __name__ == "__main__":
    sys.exit(main())
