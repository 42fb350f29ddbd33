"""Does the construction history show in a pile?  One number per pile, in fixed windows.

The paper's central finding is that a point-source (wedge) pile carries its
history: a pressure minimum, a density maximum and a dip of the vertical
strain increment near the centre, none of which a line-source (layered) pile
shows.  This module turns that into numbers that can decide it: each
statistic is one number per pile, computed in windows fixed once
(``analysis.history``; after the study's piles, see below).  The protocols
are compared over their piles by :mod:`analysis.ensemble_statistics` (the
mean with its standard error, Welch's test, Holm's correction, the power):
this module computes what one pile gives, that one what an ensemble of
piles does.

Windows, by the centre ``x`` of a grid column or base bin (``x = 0`` on the
pouring axis): the *centre* ``|x| <= centre``; the *shoulders*
``shoulder_inner <= |x| <= shoulder_outer`` on both sides (fixed, so that no
column is picked by its value); the *core* ``|x| <= shoulder_outer``,
``y <= core_height``; the *flanks* ``flank_inner <= |x| <= flank_outer``,
``y <= flank_height``.  Per pile (:func:`pile_history`):

* ``strain@h``: ``mean u_yy(centre) / mean u_yy(shoulders) - 1`` in the grid
  row nearest each height ``h`` (the Fig. 2 layers); below 0: a dip;
* ``solid_fraction@h``: ``mean phi(centre) / mean phi(shoulders) - 1``;
  above 0: denser at the centre;
* ``base_pressure``: ``mean p(centre) / mean p(shoulders) - 1`` of the normal
  force density on the support.  A heap of uniform density already presses
  most where it is highest, so this is not zero without a history; hence
* ``base_pressure_column``: the same with each bin's pressure over the
  pressure ``p_u(x) = W h(x) / integral h dx`` that a pile of uniform density
  with the pile's own measured surface ``h(x)`` and weight ``W`` would put
  there (every column carrying its own weight); below 0: the centre carries
  less than its column relative to the shoulders, a dip against the heap;
* ``centre_column``: ``mean p(centre) / mean p_u(centre) - 1``, the centre's
  load against its own column;
* ``gravity_xx``, ``gravity_yy``: medians over the core RVEs of
  ``dsigma_xx / sigma_xx`` and ``dsigma_yy / sigma_yy`` under the probe (a
  stress proportional to gravity gives ``-Delta`` in both), and
  ``gravity_gap = gravity_xx / gravity_yy - 1`` (0 when both scale with g;
  the paper's Sect. 3 finds sigma_xx changing less);
* ``stress_fabric``: the mean over the flank RVEs of ``sign(x)`` times the
  angle from the fabric's major axis to the most compressive stress axis
  (degrees; mirrored so that a tilt symmetric about the axis adds up);
  0 when the axes are collinear on average.

Probe responses of RVEs that slipped (``analysis.ensemble.slip_strain_ratio``)
are left out, as in the ensembles; a pile without a gravity probe
(``probe.levels: []``) has none, and ``strain@h``, ``gravity_xx``,
``gravity_yy`` and ``gravity_gap`` are NaN for it (:func:`probe_response`).  The five *primary* statistics, one per
question, are listed in :data:`PRIMARY`; the others are secondary.

The windows were set after the study's 19 piles had been recorded and read
(git: the piles 2026-12-01/02, the windows 8fb4149 on 2026-12-03), so they
are fixed for the piles poured since, not for those 19.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from .ensemble import leave_out_slips

#: The primary statistics, one per question (``{h}`` is ``analysis.history.primary_height``).
PRIMARY = ("strain@{h}", "base_pressure_column", "solid_fraction@{h}", "gravity_gap", "stress_fabric")

#: Unit of each statistic's kind: a relative contrast (shown in %) or an angle (degrees).
UNITS = {"stress_fabric": "deg"}


def _nanmean(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(a.mean()) if a.size else math.nan


def _nanmedian(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def probe_response(fields: xr.Dataset, name: str, k: str) -> np.ndarray:
    """The ``kk`` component of the probe response ``name`` (``stress_increment`` or
    ``strain_increment``) on the ``(y, x)`` grid.

    Parameters
    ----------
    fields : xarray.Dataset
        One pile's RVE fields.
    name : str
        The response's variable.
    k : {"x", "y"}
        The component's axis.

    Returns
    -------
    numpy.ndarray
        Shape ``(ny, nx)``; all NaN where the fields hold no ``name``: a pile without a
        gravity probe (``probe.levels: []``) has no response to one, so every statistic
        read from it is NaN and every other is as with the probe.
    """
    if name not in fields:
        return np.full((fields.sizes["y"], fields.sizes["x"]), math.nan)
    return fields[name].sel(i=k, j=k).transpose("y", "x").values


def height_key(h: float) -> str:
    """The suffix of a per-layer statistic: ``4.5`` (cm) for 0.045 m."""
    return f"{100 * h:g}"


def primary_names(history: dict[str, Any]) -> list[str]:
    """The names of the primary statistics under the settings ``history``."""
    return [name.format(h=height_key(history["primary_height"])) for name in PRIMARY]


def windows(x: np.ndarray, history: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the centre and the shoulders over the positions ``x`` (m)."""
    ax = np.abs(np.asarray(x, float))
    eps = 1e-9  # grid coordinates carry rounding; a window edge on a column keeps it
    centre = ax <= history["centre"] + eps
    shoulders = (ax >= history["shoulder_inner"] - eps) & (ax <= history["shoulder_outer"] + eps)
    return centre, shoulders


def row_contrast(row: np.ndarray, x: np.ndarray, history: dict[str, Any]) -> float:
    """``mean(centre) / mean(shoulders) - 1`` of one grid row (NaN where a window is empty)."""
    centre, shoulders = windows(x, history)
    c, s = _nanmean(row[centre]), _nanmean(row[shoulders])
    return c / s - 1.0 if np.isfinite(c) and np.isfinite(s) and s != 0 else math.nan


def uniform_pile_pressure(x_bins: np.ndarray, x_surface: np.ndarray, surface: np.ndarray,
                          weight: float) -> np.ndarray:
    """The pressure a pile of uniform density would put on the support at ``x_bins``.

    Each column carries its own weight: ``p_u(x) = W h(x) / integral h dx``, with
    ``h`` the measured free surface (NaN, outside the pile, counts as 0) linearly
    interpolated between its grid columns and ``W`` the pile's weight per unit
    length (N/m), so that ``p_u`` integrates to ``W`` over the surface's extent.
    """
    h = np.where(np.isfinite(surface), surface, 0.0)
    area = float(np.trapezoid(h, x_surface))
    if not area > 0:
        return np.full(np.shape(x_bins), math.nan)
    return weight * np.interp(x_bins, x_surface, h, left=0.0, right=0.0) / area


def base_pressure_inputs(bp: xr.Dataset, fields: xr.Dataset) -> dict[str, list]:
    """What ``base_pressure_column`` of one pile is computed from: the
    support's bins ``x`` (m), their normal force density ``p`` (N/m) and the
    uniform column's pressure ``p_u`` there (N/m, the pile's own surface and
    weight, :func:`uniform_pile_pressure`), as lists (NaN for an empty bin).
    Kept in each decision record, so that a reader recomputes ``base_pressure_column`` from it
    (:func:`base_pressure_stats`)."""
    x = bp["x"].values
    p = bp["normal_force_density_per_seed"].values[0]
    pu = uniform_pile_pressure(x, fields["x"].values, fields["surface_height"].values, float(bp["weight"].values[0]))
    return {"x": x.tolist(), "p": p.tolist(), "p_u": pu.tolist()}


def base_pressure_stats(bp: xr.Dataset, fields: xr.Dataset, history: dict[str, Any]) -> dict[str, float]:
    """``base_pressure``, ``base_pressure_column`` and ``centre_column`` of one pile
    (from :func:`base_pressure_inputs`)."""
    inputs = base_pressure_inputs(bp, fields)
    x, p, pu = (np.asarray(inputs[k], float) for k in ("x", "p", "p_u"))
    centre, shoulders = windows(x, history)
    pc, ps = _nanmean(p[centre]), _nanmean(p[shoulders])
    uc, us = _nanmean(pu[centre]), _nanmean(pu[shoulders])
    return {"base_pressure": pc / ps - 1.0,
            "base_pressure_column": (pc / uc) / (ps / us) - 1.0,
            "centre_column": pc / uc - 1.0}


def gravity_scaling(fields: xr.Dataset, history: dict[str, Any]) -> dict[str, float]:
    """``gravity_xx``, ``gravity_yy`` and ``gravity_gap`` over the core RVEs of one pile
    (NaN for a pile without a gravity probe, :func:`probe_response`)."""
    x, y = fields["x"].values, fields["y"].values
    core = (np.abs(x)[None, :] <= history["shoulder_outer"] + 1e-9) & (y[:, None] <= history["core_height"] + 1e-9)
    out = {}
    for k in ("x", "y"):
        s = fields["stress"].sel(i=k, j=k).transpose("y", "x").values
        d = probe_response(fields, "stress_increment", k)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[f"gravity_{k}{k}"] = _nanmedian(np.where(core & (s < 0), d / s, np.nan))
    out["gravity_gap"] = out["gravity_xx"] / out["gravity_yy"] - 1.0
    return out


def flanks(x: np.ndarray, y: np.ndarray, history: dict[str, Any]) -> np.ndarray:
    """Mask ``(y, x)`` of the flank window: ``flank_inner <= |x| <= flank_outer``, ``y <= flank_height``."""
    ax = np.abs(x)
    return ((ax >= history["flank_inner"] - 1e-9) & (ax <= history["flank_outer"] + 1e-9))[None, :] \
        & (y[:, None] <= history["flank_height"] + 1e-9)


def stress_fabric_angle(fields: xr.Dataset, history: dict[str, Any]) -> float:
    """Mean of ``sign(x)`` times the stress-fabric angle over the flank RVEs of one pile (degrees);
    NaN for fields made without the fabric (``outputs`` without ``fabric``)."""
    if "stress_fabric_angle" not in fields:
        return math.nan
    x, y = fields["x"].values, fields["y"].values
    a = fields["stress_fabric_angle"].transpose("y", "x").values * np.sign(x)[None, :]
    return _nanmean(np.where(flanks(x, y, history), a, np.nan))


def flank_fabric(fields: xr.Dataset, history: dict[str, Any]) -> dict[str, float]:
    """The fabric of one pile's flanks: over the valid RVEs of :func:`flanks`, the mean deviatoric
    fraction (``fabric_deviator``) and the mean of ``sign(x)`` times the major axis's angle
    (``fabric_axis_deg``, mirrored so that a tilt symmetric about the axis adds up)."""
    x, y = fields["x"].values, fields["y"].values
    flank = flanks(x, y, history) & (fields["mask_reason"].transpose("y", "x").values == 0)
    dev = fields["fabric_deviatoric_fraction"].transpose("y", "x").values
    axis = fields["fabric_orientation"].transpose("y", "x").values * np.sign(x)[None, :]
    return {"fabric_deviator": float(np.nanmean(np.where(flank, dev, np.nan))),
            "fabric_axis_deg": float(np.nanmean(np.where(flank, axis, np.nan)))}


def pile_history(fields: xr.Dataset, params: dict[str, Any], heights: list[float],
                 bp: xr.Dataset | None = None) -> dict[str, float]:
    """Every history statistic of one pile.

    Parameters
    ----------
    fields : xarray.Dataset
        The pile's RVE fields (``fields.nc``).
    params : dict
        The resolved analysis settings (``analysis.params.resolve_params``):
        ``history`` gives the windows, ``ensemble.slip_strain_ratio`` the slips.
    heights : list of float
        Layers (m) of the per-layer statistics; ``history.primary_height`` is
        added when missing.
    bp : xarray.Dataset, optional
        The pile's ``base_pressure.nc``; without it the base-pressure
        statistics are left out.

    Returns
    -------
    dict
        ``{name: value}``, relative contrasts as fractions, the angle in degrees;
        those read from the probe NaN for a pile without one (:func:`probe_response`).
    """
    h = params["history"]
    (fields,), _ = leave_out_slips([fields], params["ensemble"]["slip_strain_ratio"])
    x, y = fields["x"].values, fields["y"].values
    u = probe_response(fields, "strain_increment", "y")
    phi = fields["solid_fraction"].transpose("y", "x").values
    phi = np.where(fields["mask_reason"].transpose("y", "x").values == 0, phi, np.nan)
    out = {}
    for z in sorted(set(heights) | {h["primary_height"]}):
        k = int(np.argmin(np.abs(y - z)))
        out[f"strain@{height_key(z)}"] = row_contrast(u[k], x, h)
        out[f"solid_fraction@{height_key(z)}"] = row_contrast(phi[k], x, h)
    if bp is not None:
        out.update(base_pressure_stats(bp, fields, h))
    out.update(gravity_scaling(fields, h))
    out["stress_fabric"] = stress_fabric_angle(fields, h)
    return out


def lowest_row(fields, params):
    """Index of the lowest grid row whose centre and shoulder windows both hold a valid RVE (None: no such row)."""
    centre, shoulders = windows(fields["x"].values, params["history"])
    ok = fields["mask_reason"].transpose("y", "x").values == 0
    rows = np.flatnonzero(ok[:, centre].any(axis=1) & ok[:, shoulders].any(axis=1))
    return int(rows[0]) if rows.size else None


def pile_stress_contrasts(fields, params):
    """One pile's centre-over-shoulders contrasts behind the strain contrast, in the
    windows of ``analysis.history`` (slipped RVEs left out, as there):

    * ``stress_increment``: of ``Δσ_yy`` at the primary height;
    * ``vertical_stiffness``: of the secant ``Δσ_yy / u_yy`` there (so that
      ``1 + strain = (1 + stress_increment) / (1 + vertical_stiffness)`` up
      to the windows' averaging);
    * ``stress_column``: of ``σ_yy / p_u`` in the lowest grid row with valid
      RVEs, ``p_u`` the pressure of a uniform-density pile of the pile's own
      surface (:func:`analysis.history.uniform_pile_pressure`): the column
      contrast of the base pressure, read from the RVE stress instead of 2 cm
      bins of contact forces.

    The first three read the probe: NaN for a pile without one (:func:`probe_response`).
    """
    h = params["history"]
    (fields,), _ = leave_out_slips([fields], params["ensemble"]["slip_strain_ratio"])
    x, y = fields["x"].values, fields["y"].values
    k = int(np.argmin(np.abs(y - h["primary_height"])))
    d = probe_response(fields, "stress_increment", "y")
    u = probe_response(fields, "strain_increment", "y")
    col = _stress_column_row(fields, params)
    centre, shoulders = windows(x, h)
    window = u[k][centre | shoulders]
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"stress_increment": row_contrast(d[k], x, h), "vertical_stiffness": row_contrast(d[k] / u[k], x, h),
                "strain_min": float(np.min(window[np.isfinite(window)])) if np.isfinite(window).any() else math.nan,
                "stress_column": math.nan if col is None else row_contrast(
                    np.asarray(col["sigma_yy"]) / np.asarray(col["p_u"]), x, h),
                "lowest_row_y": math.nan if col is None else col["y"]}


def _stress_column_row(fields, params):
    """``stress_column``'s row of fields already cleared of slips (see :func:`stress_column_inputs`), or None."""
    x = fields["x"].values
    low = lowest_row(fields, params)
    if low is None:
        return None
    ok = fields["mask_reason"].transpose("y", "x").values[low] == 0
    s = np.where(ok, fields["stress"].sel(i="y", j="y").transpose("y", "x").values[low], np.nan)
    pu = uniform_pile_pressure(x, x, fields["surface_height"].values, 1.0)
    return {"y": float(fields["y"].values[low]), "x": x.tolist(), "sigma_yy": s.tolist(), "p_u": pu.tolist()}


def stress_column_inputs(fields, params):
    """What ``stress_column`` of one pile is computed from: the height
    ``y`` (m) of its row (the lowest whose centre and shoulder windows both
    hold a valid RVE, :func:`lowest_row`, slipped RVEs left out), the grid
    columns ``x`` (m), ``σ_yy`` there (N/m in 2D, NaN where the RVE is not valid)
    and the uniform column's pressure ``p_u`` of a pile of unit weight (1/m,
    :func:`uniform_pile_pressure`), as lists; None when no row qualifies.
    Kept in each decision record, so that a reader recomputes ``stress_column`` as
    ``mean(σ_yy/p_u over the centre) / mean(σ_yy/p_u over the shoulders) − 1``
    (:func:`pile_stress_contrasts`)."""
    (fields,), _ = leave_out_slips([fields], params["ensemble"]["slip_strain_ratio"])
    return _stress_column_row(fields, params)
