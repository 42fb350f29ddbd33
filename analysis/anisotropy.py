"""All six elastic constants of one pile, and the paper's statements on the
choice of elastic law tested with them (issue 27).

Per pile (:func:`pile_anisotropy`), from its probe increments
(``probes.nc`` with the support stretch, stage ``stretched``) and its fields:

* the general fit of :func:`analysis.probes.general_fit_dataset` over that
  pile alone: the Mandel stiffness ``C`` per RVE, its condition number over
  all loading probes and over the gravity probes alone, whether it pins all
  six constants (``six_constants``), the stiffest and softest uniaxial
  directions, the anisotropy ``E_max / E_min`` and the stiffest axis minus
  the pile's fabric and stress axes;
* the engineering moduli of the paper (:func:`engineering_moduli`) of three
  laws fitted to the same samples: the general one, the isotropic (K, G,
  Eq. 21) and the cubic (λ1, λ2, λ3, Eq. 16); and of the isotropic and cubic
  laws fitted to the gravity reduction alone, as the paper fits them
  (prefix ``reduced_``);
* the Voigt (affine) stiffness of the RVE from its own contacts
  (:mod:`analysis.voigt`, in the fields), its moduli, anisotropy and
  stiffest axis.

:func:`pile_summary` reduces that to one number per pile and quantity over
the core RVEs where all six constants are pinned (the core of
``analysis.history``: ``|x| <= shoulder_outer``, ``y <= core_height``), and the
centre-over-shoulders contrasts of the moduli at the primary layer
(:func:`analysis.history.row_contrast`); the script
``workflow/tools/six_constants_table.py`` averages those over piles.

**The paper's moduli of any stiffness.**  The paper defines, for its cubic
law, ``K = (λ1 + λ2)/2``, Young's moduli along the axes (``E_p``) and the
bisectors (``E_b``), shear moduli for a shear along the axes
(``G_p = λ3``) and along the bisectors (``G_b = (λ1 − λ2)/2``), and their
averages ``E_av``, ``G_av``.  The same definitions apply to any Mandel
stiffness ``C``: ``K = (C_11 + C_22 + 2 C_12)/4`` (``tr Δσ = 2K tr Δu`` under
an isotropic strain), ``E_p`` and ``E_b`` the means of the uniaxial Young's
modulus (:func:`analysis.general_elastic.directional_modulus`) along x and y
and along the two bisectors, ``G_p = C_33 / 2`` (``Δσ_xy = 2 G_p Δu_xy``
under a pure xy shear) and ``G_b = (C_11 + C_22 − 2 C_12)/4`` (the same for
the shear whose axes are the bisectors: its Mandel direction is
``(−1, 1, 0)/√2``).  For a cubic ``C`` these are the paper's expressions
(``E_b`` in the rotated form of :func:`analysis.elastic.cubic_engineering_moduli`),
for an isotropic one ``K``, ``4KG/(K + G)`` and ``G``; ``K`` and ``G_av`` are
the isotropic projection of ``C`` (:func:`analysis.voigt.isotropic_projection`).
So the three laws' moduli compare like with like.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from . import general_elastic as ge
from .history import row_contrast
from .orientation import axis_angle_difference
from .probes import general_fit_dataset
from .voigt import isotropic_projection

#: The probe stage of the support stretch (``probe.stretch``; ``STRETCH_STAGE`` of the workflow).
STRETCH = "stretched"
#: The paper's moduli, in the order the tables give them.
MODULI = ("K", "E_p", "E_b", "E_av", "G_p", "G_b", "G_av")
#: The laws whose moduli are compared: (prefix, stiffness variable of the general fit, probes it is fitted to).
LAWS = {"general": ("stiffness", "loading"), "isotropic": ("stiffness_isotropic", "loading"),
        "cubic": ("stiffness_cubic", "loading"), "reduced_isotropic": ("stiffness_isotropic", "reduced"),
        "reduced_cubic": ("stiffness_cubic", "reduced")}
#: The per-RVE variables of the general fit kept per pile.
FIT_VARS = ("condition", "condition_gravity", "six_constants", "axis_deg", "soft_axis_deg", "anisotropy",
            "axis_to_fabric_deg", "axis_to_stress_deg", "explained_general", "explained_isotropic",
            "explained_cubic")


def has_stretch(path) -> bool:
    """Whether the probes file ``path`` (:func:`analysis.probes.probe_increments`) has the stage :data:`STRETCH`."""
    with xr.open_dataset(path) as ds:
        return STRETCH in [str(p) for p in ds["probe"].values]


def engineering_moduli(stiffness: np.ndarray) -> dict[str, np.ndarray]:
    """The paper's bulk, Young's and shear moduli of Mandel stiffnesses (module docstring).

    Parameters
    ----------
    stiffness : array ``(..., 3, 3)``
        Mandel stiffnesses (N/m); the symmetric part is used.

    Returns
    -------
    dict
        :data:`MODULI` as arrays ``(...)`` (N/m); NaN where ``C`` is missing,
        and ``E_p``, ``E_b``, ``E_av`` also where it is singular.
    """
    c = np.asarray(stiffness, float)
    c = 0.5 * (c + np.swapaxes(c, -1, -2))
    e = ge.directional_modulus(c, np.array([0.0, 90.0, 45.0, -45.0]))
    K, G_av = isotropic_projection(c)
    out = {"K": K, "E_p": 0.5 * (e[..., 0] + e[..., 1]), "E_b": 0.5 * (e[..., 2] + e[..., 3]),
           "G_p": 0.5 * c[..., 2, 2], "G_b": 0.25 * (c[..., 0, 0] + c[..., 1, 1] - 2.0 * c[..., 0, 1]), "G_av": G_av}
    out["E_av"] = 0.5 * (out["E_p"] + out["E_b"])
    return {k: out[k] for k in MODULI}


def pile_anisotropy(probes: xr.Dataset, fields: xr.Dataset, params: dict[str, Any]) -> xr.Dataset:
    """Everything :func:`pile_summary` needs of one pile, per RVE.

    Parameters
    ----------
    probes : xarray.Dataset
        The pile's ``probes.nc`` (:func:`analysis.probes.probe_increments`),
        with the gravity reduction ``reduced``.
    fields : xarray.Dataset
        Its ``fields.nc``: the fabric and stress orientations, and the Voigt
        stiffness ``voigt_stiffness`` where it has one.
    params : dict
        The resolved analysis settings.

    Returns
    -------
    xarray.Dataset
        On ``(points, y, x)``: :data:`FIT_VARS` of the pile's general fit,
        ``{law}_{modulus}`` for the laws of :data:`LAWS` and :data:`MODULI`;
        with the Voigt stiffness also ``voigt_{modulus}``,
        ``voigt_anisotropy`` and ``voigt_axis_to_fit_deg`` (the Voigt
        stiffest axis minus the fitted one, folded into (−90°, 90°]).
    """
    fits = {"loading": general_fit_dataset([probes], params, fields),
            "reduced": general_fit_dataset([probes.sel(probe=["reduced"])], params)}
    whole = fits["loading"]
    out = xr.Dataset({name: whole[name] for name in FIT_VARS})
    for law, (name, data) in LAWS.items():
        for k, v in engineering_moduli(fits[data][name].values).items():
            out[f"{law}_{k}"] = (("points", "y", "x"), v)
    if "voigt_stiffness" in fields:
        c = np.broadcast_to(fields["voigt_stiffness"].transpose("y", "x", ...).values, whole["stiffness"].shape)
        for k, v in engineering_moduli(c).items():
            out[f"voigt_{k}"] = (("points", "y", "x"), v)
        axes = ge.stiffness_axes(0.5 * (c + np.swapaxes(c, -1, -2)))
        out["voigt_anisotropy"] = (("points", "y", "x"), axes["anisotropy"])
        out["voigt_axis_to_fit_deg"] = (("points", "y", "x"),
                                        axis_angle_difference(axes["axis_deg"], whole["axis_deg"].values))
    out.attrs.update({k: whole.attrs[k] for k in ("loading_probes", "gravity_probes", "other_probes",
                                                  "six_constants_max_condition")})
    return out


def _median(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else float("nan")


def pile_summary(pile: xr.Dataset, params: dict[str, Any], points: int = 5) -> dict[str, float]:
    """One number per quantity of one pile (:func:`pile_anisotropy`).

    Parameters
    ----------
    pile : xarray.Dataset
        :func:`pile_anisotropy` of the pile.
    params : dict
        The resolved analysis settings: ``history`` gives the core
        (``|x| <= shoulder_outer``, ``y <= core_height``), the centre and
        shoulder windows and the primary layer.
    points : int
        The fits (1 or 5 points) of everything but the identified shares,
        which are given for both.

    Returns
    -------
    dict
        ``core_fitted@m``, ``six_share@m`` (the share of the core RVEs with
        a fit that pin all six constants), ``condition@m``,
        ``condition_gravity@m`` (their medians over the core RVEs with a
        fit), for m = 1 and 5; at ``points``, medians over the core RVEs that
        pin all six: ``anisotropy``, ``axis_mirrored`` (the stiffest axis
        times the sign of x, so that mirror-image flanks agree),
        ``soft_axis_mirrored``, ``axis_to_fabric``, ``axis_to_stress``
        (mirrored likewise; the column x = 0 left out), ``abs_axis_to_fabric``, ``abs_axis_to_stress``,
        ``explained_{general,isotropic,cubic}``, ``{law}_{modulus}`` of
        every law, the ratios ``{a}/{b}:{modulus}`` of the laws' moduli at
        each RVE (isotropic, cubic and the Voigt stiffness against the
        general law; cubic against isotropic, also for the reduction
        alone; the Voigt stiffness against the reduction's isotropic law,
        the paper's), ``voigt_anisotropy`` and ``voigt_axis_to_fit``;
        ``stable:{law}``, the share of the core RVEs with a fit of the law
        where its K, G_p and G_b are positive (for the isotropic and cubic
        laws: where the law is positive definite); and
        ``centre:{law}_{modulus}``, the centre-over-shoulders contrast at
        the primary layer of the positive values of the modulus where all
        six constants are pinned (the reduction's laws wherever they are
        fitted, as the paper draws them; a mean over values of both signs
        would be no modulus).
    """
    h = params["history"]
    x, y = pile["x"].values, pile["y"].values
    core = (np.abs(x)[None, :] <= h["shoulder_outer"] + 1e-9) & (y[:, None] <= h["core_height"] + 1e-9)
    out: dict[str, float] = {}
    for m in (1, 5):
        fit = pile.sel(points=m)
        fitted = core & np.isfinite(fit["condition"].values)
        six = fitted & (fit["six_constants"].values == 1)
        out[f"core_fitted@{m}"] = float(fitted.sum())
        out[f"six_share@{m}"] = float(six.sum() / fitted.sum()) if fitted.any() else float("nan")
        for name in ("condition", "condition_gravity"):
            out[f"{name}@{m}"] = _median(fit[name].values[fitted])
    fit = pile.sel(points=points)
    six = fit["six_constants"].values == 1
    keep = core & six
    sign = np.where(x == 0, np.nan, np.sign(x))[None, :]        # the axis column has no mirror image
    for name in ("anisotropy", "explained_general", "explained_isotropic", "explained_cubic"):
        out[name] = _median(fit[name].values[keep])
    for name, var in (("axis_mirrored", "axis_deg"), ("soft_axis_mirrored", "soft_axis_deg"),
                      ("axis_to_fabric", "axis_to_fabric_deg"), ("axis_to_stress", "axis_to_stress_deg")):
        out[name] = _median((fit[var].values * sign)[keep])
    for name in ("axis_to_fabric", "axis_to_stress"):
        out[f"abs_{name}"] = _median(np.abs(fit[f"{name}_deg"].values)[keep])
    laws = [law for law in (*LAWS, "voigt") if f"{law}_K" in fit]
    for law in laws:
        for k in MODULI:
            out[f"{law}_{k}"] = _median(fit[f"{law}_{k}"].values[keep])
    pairs = [(a, "general") for a in laws if a != "general"] + [("cubic", "isotropic"),
                                                                 ("reduced_cubic", "reduced_isotropic")]
    if "voigt" in laws:
        pairs.append(("voigt", "reduced_isotropic"))
    for a, b in pairs:
        for k in MODULI:
            with np.errstate(divide="ignore", invalid="ignore"):
                out[f"{a}/{b}:{k}"] = _median((fit[f"{a}_{k}"].values / fit[f"{b}_{k}"].values)[keep])
    if "voigt_anisotropy" in fit:
        out["voigt_anisotropy"] = _median(fit["voigt_anisotropy"].values[keep])
        out["voigt_axis_to_fit"] = _median((fit["voigt_axis_to_fit_deg"].values * sign)[keep])
    for law in laws:
        fitted = core & np.isfinite(fit[f"{law}_K"].values)
        stable = fitted & np.all([fit[f"{law}_{k}"].values > 0 for k in ("K", "G_p", "G_b")], axis=0)
        out[f"stable:{law}"] = float(stable.sum() / fitted.sum()) if fitted.any() else float("nan")
        for k in MODULI:
            v = fit[f"{law}_{k}"].values
            v = np.where((v > 0) & (True if law.startswith("reduced_") else six), v, np.nan)
            out[f"centre:{law}_{k}"] = primary_contrast(v, y, x, h)
    return out


def primary_contrast(values: np.ndarray, y: np.ndarray, x: np.ndarray, history: dict[str, Any]) -> float:
    """Centre over shoulders − 1 (:func:`analysis.history.row_contrast`) of a field ``(y, x)``
    in the grid row nearest ``history["primary_height"]``."""
    return row_contrast(np.asarray(values)[int(np.argmin(np.abs(y - history["primary_height"])))], x, history)


def reduction_shear_contrast(fields: xr.Dataset, params: dict[str, Any], points: int = 5) -> float:
    """:func:`primary_contrast` of the shear modulus of the isotropic law fitted to a
    pile's gravity reduction, as :func:`pile_anisotropy` fits it (``reduced_isotropic_G_av``),
    from the pile's fields alone: the scale of its scatter over the study's piles,
    which have no stretch."""
    probe = xr.Dataset({k: fields[k].transpose("y", "x", "i", "j").expand_dims(probe=["reduced"])
                        for k in ("stress_increment", "strain_increment")})
    fit = general_fit_dataset([probe], params).sel(points=points)
    g = engineering_moduli(fit["stiffness_isotropic"].values)["G_av"]
    return primary_contrast(g, fields["y"].values, fields["x"].values, params["history"])
