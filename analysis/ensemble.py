"""Seed averages of per-pile fields (CONTRACT.md section 3, ``fields.nc``).

Every numeric field of the per-pile files is averaged over seeds with
``nanmean`` (a pile whose RVE is masked at a point does not enter that
point); ``<name>_count`` holds the number of seeds that did, ``<name>_sem``
the standard error ``std(ddof=1)/sqrt(count)`` (NaN where count < 2). The
bit-mask variables (``mask_reason``, ``strain_flag``) are not averaged; their
role is taken by the counts.

Derived quantities (fabric trace, deviatoric fraction, orientations) are
recomputed from the **mean tensors** (the orientation of an averaged tensor,
not an average of angles); their ``_sem`` comes from the per-seed values
(for angles, the per-seed deviations from the ensemble angle folded into
(−90, 90], since axes have no sign).

All piles share one grid in absolute coordinates (``analysis.grid``), so
piles of different widths need no interpolation; files with different grids
or RVEs are refused.
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from .errors import InputError
from .fields import ANGLES, DERIVED, derived_fields
from .netcdf import var
from .orientation import fold_axis_angle

FLAG_VARS = ("mask_reason", "strain_flag")


def nan_mean_sem(stack: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, standard error and count of finite values along axis 0."""
    stack = np.asarray(stack, dtype=float)
    finite = np.isfinite(stack)
    count = finite.sum(axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        clean = np.where(finite, stack, np.nan)
        mean = np.nanmean(clean, axis=0)
        std = np.nanstd(clean, axis=0, ddof=1)
    mean = np.where(count > 0, mean, np.nan)
    sem = np.where(count >= 2, std / np.sqrt(np.maximum(count, 1)), np.nan)
    return mean, sem, count


def _check_compatible(datasets: list[xr.Dataset], names: list[str]) -> None:
    ref = datasets[0]
    for ds, name in zip(datasets[1:], names[1:]):
        for c in ("x", "y"):
            if ds[c].shape != ref[c].shape or not np.allclose(ds[c].values, ref[c].values, rtol=0, atol=1e-9):
                raise InputError(f"{name}: its {c} grid differs from {names[0]}; all piles of an ensemble must be "
                                 "analysed on the same grid (analysis.grid)")
        for a in ("rve_shape", "rve_size"):
            if ds.attrs.get(a) != ref.attrs.get(a):
                raise InputError(f"{name}: attribute {a} = {ds.attrs.get(a)!r} differs from {names[0]} "
                                 f"({ref.attrs.get(a)!r})")
        missing = set(ref.data_vars) ^ set(ds.data_vars)
        if missing:
            raise InputError(f"{name}: variables {sorted(missing)} are not in every file of the ensemble")


def ensemble_fields(datasets: list[xr.Dataset], names: list[str] | None = None) -> xr.Dataset:
    """Average per-pile fields datasets over seeds (see module docstring)."""
    if not datasets:
        raise InputError("an ensemble needs at least one fields file")
    names = names or [f"file {k}" for k in range(len(datasets))]
    _check_compatible(datasets, names)
    ref = datasets[0]
    out = xr.Dataset(coords={k: ref[k].variable for k in ref.coords})
    averaged = [v for v in ref.data_vars if v not in FLAG_VARS and v not in DERIVED
                and ref[v].dtype.kind in "fiu"]
    for name in averaged:
        stack = np.stack([ds[name].values for ds in datasets])
        mean, sem, count = nan_mean_sem(stack)
        attrs = {k: v for k, v in ref[name].attrs.items() if k not in ("flag_masks", "flag_meanings")}
        out[name] = xr.Variable(ref[name].dims, mean, {**attrs, "cell_methods": "seed: mean"})
        out[f"{name}_sem"] = var(ref[name].dims, sem, f"standard error over seeds of {name}", attrs["units"],
                                 cell_methods="seed: standard_deviation (comment: divided by sqrt(count), ddof=1)")
        out[f"{name}_count"] = var(ref[name].dims, count.astype(np.int32), f"seeds with a finite {name}", "1")
    derived_fields(out)
    for name in (d for d in DERIVED if d in out):
        stack = np.stack([ds[name].values for ds in datasets])
        if name in ANGLES:
            stack = fold_axis_angle(stack - out[name].values[None]) + out[name].values[None]
        _, sem, count = nan_mean_sem(stack)
        out[name].attrs["comment"] = "computed from the ensemble-mean tensors"
        out[f"{name}_sem"] = var(out[name].dims, sem, f"standard error over seeds of {name}",
                                 out[name].attrs["units"])
        out[f"{name}_count"] = var(out[name].dims, count.astype(np.int32), f"seeds with a finite {name}", "1")
    keep = ("rve_shape", "rve_size", "rve_size_meaning", "rve_area_nominal", "min_particles", "min_solid_fraction",
            "grid_spacing", "membership", "protocol", "gravity_relaxed", "gravity_reduced")
    out.attrs.update({k: ref.attrs[k] for k in keep if k in ref.attrs})
    out.attrs["n_seeds"] = len(datasets)
    out.attrs["seeds"] = ",".join(str(ds.attrs.get("seed", "")) for ds in datasets)
    out.attrs["cell_methods"] = "seed: mean"
    out.attrs["source_files"] = ",".join(names)
    return out
