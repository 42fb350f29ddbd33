"""Stress and strain invariants (paper Sect. 6, Fig. 5).

The paper plots −tr(Δσ) against −tr(u) for the loading step from reduced to
full gravity (both positive: compression). Our increments are defined the
other way round (reduced − relaxed, docs/formats.md), so the paper's quantities
are exactly ``trace_stress_increment = tr(stress_increment)`` and
``trace_strain_increment = tr(strain_increment)`` of the ensemble fields.

Local slope: RVEs are binned by depth below the free surface
(``analysis.invariants.depth_bin``); per bin we give the means (with
standard errors over the RVEs of the bin), the secant bulk modulus
``K_sec = <tr Δσ> / (2 <tr u>)`` and the differential bulk modulus
``K_diff = ½ d<tr Δσ>/d<tr u>`` along the depth sequence (central
differences of the bin means, ``numpy.gradient`` with respect to depth), the
slope of the curve of Fig. 5 traced from the surface downwards. In 2D
``tr σ = 2K tr u`` (Eq. 22), hence the factor ½.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import xarray as xr

from .ensemble import leave_out_slips
from .netcdf import var


def invariants_dataset(ensemble: xr.Dataset, params: dict[str, Any]) -> xr.Dataset:
    """``invariants.nc``: traces on the grid and their depth-binned statistics."""
    ts = ensemble["stress_increment"].sel(i="x", j="x").values + ensemble["stress_increment"].sel(i="y", j="y").values
    tu = ensemble["strain_increment"].sel(i="x", j="x").values + ensemble["strain_increment"].sel(i="y", j="y").values
    depth = ensemble["depth"].values
    ok = np.isfinite(ts) & np.isfinite(tu) & np.isfinite(depth)
    w = params["invariants"]["depth_bin"]
    dmax = float(depth[ok].max()) if ok.any() else w
    edges = np.arange(0.0, dmax + w, w)
    if edges.size < 2:
        edges = np.array([0.0, w])
    centres = 0.5 * (edges[:-1] + edges[1:])
    nb = centres.size
    b = np.clip(np.digitize(depth[ok], edges) - 1, 0, nb - 1)
    inb = (depth[ok] >= 0)
    b, tsv, tuv = b[inb], ts[ok][inb], tu[ok][inb]
    cnt = np.bincount(b, minlength=nb)

    def stats(v):
        s = np.bincount(b, weights=v, minlength=nb)
        s2 = np.bincount(b, weights=v * v, minlength=nb)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = s / cnt
            varc = (s2 - cnt * mean ** 2) / (cnt - 1)
            sem = np.sqrt(np.maximum(varc, 0) / cnt)
        return np.where(cnt > 0, mean, np.nan), np.where(cnt > 1, sem, np.nan)

    ms, ss = stats(tsv)
    mu, su = stats(tuv)
    with np.errstate(invalid="ignore", divide="ignore"):
        ksec = ms / (2 * mu)
    ksec = np.where(np.isfinite(ksec), ksec, np.nan)
    kdiff = np.full(nb, np.nan)
    good = np.flatnonzero(np.isfinite(ms) & np.isfinite(mu))
    if good.size >= 2:
        with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            dts = np.gradient(ms[good], centres[good])
            dtu = np.gradient(mu[good], centres[good])
            k = 0.5 * dts / dtu
        kdiff[good] = np.where(np.isfinite(k), k, np.nan)
    ds = xr.Dataset(coords={
        "y": ensemble["y"].variable, "x": ensemble["x"].variable,
        "depth_bin": var("depth_bin", centres, "centre of the depth bin below the free surface", "m"),
    })
    ds["trace_stress_increment"] = var(("y", "x"), ts, "tr(stress_increment) = -tr(Delta sigma) of the loading "
                                       "step reduced -> full gravity (paper Fig. 5 ordinate)", "N m-1")
    ds["trace_strain_increment"] = var(("y", "x"), tu, "tr(strain_increment) = -tr(u) of the loading step "
                                       "(paper Fig. 5 abscissa)", "1")
    ds["depth"] = var(("y", "x"), depth, "depth of the RVE centre below the free surface", "m")
    ds["depth_bin_bounds"] = var(("depth_bin", "nv"), np.column_stack([edges[:-1], edges[1:]]),
                                 "depth bin edges", "m")
    ds["n_rve"] = var("depth_bin", cnt.astype(np.int32), "RVEs in the depth bin", "1")
    ds["mean_trace_stress_increment"] = var("depth_bin", ms, "bin mean of trace_stress_increment", "N m-1")
    ds["mean_trace_stress_increment_sem"] = var("depth_bin", ss, "standard error over the RVEs of the bin", "N m-1")
    ds["mean_trace_strain_increment"] = var("depth_bin", mu, "bin mean of trace_strain_increment", "1")
    ds["mean_trace_strain_increment_sem"] = var("depth_bin", su, "standard error over the RVEs of the bin", "1")
    ds["secant_bulk_modulus"] = var("depth_bin", ksec, "<tr dsigma>/(2 <tr u>) per depth bin", "N m-1")
    ds["differential_bulk_modulus"] = var("depth_bin", kdiff, "0.5 d<tr dsigma>/d<tr u> along depth "
                                          "(local slope of Fig. 5 over 2)", "N m-1")
    for a in ("rve_shape", "rve_size", "n_seeds", "protocol"):
        if a in ensemble.attrs:
            ds.attrs[a] = ensemble.attrs[a]
    return ds


def secant_deciles(ts: np.ndarray, te: np.ndarray, parts: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """The secant of ``tr Δσ`` over ``tr ε`` (2K in two dimensions, Eq. 22) in each of `parts`
    quantile bins of ``tr ε``: the bin's mean ``tr Δσ`` over its mean ``tr ε``.

    Parameters
    ----------
    ts, te : ndarray
        ``tr Δσ`` and ``tr ε`` of the same RVEs (NaN pairs left out).
    parts : int
        The bins, of equal counts.

    Returns
    -------
    secants, strains : ndarray
        The secants and the bins' mean strains (the latter bounds the
        conditioning: a bin whose mean strain neared 0 would blow up); NaN
        with fewer RVEs than bins.
    """
    ok = np.isfinite(ts) & np.isfinite(te)
    ts, te = ts[ok], te[ok]
    if te.size < parts:
        return np.full(parts, np.nan), np.full(parts, np.nan)
    bins = np.array_split(np.argsort(te, kind="stable"), parts)
    return np.array([ts[b].mean() / te[b].mean() for b in bins]), np.array([te[b].mean() for b in bins])


def pile_secants(fields: xr.Dataset, params: dict[str, Any]) -> tuple[float, float, float]:
    """One pile's secant 2K (:func:`secant_deciles`) in its lowest and highest strain decile (valid
    RVEs, slips left out), and the lowest decile's mean tr ε (its conditioning)."""
    (fields,), _ = leave_out_slips([fields], params["ensemble"]["slip_strain_ratio"])
    ok = fields["mask_reason"].transpose("y", "x").values == 0
    tr = lambda v: (v.sel(i="x", j="x") + v.sel(i="y", j="y")).transpose("y", "x").values  # noqa: E731
    sec, strain = secant_deciles(np.where(ok, tr(fields["stress_increment"]), np.nan),
                                 np.where(ok, tr(fields["strain_increment"]), np.nan))
    return sec[0], sec[-1], strain[0]


def trace_line_r2(ts: np.ndarray, te: np.ndarray) -> tuple[float, int]:
    """``R²`` of a straight line through ``tr Δσ`` against ``tr ε`` (Fig. 5) over the RVEs where
    both are finite, and their number; NaN below 3 RVEs."""
    ok = np.isfinite(ts) & np.isfinite(te)
    if ok.sum() < 3:
        return np.nan, int(ok.sum())
    r = np.corrcoef(te[ok], ts[ok])[0, 1]
    return r * r, int(ok.sum())
