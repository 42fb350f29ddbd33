"""The per-pile fields file (docs/formats.md#fields).

:func:`rve_quantities` computes everything for an arbitrary list of RVE
centres (used for the grid and for the convergence study);
:func:`compute_fields` puts it on the configured grid as an
``xarray.Dataset`` with dimensions ``y, x, i, j``; :func:`derived_fields`
adds the invariants and orientations computed from the tensors (and is
reused on ensemble means).

A scene may ask for less (docs/workflow.md, "Scenes"): the stress always, the fabric
and the strain only when asked; without a reduced state there is no stress
increment and no strain. Every variable computed is the same, value for
value, whatever else is computed alongside.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from . import rve as _rve
from .errors import InputError, ParamError
from .fabric import deviatoric_fraction, fabric_trace, particle_fabric, rve_fabric
from .netcdf import read_dataset, tensor_coords, var
from .orientation import axis_angle_difference, axis_angle_from_vertical
from .solid_fraction import solid_fraction as _solid_fraction
from .states import State, check_same_particles, pile_attributes
from .strain import STRAIN_FLAGS, best_fit_strain
from .stress import antisymmetric_component, particle_stress_moment, rve_stress, symmetric_part
from .surface import surface_height
from .voigt import contact_stiffness, isotropic_projection, particle_voigt_moment, rve_voigt_stiffness
from .voigt import summary_attributes as voigt_attributes

QUANTITIES = ("fabric", "strain")  # optional besides the stress
TENSOR_FIELDS = ("stress", "stress_reduced", "stress_increment", "displacement_gradient", "strain_increment", "fabric")
# variables recomputed from (ensemble-mean) tensors rather than averaged
DERIVED = ("fabric_trace", "fabric_deviatoric_fraction", "fabric_orientation", "stress_orientation",
           "stress_increment_orientation", "strain_orientation", "stress_fabric_angle")
# variables that describe the response to the probe (relaxed -> reduced), left out
# together where a pile slipped under the probe (analysis.ensemble)
PROBE_RESPONSE = ("stress_reduced", "stress_increment", "displacement_gradient", "strain_increment",
                  "strain_residual", "stress_increment_orientation", "strain_orientation")
# the affine (Voigt) stiffness from the relaxed contacts (analysis/voigt.py): computed whenever the relaxed
# state names its Young's modulus; per-pile files written before it lack these, which an ensemble allows
VOIGT = ("voigt_stiffness", "voigt_bulk_modulus", "voigt_shear_modulus")
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
    "voigt_stiffness": ("affine (Voigt) Mandel stiffness C_MN of the RVE from the relaxed contacts, "
                        "Delta sigma_M = C_MN eps_N (analysis/voigt.py)", "N m-1"),
    "voigt_bulk_modulus": ("isotropic projection K = (C11 + C22 + C12 + C21)/4 of voigt_stiffness", "N m-1"),
    "voigt_shear_modulus": ("isotropic projection G = (C11 + C22 - C12 - C21 + 2 C33)/8 of voigt_stiffness",
                            "N m-1"),
}


def check_units(ds: xr.Dataset, path: str | None = None) -> None:
    """Refuse a fields file whose variables are not in the units :data:`META` writes them in.

    Every variable of :data:`META` in ``ds``, and its standard error
    ``<name>_sem`` in an ensemble, must carry exactly that ``units``: a copy
    converted to other units (the stress in kPa) would otherwise be computed
    with as if it were in the writer's.

    Parameters
    ----------
    ds : xarray.Dataset
        A per-pile or ensemble fields file as read.
    path : str, optional
        The file, named in the error; by default the file ``ds`` was opened
        from (``ds.encoding["source"]``).

    Raises
    ------
    InputError
        Naming the file, the variable, the unit found (or its absence) and
        the unit expected.
    """
    for name, v in ds.data_vars.items():
        expected = META.get(str(name).removesuffix("_sem"), (None, None))[1]
        if expected is not None and v.attrs.get("units") != expected:
            found = f"units {v.attrs['units']!r}" if "units" in v.attrs else "no units attribute"
            where = path or ds.encoding.get("source", "<dataset>")
            raise InputError(f"{where}: variable {name} has {found}, expected {expected!r} "
                             "(docs/formats.md#fields); the analysis reads fields files only in the units "
                             "python -m analysis fields writes: compute them again from the states")


def read_fields(path: str) -> xr.Dataset:
    """A per-pile or ensemble fields file, loaded, in the units of its writer
    (:func:`check_units`) and as written (its ``data_digest``,
    :func:`analysis.netcdf.read_dataset`)."""
    return read_dataset(path, check_units)


def check_quantities(quantities, has_reduced: bool) -> tuple[str, ...]:
    """The optional quantities to compute, validated: a subset of :data:`QUANTITIES`;
    ``None`` means all that the inputs allow (the strain only with a reduced state,
    ``has_reduced``).

    Raises
    ------
    ParamError
        For an unknown name, or the strain without a reduced state.
    """
    if quantities is None:
        return tuple(q for q in QUANTITIES if q != "strain" or has_reduced)
    unknown = sorted(set(quantities) - set(QUANTITIES))
    if unknown:
        raise ParamError(f"quantities {unknown}: unknown; allowed: {list(QUANTITIES)} (the stress is always "
                         "computed)")
    if "strain" in quantities and not has_reduced:
        raise ParamError("quantities: strain needs the reduced state (the strain is the relaxed -> reduced "
                         "displacement); give --reduced or leave strain out")
    return tuple(q for q in QUANTITIES if q in quantities)


def rve_quantities(relaxed: State, reduced: State | None, centres: np.ndarray, shape: str, size: float,
                   params: dict[str, Any], apply_mask: bool = True,
                   quantities=None, voigt: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """RVE quantities for RVEs of one ``shape``/``size`` at ``centres`` ``(n, 2)``.

    Membership is decided on the relaxed positions (see :mod:`analysis.rve`).
    With ``apply_mask`` the RVEs failing ``min_particles`` or
    ``min_solid_fraction`` hold NaN in every stress, strain and fabric
    quantity. The stress is always computed, the stress increment when
    ``reduced`` is given, and the optional ``quantities`` (see
    :func:`check_quantities`). With ``voigt``, the contact stiffnesses of the
    relaxed state (:func:`analysis.voigt.contact_stiffness`), also the Voigt
    stiffness ``(n, 3, 3)`` and its isotropic projections (:data:`VOIGT`).
    Returns flat arrays (tensors as ``(n, 2, 2)``).
    """
    quantities = check_quantities(quantities, reduced is not None)
    if reduced is not None:
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
    out = {
        "stress": symmetric_part(s_full),
        "stress_antisymmetric": antisymmetric_component(s_full),
        "n_particles": n_p,
        "solid_fraction": sf,
        "particle_area_fraction": paf,
        "rve_area": V,
        "mask_reason": mask,
    }
    if reduced is not None:
        out["stress_reduced"] = symmetric_part(rve_stress(W, particle_stress_moment(reduced), V))
        out["stress_increment"] = out["stress_reduced"] - out["stress"]
    if "fabric" in quantities:
        out["fabric"] = rve_fabric(W, particle_fabric(relaxed), relaxed.area)
    if "strain" in quantities:
        strain = best_fit_strain(W, relaxed, reduced, params["strain"]["min_contacts"],
                                 params["strain"]["max_condition"], masked=bad)
        out.update({
            "displacement_gradient": strain["displacement_gradient"],
            "strain_residual": strain["residual"],
            "strain_condition": strain["condition"],
            "n_contacts_strain": strain["n_contacts"],
            "strain_flag": strain["flag"],
        })
        out["strain_increment"] = symmetric_part(out["displacement_gradient"])
    if voigt is not None:
        out["voigt_stiffness"] = rve_voigt_stiffness(W, particle_voigt_moment(relaxed, voigt), V)
        out["voigt_stiffness"][bad] = np.nan
        out["voigt_bulk_modulus"], out["voigt_shear_modulus"] = isotropic_projection(out["voigt_stiffness"])
    for k in ("stress", "stress_reduced", "stress_increment", "stress_antisymmetric", "fabric"):
        if k in out:
            out[k] = np.asarray(out[k], dtype=float)
            out[k][bad] = np.nan
    return out


def derived_fields(ds: xr.Dataset) -> xr.Dataset:
    """Add fabric invariants and the principal-axis orientations (Sect. 4.2, Fig. 3) to ``ds``.

    Each is added when the tensors it is computed from are in ``ds``.
    """
    dims = ds["stress"].dims[:-2]
    new = {"stress_orientation": axis_angle_from_vertical(ds["stress"].values, "smallest")}
    if "fabric" in ds:
        F = ds["fabric"].values
        new["fabric_trace"] = fabric_trace(F)
        new["fabric_deviatoric_fraction"] = deviatoric_fraction(F)
        new["fabric_orientation"] = axis_angle_from_vertical(F, "largest")
        new["stress_fabric_angle"] = axis_angle_difference(new["stress_orientation"], new["fabric_orientation"])
    if "stress_increment" in ds:
        new["stress_increment_orientation"] = axis_angle_from_vertical(ds["stress_increment"].values, "largest")
    if "strain_increment" in ds:
        new["strain_orientation"] = axis_angle_from_vertical(ds["strain_increment"].values, "largest")
    for k in DERIVED:
        if k in new:
            ln, u = META[k]
            ds[k] = var(dims, np.asarray(new[k], dtype=float), ln, u)
    if "fabric_orientation" in ds:
        ds["fabric_orientation"].attrs["comment"] = ANGLE_COMMENT
    return ds


def nominal_area(shape: str, size: float) -> float:
    """Area of an unclipped RVE: ``size**2`` (square) or ``pi size**2 / 4`` (disc)."""
    return float(size * size if shape == "square" else np.pi * size * size / 4)


ANGLE_COMMENT = ("angles from the vertical (+y), positive counter-clockwise (upper end leaning to -x), folded "
                 "into (-90, 90]; NaN where the principal values coincide")


def _extents(relaxed: State, grid: "_rve.Grid") -> str:
    return (f"grid centres x {grid.x[0]:.4g}..{grid.x[-1]:.4g} m, y {grid.y[0]:.4g}..{grid.y[-1]:.4g} m; the "
            f"pile's particles x {relaxed.x.min():.4g}..{relaxed.x.max():.4g} m, y {relaxed.y.min():.4g}.."
            f"{relaxed.y.max():.4g} m")


def check_grid_on_pile(relaxed: State, grid: "_rve.Grid", rve: dict[str, Any]) -> None:
    """Refuse a grid none of whose RVEs can reach a particle centre, before any RVE is computed.

    An RVE of side (or diameter) ``rve["size"]`` around a centre of the grid
    reaches at most ``size / 2`` from it in x and in y; a grid whose span so
    widened misses the box of the pile's particle centres would give an
    all-NaN field (and did, with exit status 0).

    Raises
    ------
    InputError
        Naming ``analysis.grid``, both extents and what to do.
    """
    half = 0.5 * float(rve["size"])
    if relaxed.n_particles == 0 or (grid.x[-1] + half < relaxed.x.min() or grid.x[0] - half > relaxed.x.max()
                                    or grid.y[-1] + half < relaxed.y.min() or grid.y[0] - half > relaxed.y.max()):
        raise InputError(f"analysis.grid lies off the pile: no RVE of size {rve['size']} m reaches a particle "
                         f"({_extents(relaxed, grid) if relaxed.n_particles else 'the pile has no particles'}); "
                         "move the grid onto the pile")


def compute_fields(relaxed: State, reduced: State | None, params: dict[str, Any], quantities=None) -> xr.Dataset:
    """The per-pile fields of docs/formats.md#fields on the configured grid.

    ``reduced`` (None: no stress increment, no strain) and ``quantities``
    as in :func:`rve_quantities`.
    """
    grid = _rve.Grid.from_params(params["grid"])
    rp = params["rve"]
    check_grid_on_pile(relaxed, grid, rp)
    stiffness = contact_stiffness(relaxed) if "youngs_modulus" in relaxed.attrs else None
    q = rve_quantities(relaxed, reduced, grid.centres(), rp["shape"], rp["size"], params, quantities=quantities,
                       voigt=stiffness)
    if np.all(np.asarray(q["n_particles"]) < rp["min_particles"]):
        raise InputError(f"analysis.grid: none of the {grid.x.size * grid.y.size} RVEs holds "
                         f"analysis.rve.min_particles = {rp['min_particles']} particles ({_extents(relaxed, grid)})")
    ny, nx = grid.shape
    coords = {
        "y": var("y", grid.y, "height of the RVE centre above the support", "m", axis="Y"),
        "x": var("x", grid.x, "horizontal position of the RVE centre (0 at the pouring axis)", "m", axis="X"),
        **tensor_coords(),
    }
    if stiffness is not None:
        coords.update({m: var(m, np.array(["xx", "yy", "xy"], dtype=object), "Mandel component", "1")
                       for m in ("mandel_i", "mandel_j")})
    data = {}
    for k, v in q.items():
        ln, u = META[k]
        v = np.asarray(v)
        if k == "voigt_stiffness":
            data[k] = var(("y", "x", "mandel_i", "mandel_j"), v.reshape(ny, nx, 3, 3), ln, u)
        elif v.ndim == 3:
            data[k] = var(("y", "x", "i", "j"), v.reshape(ny, nx, 2, 2), ln, u)
        else:
            data[k] = var(("y", "x"), v.reshape(ny, nx), ln, u)
    ds = xr.Dataset(data, coords=coords)
    ds["mask_reason"].attrs.update({k: v for k, v in _rve.MASK_FLAGS.items()})
    if "strain_flag" in ds:
        ds["strain_flag"].attrs.update({k: v for k, v in STRAIN_FLAGS.items()})
    h = surface_height(relaxed, grid.x, params["surface"]["window"])
    ds["surface_height"] = var("x", h, *META["surface_height"])
    ds["depth"] = var(("y", "x"), h[None, :] - grid.y[:, None], *META["depth"])
    derived_fields(ds)
    ds["stress"].attrs["comment"] = ("(1/V) sum over member particles of sum_c x_i f_j (Eq. 2 with 1/V^p -> 1/V) "
                                     "= sum_p (V^p/V) sigma^p; symmetric part (the antisymmetric remainder is "
                                     "stress_antisymmetric)")
    if "displacement_gradient" in ds:
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
        **pile_attributes(relaxed),
        "gravity_relaxed": relaxed.gravity,
        "relaxed_file": relaxed.path,
        "n_particles_total": relaxed.n_particles,
        "quantities": " ".join(("stress",) + check_quantities(quantities, reduced is not None)),
    })
    if reduced is not None:
        ds.attrs.update({"gravity_reduced": reduced.gravity, "reduced_file": reduced.path,
                         **({"reduced_stage": str(reduced.attrs["stage"])} if "stage" in reduced.attrs else {})})
    if stiffness is not None:
        ds["voigt_stiffness"].attrs["comment"] = (
            "every particle moved by x . eps, none turned, every contact sticking: k_n = Y L / l (L the contact "
            "line), k_t = (2/7) Y; member particles' contacts as in the stress (support included); not exactly "
            "symmetric where contacts cross the RVE edge")
        ds.attrs.update(voigt_attributes(stiffness))
    return ds
