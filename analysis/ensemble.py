"""Seed averages of per-pile fields (docs/formats.md#ensemble-fields, ``fields.nc``).

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

**Slips under the probe.** A pile may slip locally when gravity is reduced
(a plastic event, not an elastic response); one such pile would dominate the
means of the probe response over a handful of piles. With
``analysis.ensemble.slip_strain_ratio`` = r (not null), a pile's RVE whose
strain increment magnitude ``|u| = sqrt(sum_ij u_ij^2)`` exceeds r times the
median ``|u|`` over that pile's RVEs counts as slipped (:func:`slipped`): its
probe response (:data:`analysis.fields.PROBE_RESPONSE`) is left out there,
so means, standard errors and counts of those variables are over the other
piles; the stress at full gravity, fabric and geometry are kept. The
variable ``slip_left_out`` holds, per RVE, how many piles were left out;
the attributes ``slip_left_out_total`` and ``slip_left_out_per_seed`` (in the
order of ``seeds``) sum it up. null leaves out nothing (a plain mean).

All piles share one grid in absolute coordinates (``analysis.grid``), so
piles of different widths need no interpolation; files with different grids
or RVEs are refused, and so are files with different variables, except the
Voigt stiffness (:data:`analysis.fields.VOIGT`), which per-pile files written
before it lack (the committed records): its mean, standard error and count
are over the piles that have it.
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from .errors import InputError
from .fields import ANGLES, DERIVED, PROBE_RESPONSE, VOIGT, derived_fields
from .netcdf import var
from .orientation import fold_axis_angle
from .params import DEFAULTS

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


def strain_magnitude(strain_increment: np.ndarray) -> np.ndarray:
    """``|u| = sqrt(sum_ij u_ij^2)`` of tensors ``(..., 2, 2)`` (NaN where any component is)."""
    u = np.asarray(strain_increment, dtype=float)
    return np.sqrt(np.sum(u * u, axis=(-2, -1)))


def slipped(strain_increment: np.ndarray, ratio: float | None) -> np.ndarray:
    """Where one pile slipped under the probe: ``|u| > ratio * median(|u|)``.

    Parameters
    ----------
    strain_increment : ndarray, shape (ny, nx, 2, 2)
        One pile's strain increment (NaN at masked RVEs).
    ratio : float or None
        ``analysis.ensemble.slip_strain_ratio``; None: nothing has slipped.

    Returns
    -------
    ndarray of bool, shape (ny, nx)
        True at the RVEs whose strain increment magnitude exceeds ``ratio``
        times the median magnitude over the pile's finite RVEs; False at
        NaN RVEs and everywhere in a pile without a finite strain.
    """
    mag = strain_magnitude(strain_increment)
    finite = np.isfinite(mag)
    if ratio is None or not finite.any():
        return np.zeros(mag.shape, dtype=bool)
    return finite & (mag > ratio * np.median(mag[finite]))


def leave_out_slips(datasets: list[xr.Dataset], ratio: float | None) -> tuple[list[xr.Dataset], np.ndarray]:
    """Per-pile fields with the probe response set to NaN where the pile slipped.

    Parameters
    ----------
    datasets : list of xarray.Dataset
        Per-pile fields files (docs/formats.md#fields) on one grid.
    ratio : float or None
        ``analysis.ensemble.slip_strain_ratio`` (see :func:`slipped`).

    Returns
    -------
    kept : list of xarray.Dataset
        Copies of ``datasets`` whose :data:`analysis.fields.PROBE_RESPONSE`
        variables are NaN at the slipped RVEs (the inputs themselves when no
        file has a strain increment).
    left_out : ndarray of bool, shape (n_piles, ny, nx)
        Which pile was left out at which RVE.
    """
    shape = (len(datasets), datasets[0].sizes["y"], datasets[0].sizes["x"])
    if any("strain_increment" not in ds for ds in datasets):
        return list(datasets), np.zeros(shape, dtype=bool)
    left_out = np.stack([slipped(ds["strain_increment"].transpose("y", "x", "i", "j").values, ratio)
                         for ds in datasets])
    kept = []
    for ds, out in zip(datasets, left_out):
        keep = xr.DataArray(~out, dims=("y", "x"))
        kept.append(ds.assign({name: ds[name].where(keep) for name in PROBE_RESPONSE if name in ds}))
    return kept, left_out


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
        missing = (set(ref.data_vars) ^ set(ds.data_vars)) - set(VOIGT)
        if missing:
            raise InputError(f"{name}: variables {sorted(missing)} are not in every file of the ensemble")


def ensemble_fields(datasets: list[xr.Dataset], names: list[str] | None = None,
                    slip_strain_ratio: float | None = DEFAULTS["ensemble"]["slip_strain_ratio"]) -> xr.Dataset:
    """Average per-pile fields datasets over seeds (see module docstring).

    Parameters
    ----------
    datasets : list of xarray.Dataset
        Per-pile fields files on one grid.
    names : list of str, optional
        Their file names, for messages and the ``source_files`` attribute.
    slip_strain_ratio : float or None
        ``analysis.ensemble.slip_strain_ratio`` (default: the schema's); None
        averages every pile-RVE.

    Returns
    -------
    xarray.Dataset
        Means, ``_sem`` and ``_count`` of every numeric field, the derived
        fields, and ``slip_left_out``.
    """
    if not datasets:
        raise InputError("an ensemble needs at least one fields file")
    names = names or [f"file {k}" for k in range(len(datasets))]
    _check_compatible(datasets, names)
    datasets, left_out = leave_out_slips(datasets, slip_strain_ratio)
    ref = datasets[0]
    out = xr.Dataset(coords={k: ref[k].variable for k in ref.coords})
    averaged = [v for v in ref.data_vars if v not in FLAG_VARS and v not in DERIVED and v not in VOIGT
                and ref[v].dtype.kind in "fiu"]
    voigt = [v for v in VOIGT if any(v in ds for ds in datasets)]
    holder = next((ds for ds in datasets if voigt[0] in ds), None) if voigt else None
    if holder is not None:
        out = out.assign_coords({k: holder[k].variable for k in holder.coords if k not in out.coords})
    for name in averaged + voigt:
        first = ref if name not in VOIGT else holder
        stack = np.stack([ds[name].values if name in ds else np.full(first[name].shape, np.nan)
                          for ds in datasets])
        mean, sem, count = nan_mean_sem(stack)
        attrs = {k: v for k, v in first[name].attrs.items() if k not in ("flag_masks", "flag_meanings")}
        out[name] = xr.Variable(first[name].dims, mean, {**attrs, "cell_methods": "seed: mean"})
        out[f"{name}_sem"] = var(first[name].dims, sem, f"standard error over seeds of {name}", attrs["units"],
                                 cell_methods="seed: standard_deviation (comment: divided by sqrt(count), ddof=1)")
        out[f"{name}_count"] = var(first[name].dims, count.astype(np.int32), f"seeds with a finite {name}", "1")
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
    _record_left_out(out, left_out, slip_strain_ratio)
    return out


def _record_left_out(out: xr.Dataset, left_out: np.ndarray, ratio: float | None) -> None:
    """``slip_left_out`` (per RVE) and its totals (attributes) on the ensemble ``out``."""
    rule = ("none left out (analysis.ensemble.slip_strain_ratio = null)" if ratio is None else
            f"{', '.join(PROBE_RESPONSE)} of a pile left out where its |strain_increment| exceeds {ratio:g} "
            "times its median over the pile's RVEs (analysis.ensemble.slip_strain_ratio)")
    out["slip_left_out"] = var(("y", "x"), left_out.sum(axis=0).astype(np.int32),
                               "piles whose probe response is left out here (slipped under the probe)", "1",
                               comment=rule)
    out.attrs["slip_left_out_total"] = int(left_out.sum())
    out.attrs["slip_left_out_per_seed"] = ",".join(str(int(n)) for n in left_out.sum(axis=(1, 2)))
