"""The per-pile fields file (CONTRACT.md section 2).

:func:`rve_quantities` computes everything for an arbitrary list of RVE
centres (used for the grid and for the convergence study);
:func:`compute_fields` puts it on the configured grid as an
``xarray.Dataset`` with dimensions ``y, x, i, j``; :func:`derived_fields`
adds the invariants and orientations computed from the tensors (and is
reused on ensemble means).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from . import rve as _rve
from .fabric import deviatoric_fraction, fabric_trace, particle_fabric, rve_fabric
from .netcdf import tensor_coords, var
from .orientation import axis_angle_difference, axis_angle_from_vertical
from .solid_fraction import solid_fraction as _solid_fraction
from .states import State, check_same_particles
from .strain import STRAIN_FLAGS, best_fit_strain
from .stress import antisymmetric_component, particle_stress_moment, rve_stress, symmetric_part
from .surface import surface_height

TENSOR_FIELDS = ("stress", "stress_reduced", "stress_increment", "displacement_gradient", "strain_increment", "fabric")
# variables recomputed from (ensemble-mean) tensors rather than averaged
DERIVED = ("fabric_trace", "fabric_deviatoric_fraction", "fabric_orientation", "stress_orientation",
           "stress_increment_orientation", "strain_orientation", "stress_fabric_angle")
ANGLES = ("fabric_orientation", "stress_orientation", "stress_increment_orientation", "strain_orientation",
          "stress_fabric_angle")

META: dict[str, tuple[str, str]] = {
    "stress": ("RVE stress at full gravity, symmetric part of the Eq. 2 average (compression negative)", "N m-1"),
    "stress_reduced": ("RVE stress at reduced gravity, symmetric part of the Eq. 2 average", "N m-1"),
    "stress_increment": ("stress(reduced) - stress(relaxed)", "N m-1"),
    "stress_antisymmetric": ("(sigma_xy - sigma_yx)/2 of the full-gravity Eq. 2 average (zero at rest)", "N m-1"),
    "displacement_gradient": ("Cambou best-fit displacement gradient eps_ij = du_j/dx_i, relaxed -> reduced", "1"),
    "strain_increment": ("symmetric part u_ij of the displacement gradient, relaxed -> reduced", "1"),
    "strain_residual": ("RMS of the non-affine part of the relative translations over their RMS", "1"),
    "strain_condition": ("condition number of the branch-vector matrix M_ij = sum_c l_i l_j", "1"),
    "n_contacts_strain": ("particle-particle contacts with both particles in the RVE", "1"),
    "strain_flag": ("why the strain is NaN (bit mask, 0 = valid)", "1"),
    "fabric": ("volume-weighted fabric tensor (Eqs 10-12)", "1"),
    "fabric_trace": ("trace of the fabric tensor (mean contact number)", "1"),
    "fabric_deviatoric_fraction": ("(F_max - F_min)/tr F", "1"),
    "fabric_orientation": ("angle of the major fabric axis from the vertical, counter-clockwise", "degree"),
    "stress_orientation": ("angle of the most compressive stress axis from the vertical, counter-clockwise",
                           "degree"),
    "stress_increment_orientation": ("angle of the largest-eigenvalue axis of stress_increment from the vertical, "
                                     "counter-clockwise", "degree"),
    "strain_orientation": ("angle of the largest-eigenvalue axis of strain_increment from the vertical, "
                           "counter-clockwise", "degree"),
    "stress_fabric_angle": ("stress_orientation - fabric_orientation, folded into (-90, 90]", "degree"),
    "n_particles": ("particles whose centre lies in the RVE", "1"),
    "solid_fraction": ("polygon area inside the RVE over the RVE area (rasterised)", "1"),
    "particle_area_fraction": ("sum of the areas of member particles over the RVE area", "1"),
    "rve_area": ("RVE area V above the support", "m2"),
    "mask_reason": ("why the RVE is not used (bit mask, 0 = valid)", "1"),
    "surface_height": ("height of the free surface above the support", "m"),
    "depth": ("depth of the RVE centre below the free surface", "m"),
}


def rve_quantities(relaxed: State, reduced: State, centres: np.ndarray, shape: str, size: float,
                   params: dict[str, Any], apply_mask: bool = True) -> dict[str, np.ndarray]:
    """All RVE quantities for RVEs of one ``shape``/``size`` at ``centres`` ``(n, 2)``.

    Membership is decided on the relaxed positions (see :mod:`analysis.rve`).
    With ``apply_mask`` the RVEs failing ``min_particles`` or
    ``min_solid_fraction`` hold NaN in every stress, strain and fabric
    quantity. Returns flat arrays (tensors as ``(n, 2, 2)``).
    """
    check_same_particles(relaxed, reduced)
    rp = params["rve"]
    W = _rve.membership(centres, relaxed.x, relaxed.y, shape, size)
    V = _rve.rve_area(centres[:, 1], shape, size)
    n_p = np.asarray(W.sum(axis=1)).ravel().astype(np.int64)
    sf = _solid_fraction(relaxed, centres, shape, size, rp["raster_pixel"])
    with np.errstate(invalid="ignore", divide="ignore"):
        paf = _rve.rve_sum(W, relaxed.area) / V
    if apply_mask:
        mask = _rve.mask_reason(n_p, sf, rp["min_particles"], rp["min_solid_fraction"])
    else:
        mask = np.where(n_p < 1, _rve.MASK_TOO_FEW_PARTICLES, 0).astype(np.int32)
    bad = mask != 0
    s_full = rve_stress(W, particle_stress_moment(relaxed), V)
    s_red = rve_stress(W, particle_stress_moment(reduced), V)
    fab = rve_fabric(W, particle_fabric(relaxed), relaxed.area)
    strain = best_fit_strain(W, relaxed, reduced, params["strain"]["min_contacts"],
                             params["strain"]["max_condition"], masked=bad)
    out = {
        "stress": symmetric_part(s_full),
        "stress_reduced": symmetric_part(s_red),
        "stress_antisymmetric": antisymmetric_component(s_full),
        "displacement_gradient": strain["displacement_gradient"],
        "strain_residual": strain["residual"],
        "strain_condition": strain["condition"],
        "n_contacts_strain": strain["n_contacts"],
        "strain_flag": strain["flag"],
        "fabric": fab,
        "n_particles": n_p,
        "solid_fraction": sf,
        "particle_area_fraction": paf,
        "rve_area": V,
        "mask_reason": mask,
    }
    out["stress_increment"] = out["stress_reduced"] - out["stress"]
    out["strain_increment"] = symmetric_part(out["displacement_gradient"])
    for k in ("stress", "stress_reduced", "stress_increment", "stress_antisymmetric", "fabric"):
        out[k] = np.asarray(out[k], dtype=float)
        out[k][bad] = np.nan
    return out


def derived_fields(ds: xr.Dataset) -> xr.Dataset:
    """Add fabric invariants and the principal-axis orientations (Sect. 4.2, Fig. 3) to ``ds``."""
    dims = ds["fabric"].dims[:-2]
    F = ds["fabric"].values
    fab_or = axis_angle_from_vertical(F, "largest")
    st_or = axis_angle_from_vertical(ds["stress"].values, "smallest")
    new = {
        "fabric_trace": fabric_trace(F),
        "fabric_deviatoric_fraction": deviatoric_fraction(F),
        "fabric_orientation": fab_or,
        "stress_orientation": st_or,
        "stress_increment_orientation": axis_angle_from_vertical(ds["stress_increment"].values, "largest"),
        "strain_orientation": axis_angle_from_vertical(ds["strain_increment"].values, "largest"),
        "stress_fabric_angle": axis_angle_difference(st_or, fab_or),
    }
    for k, v in new.items():
        ln, u = META[k]
        ds[k] = var(dims, np.asarray(v, dtype=float), ln, u)
    ds["fabric_orientation"].attrs["comment"] = ANGLE_COMMENT
    return ds


def nominal_area(shape: str, size: float) -> float:
    """Area of an unclipped RVE: ``size**2`` (square) or ``pi size**2 / 4`` (disc)."""
    return float(size * size if shape == "square" else np.pi * size * size / 4)


ANGLE_COMMENT = ("angles from the vertical (+y), positive counter-clockwise (upper end leaning to -x), folded "
                 "into (-90, 90]; NaN where the principal values coincide")


def compute_fields(relaxed: State, reduced: State, params: dict[str, Any]) -> xr.Dataset:
    """The per-pile fields of CONTRACT.md section 2 on the configured grid."""
    grid = _rve.Grid.from_params(params["grid"])
    rp = params["rve"]
    q = rve_quantities(relaxed, reduced, grid.centres(), rp["shape"], rp["size"], params)
    ny, nx = grid.shape
    coords = {
        "y": var("y", grid.y, "height of the RVE centre above the support", "m", axis="Y"),
        "x": var("x", grid.x, "horizontal position of the RVE centre (0 at the pouring axis)", "m", axis="X"),
        **tensor_coords(),
    }
    data = {}
    for k, v in q.items():
        ln, u = META[k]
        v = np.asarray(v)
        if v.ndim == 3:
            data[k] = var(("y", "x", "i", "j"), v.reshape(ny, nx, 2, 2), ln, u)
        else:
            data[k] = var(("y", "x"), v.reshape(ny, nx), ln, u)
    ds = xr.Dataset(data, coords=coords)
    ds["mask_reason"].attrs.update({k: v for k, v in _rve.MASK_FLAGS.items()})
    ds["strain_flag"].attrs.update({k: v for k, v in STRAIN_FLAGS.items()})
    h = surface_height(relaxed, grid.x, params["surface"]["window"])
    ds["surface_height"] = var("x", h, *META["surface_height"])
    ds["depth"] = var(("y", "x"), h[None, :] - grid.y[:, None], *META["depth"])
    derived_fields(ds)
    ds["stress"].attrs["comment"] = ("(1/V) sum over member particles of sum_c x_i f_j (Eq. 2 with 1/V^p -> 1/V) "
                                     "= sum_p (V^p/V) sigma^p; symmetric part (the antisymmetric remainder is "
                                     "stress_antisymmetric)")
    ds["displacement_gradient"].attrs["comment"] = "index order of Eq. 4: dDelta u_j = eps_ij l_i"
    ds.attrs.update({
        "rve_shape": rp["shape"],
        "rve_size": rp["size"],
        "rve_size_meaning": "side of the square" if rp["shape"] == "square" else "diameter of the disc",
        "rve_area_nominal": nominal_area(rp["shape"], rp["size"]),
        "min_particles": rp["min_particles"],
        "min_solid_fraction": rp["min_solid_fraction"],
        "grid_spacing": params["grid"]["spacing"],
        "membership": ("particles: centre inside the RVE (relaxed positions, both stages); stress and fabric: all "
                       "contacts of member particles incl. the support; strain: particle-particle contacts with "
                       "both particles inside; RVE clipped to y >= 0"),
        "protocol": str(relaxed.attrs.get("protocol", "")),
        "seed": str(relaxed.attrs.get("seed", "")),
        "gravity_relaxed": relaxed.gravity,
        "gravity_reduced": reduced.gravity,
        "relaxed_file": relaxed.path,
        "reduced_file": reduced.path,
        "n_particles_total": relaxed.n_particles,
    })
    return ds
