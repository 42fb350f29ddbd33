"""RVE-size convergence (paper Fig. 1).

At a few fixed points (``analysis.convergence.points``) of one pile, the
stress at full gravity, the stress increment and the strain increment are
computed with RVEs of growing size (``analysis.convergence.sizes``, shape
``analysis.rve.shape``), from a few particles to several hundred, without
the ``min_particles``/``min_solid_fraction`` mask (the point of the study is
to show small RVEs) but with the strain conditioning checks.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from .errors import InputError
from .fields import META, rve_quantities
from .netcdf import tensor_coords, var
from .states import State


def convergence_dataset(relaxed: State, reduced: State, params: dict[str, Any]) -> xr.Dataset:
    """Fields at the configured points for every configured RVE size.

    A point whose largest RVE holds no particle is refused (:class:`InputError`
    naming it): its fields would be NaN at every size.
    """
    pts = np.asarray(params["convergence"]["points"], dtype=float).reshape(-1, 2)
    sizes = np.asarray(sorted(params["convergence"]["sizes"]), dtype=float)
    shape = params["rve"]["shape"]
    keys = ("stress", "stress_increment", "displacement_gradient", "strain_increment", "fabric", "n_particles",
            "n_contacts_strain", "solid_fraction", "strain_flag", "strain_residual")
    acc: dict[str, list] = {k: [] for k in keys}
    for s in sizes:  # loop over RVE sizes
        q = rve_quantities(relaxed, reduced, pts, shape, float(s), params, apply_mask=False)
        for k in keys:
            acc[k].append(q[k])
    empty = np.flatnonzero(np.max(np.stack(acc["n_particles"]), axis=0) == 0)
    if empty.size:
        k = int(empty[0])
        raise InputError(f"analysis.convergence.points[{k}] = ({pts[k, 0]:g}, {pts[k, 1]:g}) m lies off the pile: "
                         f"no RVE up to {sizes[-1]:g} m around it holds a particle (the pile's particles: x "
                         f"{relaxed.x.min():.4g}..{relaxed.x.max():.4g} m, y {relaxed.y.min():.4g}..{relaxed.y.max():.4g} m)")
    coords = {
        "rve_size": var("rve_size", sizes, "RVE size (square side or disc diameter)", "m"),
        "point": var("point", np.arange(pts.shape[0], dtype=np.int32), "index of the fixed point", "1"),
        **tensor_coords(),
    }
    ds = xr.Dataset(coords=coords)
    ds["point_x"] = var("point", pts[:, 0], "x of the RVE centre", "m")
    ds["point_y"] = var("point", pts[:, 1], "y of the RVE centre", "m")
    for k in keys:
        a = np.stack(acc[k])
        dims = ("rve_size", "point", "i", "j") if a.ndim == 4 else ("rve_size", "point")
        ds[k] = var(dims, a, *META[k])
    ds.attrs.update({"rve_shape": shape, "protocol": str(relaxed.attrs.get("protocol", "")),
                     "seed": str(relaxed.attrs.get("seed", "")), "relaxed_file": relaxed.path,
                     "reduced_file": reduced.path})
    return ds


def reference_size(sizes: np.ndarray, point_y: np.ndarray) -> int:
    """Index of the largest RVE side ``s`` with ``s / 2 <= y`` at every fixed point (an RVE wholly
    above the support: 12 cm for points at 6 and 9 cm); the largest size when none is."""
    inside = np.flatnonzero(sizes / 2 <= point_y.min() + 1e-9)
    return int(inside[-1]) if inside.size else sizes.size - 1


def deviations(sets: list[xr.Dataset], ref: int | None = None) -> dict[str, Any]:
    """Fig. 1 over several piles' convergence files (the same RVE sizes in each): how far ``σ_yy``
    and ``Δσ_yy`` in each RVE size lie from their values in a reference RVE.

    Parameters
    ----------
    sets : list of xarray.Dataset
        The piles' :func:`convergence_dataset` files.
    ref : int, optional
        Index of the reference size; by default :func:`reference_size`.

    Returns
    -------
    dict
        ``sizes``, ``ref``, ``n`` (particles in each RVE, size × pile-point);
        per quantity (``stress``, ``stress_increment``) the median and the
        largest over the piles' points of ``100 |v / v_ref − 1|`` (%) per size,
        and ``{quantity}_largest_cut``: the median of ``v`` in the largest RVE
        over ``v_ref`` at the points whose largest RVE reaches below the
        support (NaN: none); ``cut_points``: the heights of those points.
    """
    sizes = sets[0]["rve_size"].values
    py = np.concatenate([ds["point_y"].values for ds in sets])
    ref = reference_size(sizes, py) if ref is None else ref % sizes.size
    out = {"sizes": sizes, "ref": ref, "n": np.concatenate([ds["n_particles"].values for ds in sets], axis=1)}
    cut = sizes[-1] / 2 > py + 1e-9
    for name in ("stress", "stress_increment"):
        v = np.concatenate([ds[name].sel(i="y", j="y").values for ds in sets], axis=1)
        dev = 100 * np.abs(v / v[ref] - 1.0)
        out[name] = (np.median(dev, axis=1), dev.max(axis=1))
        out[f"{name}_largest_cut"] = float(np.median(v[-1, cut] / v[ref, cut])) if cut.any() else np.nan
    out["cut_points"] = sorted({float(v) for v in py[cut]})
    return out
