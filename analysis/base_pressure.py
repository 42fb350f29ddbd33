"""Forces per unit length on the support (``base_pressure.nc``, docs/formats.md#base-pressure).

The support contacts are those with ``contact_j = -1``; ``force_x, force_y``
act on the particle, so the support receives ``(-force_x, -force_y)``.
Per x bin (``analysis.base_pressure``; contacts binned by ``contact_x``):

* ``normal_force_density`` = Σ force_y / bin width: the downward push of the
  pile on the support (positive = compressive), N/m;
* ``shear_force_density`` = Σ (−force_x) / bin width: the horizontal force the
  pile exerts on the support, positive towards +x (on the right flank of a
  spreading pile positive, on the left negative).

Means and standard errors are over the seeds of one protocol.  A file may
hold one pile (the workflow writes one per pile, next to its fields) or an
ensemble; :func:`combine_base_pressure` stacks the piles of several files, so
the ensemble is built from per-pile files without the state files.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from .ensemble import nan_mean_sem
from .errors import InputError
from .netcdf import var
from .states import State


def bin_edges(bp: dict[str, Any]) -> np.ndarray:
    n = int(np.floor((bp["x_max"] - bp["x_min"]) / bp["bin_width"] + 1e-9))
    return bp["x_min"] + bp["bin_width"] * np.arange(n + 1)


def support_force_density(state: State, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normal and shear force per unit length on the support in each bin of ``edges``."""
    s = state.support
    cx = state.contact_x[s]
    nb = edges.size - 1
    b = np.digitize(cx, edges) - 1
    ok = (b >= 0) & (b < nb)
    width = np.diff(edges)
    normal = np.bincount(b[ok], weights=state.force_y[s][ok], minlength=nb) / width
    shear = np.bincount(b[ok], weights=-state.force_x[s][ok], minlength=nb) / width
    return normal, shear


def base_pressure_dataset(states: list[State], params: dict[str, Any]) -> xr.Dataset:
    """Mean and standard error over seeds of the support force densities.

    The file's ``stage`` is that of the states (``analysis.base_pressure.stage``
    where they carry none).

    Raises
    ------
    InputError
        If the states are of different stages.
    """
    stages = {str(s.attrs["stage"]): s.path for s in states if "stage" in s.attrs}
    if len(stages) > 1:
        (a, path_a), (b, path_b) = list(stages.items())[:2]
        raise InputError(f"--states {path_b}: its stage is {b!r}, but {path_a} is of stage {a!r}; the base "
                         "pressure of several piles is of one stage: give states of one")
    edges = bin_edges(params["base_pressure"])
    per = [support_force_density(s, edges) for s in states]
    return _dataset(edges, np.stack([p[0] for p in per]), np.stack([p[1] for p in per]),
                    [str(s.attrs.get("seed", k)) for k, s in enumerate(states)],
                    np.array([s.mass.sum() * s.gravity for s in states]),
                    str(states[0].attrs.get("protocol", "")) if states else "",
                    next(iter(stages), params["base_pressure"]["stage"]), params)


def combine_base_pressure(datasets: list[xr.Dataset], names: list[str], params: dict[str, Any]) -> xr.Dataset:
    """The ensemble over the piles of several ``base_pressure.nc`` files (each of
    one pile or more; ``names`` name them in errors): their per-seed profiles
    stacked, mean and standard error recomputed.

    Raises
    ------
    InputError
        If a file's bins or stage differ from ``analysis.base_pressure``.
    """
    edges = bin_edges(params["base_pressure"])
    for ds, name in zip(datasets, names):
        got = ds["x_bounds"].values
        if got.shape != (edges.size - 1, 2) or not np.allclose(got, np.column_stack([edges[:-1], edges[1:]])):
            raise InputError(f"{name}: its x bins differ from "
                             f"analysis.base_pressure (x_min {params['base_pressure']['x_min']}, x_max "
                             f"{params['base_pressure']['x_max']}, bin_width {params['base_pressure']['bin_width']})")
        if ds.attrs.get("stage") != params["base_pressure"]["stage"]:
            raise InputError(f"{name}: stage {ds.attrs.get('stage')!r}, "
                             f"but analysis.base_pressure.stage = {params['base_pressure']['stage']!r}")
    cat = xr.concat([ds[["normal_force_density_per_seed", "shear_force_density_per_seed", "weight"]]
                     for ds in datasets], dim="seed")
    return _dataset(edges, cat["normal_force_density_per_seed"].values, cat["shear_force_density_per_seed"].values,
                    [str(v) for v in cat["seed"].values], cat["weight"].values,
                    str(datasets[0].attrs.get("protocol", "")) if datasets else "", params["base_pressure"]["stage"],
                    params)


def _dataset(edges, normal, shear, seeds, weight, protocol, stage, params) -> xr.Dataset:
    mn, sn, _ = nan_mean_sem(normal)
    ms, ssh, _ = nan_mean_sem(shear)
    centres = 0.5 * (edges[:-1] + edges[1:])
    ds = xr.Dataset(coords={
        "x": var("x", centres, "centre of the x bin on the support (0 at the pouring axis)", "m", axis="X",
                 bounds="x_bounds"),
        "seed": var("seed", np.array(seeds), "seed of the pile", "1"),
    })
    ds["x_bounds"] = var(("x", "nv"), np.column_stack([edges[:-1], edges[1:]]), "x bin edges", "m")
    ds["normal_force_density"] = var("x", mn, "normal force per unit length exerted by the pile on the support "
                                     "(positive = compressive)", "N m-1", cell_methods="seed: mean")
    ds["normal_force_density_sem"] = var("x", sn, "standard error over seeds of normal_force_density", "N m-1")
    ds["shear_force_density"] = var("x", ms, "horizontal force per unit length exerted by the pile on the "
                                    "support (positive towards +x)", "N m-1", cell_methods="seed: mean")
    ds["shear_force_density_sem"] = var("x", ssh, "standard error over seeds of shear_force_density", "N m-1")
    ds["normal_force_density_per_seed"] = var(("seed", "x"), normal, "normal_force_density of each pile", "N m-1")
    ds["shear_force_density_per_seed"] = var(("seed", "x"), shear, "shear_force_density of each pile", "N m-1")
    ds["weight"] = var("seed", np.asarray(weight, dtype=float), "weight M g of each pile", "N")
    ds.attrs["n_seeds"] = len(seeds)
    ds.attrs["stage"] = stage
    ds.attrs["protocol"] = protocol
    ds.attrs["bin_width"] = params["base_pressure"]["bin_width"]
    return ds
