"""Increments of every probe of a pile, and from them the general elastic fit
and the reversibility of the gravity reduction (#14).

Per pile (``python -m analysis probes``): for each probe stage (``reduced``,
``tiltpNN``, ``tiltmNN``, ``restored``, ...) the RVE stress increment and the
Cambou strain increment from the relaxed pile, on the grid and RVEs of the
fields (:func:`analysis.fields.rve_quantities`, membership on the relaxed
positions), in one file with a dimension ``probe``.

Over the piles of a protocol (``python -m analysis general-fit``):

* the **general fit** (:mod:`analysis.general_elastic`) of the ensemble-mean
  increments of the *loading* probes (every probe but ``restored``), with m = 1
  (the RVE alone: one sample per probe) and m = 5 points (the RVE and its four
  grid neighbours), its condition number, the stiffest axis and anisotropy
  ratio; standard errors from the same fit done pile by pile
  (``std/√n`` over the piles whose fit is identified);
* the **fractions explained** by the general law and by the paper's isotropic
  and cubic laws fitted to the same samples
  (:func:`analysis.general_elastic.explained_fraction`);
* the **reversibility** of the reduction: ``1 − |u(restored)| / |u(reduced)|``
  (Frobenius norms of the strain increments from the relaxed pile), 1 where
  the pile comes back to its relaxed shape (elastic), 0 where it keeps all
  of the reduction's strain; per pile, then mean and standard error.

Six constants.  A gravity change has two components, so in a linear pile the
strains of every reduction and tilt at a point span two shapes and the
sixth constant is pinned only by the non-linear part of their response
(:mod:`analysis.general_elastic`).  A probe of another kind, the support
stretch (stage ``stretched``), adds a third shape.  The file therefore gives,
besides the fit's ``condition`` over all loading probes, ``condition_gravity``
over the gravity probes alone, and ``six_constants``: 1 where the fit has
samples of a probe that is not a gravity change, is identified and
positive definite, and its condition number is at most
:data:`SIX_CONSTANTS_MAX_CONDITION`.  The per-pile fits are kept too
(dimension ``pile``: their condition numbers, stiffest axis and
anisotropy), and the stiffest axis is compared with the fabric and stress
axes of the ensemble (``axis_to_fabric_deg``, ``axis_to_stress_deg``).

Slips.  Where a pile slipped under a loading probe (its strain increment
more than ``analysis.ensemble.slip_strain_ratio`` times that pile's median
for that probe, :func:`analysis.ensemble.slipped`), that pile's increments of
that probe are left out of the fits there, as the paper's fits leave them
out (:func:`analysis.ensemble.leave_out_slips`): a slip is not an elastic
response.  The reversibility keeps every pile: a slip is exactly what it
should show (it comes back little).  ``slip_left_out`` counts the piles left
out per probe and RVE.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import xarray as xr

from . import general_elastic as ge
from .elastic import POINTS, fit_cubic_moduli, fit_isotropic_moduli, gather_points
from .ensemble import nan_mean_sem, slipped
from .errors import InputError
from .fields import rve_quantities
from .netcdf import tensor_coords, var
from .orientation import axis_angle_difference
from .rve import Grid
from .states import State, check_same_particles, pile_attributes

#: The probe whose increment, compared with the reduction's, measures reversibility.
RESTORED = "restored"

#: Stage names of the probes that change gravity (reductions and tilts): in a
#: linear pile their strains at a point span two shapes only.
GRAVITY_PROBE = re.compile(r"reduced(\d\d)?|tilt[pm]\d\d")

#: The largest condition number at which the general fit counts as pinning
#: all six constants (when a probe that is not a gravity change is among its
#: samples).  The condition number bounds how far the samples' relative misfit
#: to a linear law is amplified into the weakest combination of C; that
#: misfit, sqrt(1 - explained_general), is 13-16 % at m = 1 and about 30 % at
#: m = 5 in the smoke piles of config/scenes/six_constants.yaml, so at 10 the
#: worst case is already of order one, while the fits the stretch pins there
#: have a 90th percentile of 4.5-6.  It is the paper fits' threshold
#: (analysis.moduli.max_condition).  Gravity probes alone never qualify,
#: however low their condition number (docs/analysis.md, "All six constants").
SIX_CONSTANTS_MAX_CONDITION = 10.0


def probe_increments(relaxed: State, probes: dict[str, State], params: dict[str, Any]) -> xr.Dataset:
    """Stress and strain increments ``(probe, y, x, i, j)`` of each probe state from ``relaxed``.

    Parameters
    ----------
    relaxed : State
    probes : dict
        Stage name to its state (same particles as ``relaxed``).
    params : dict
        The analysis parameters (grid, rve, strain).
    """
    if not probes:
        raise InputError("probes: no probe state given")
    grid = Grid.from_params(params["grid"])
    ny, nx = grid.shape
    rp = params["rve"]
    stress, strain = [], []
    for stage, state in probes.items():
        check_same_particles(relaxed, state)
        q = rve_quantities(relaxed, state, grid.centres(), rp["shape"], rp["size"], params,
                           quantities=("strain",))
        stress.append(np.asarray(q["stress_increment"]).reshape(ny, nx, 2, 2))
        strain.append(np.asarray(q["strain_increment"]).reshape(ny, nx, 2, 2))
    coords = {
        "probe": var("probe", np.array(list(probes), dtype=object), "probe stage (from the relaxed pile)", "1"),
        "y": var("y", grid.y, "height of the RVE centre above the support", "m", axis="Y"),
        "x": var("x", grid.x, "horizontal position of the RVE centre (0 at the pouring axis)", "m", axis="X"),
        **tensor_coords(),
    }
    dims = ("probe", "y", "x", "i", "j")
    ds = xr.Dataset({
        "stress_increment": var(dims, np.array(stress), "RVE stress of the probe minus the relaxed one", "N/m"),
        "strain_increment": var(dims, np.array(strain), "Cambou best-fit strain (symmetric part), relaxed -> probe",
                                "1"),
    }, coords=coords)
    ds.attrs.update({"rve_shape": rp["shape"], "rve_size": rp["size"], "grid_spacing": params["grid"]["spacing"],
                     **pile_attributes(relaxed), "relaxed_file": relaxed.path})
    return ds


def _samples(stress: np.ndarray, strain: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Samples ``(ny, nx, n_probes * m, 2, 2)`` of probe fields ``(probe, ny, nx, 2, 2)``."""
    sig = np.concatenate([gather_points(s, m) for s in stress], axis=2)
    u = np.concatenate([gather_points(e, m) for e in strain], axis=2)
    return sig, u


def _fit(stress: np.ndarray, strain: np.ndarray, m: int, min_samples: int) -> dict[str, np.ndarray]:
    """General fit, axes and explained fractions on one set of probe fields."""
    sig, u = _samples(stress, strain, m)
    fit = ge.fit_general_stiffness(sig, u, min_samples=min_samples)
    axes = ge.stiffness_axes(fit["stiffness"])
    K, G, _ = fit_isotropic_moduli(sig, u, min_points=min_samples)
    l1, l2, l3, _ = fit_cubic_moduli(sig, u, min_points=min_samples)
    iso, cub = ge.isotropic_stiffness(K, G), ge.cubic_stiffness(l1, l2, l3)
    return {**fit, **axes, "stiffness_isotropic": iso, "stiffness_cubic": cub,
            "explained_general": ge.explained_fraction(fit["stiffness"], sig, u),
            "explained_isotropic": ge.explained_fraction(iso, sig, u),
            "explained_cubic": ge.explained_fraction(cub, sig, u)}


def _add_gravity_only(fit: dict, stress: np.ndarray, strain: np.ndarray, gravity: list[int], m: int,
                      need: int) -> None:
    """Add to ``fit`` the condition number of the gravity probes alone
    (``condition_gravity``; inf without any) and their valid samples
    (``n_gravity``), from probe fields ``(probe, y, x, 2, 2)``."""
    if gravity:
        sig, u = _samples(stress[gravity], strain[gravity], m)
        g = ge.fit_general_stiffness(sig, u, min_samples=need)
        fit["condition_gravity"], fit["n_gravity"] = g["condition"], g["n_samples"]
    else:
        fit["condition_gravity"] = np.full(fit["condition"].shape, np.inf)
        fit["n_gravity"] = np.zeros(fit["condition"].shape, dtype=int)


def six_constants(fit: dict, has_other: bool,
                  max_condition: float = SIX_CONSTANTS_MAX_CONDITION) -> np.ndarray:
    """Where a general fit (:func:`_fit` with :func:`_add_gravity_only`) pins
    all six constants: it has valid samples of a probe that is not a gravity
    change (``has_other`` and more samples than the gravity probes alone),
    is identified and positive definite (flag 0), and its condition number
    is at most ``max_condition``.  Gravity probes alone never qualify: their
    sixth constant rests on the non-linear part of the response, however
    well conditioned the fit looks (module docstring)."""
    if not has_other:
        return np.zeros(fit["condition"].shape, dtype=bool)
    return ((fit["n_samples"] > fit["n_gravity"]) & (fit["flag"] == 0)
            & (fit["condition"] <= max_condition))


def reversibility(strain: np.ndarray, probes: list[str]) -> np.ndarray:
    """``1 − |u(restored)| / |u(reduced)|`` per RVE from probe strains ``(..., probe, ny, nx, 2, 2)``.

    NaN without both probes or where the reduction's strain is zero.
    """
    if RESTORED not in probes or "reduced" not in probes:
        return np.full(strain.shape[-4:-2], np.nan)
    back = np.linalg.norm(strain[..., probes.index(RESTORED), :, :, :, :], axis=(-2, -1))
    there = np.linalg.norm(strain[..., probes.index("reduced"), :, :, :, :], axis=(-2, -1))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 1.0 - back / there
    return np.where(np.isfinite(out), out, np.nan)



#: Depth bands (m below the top filled RVE of each grid column) of :func:`reversibility_by_depth`.
DEPTHS = (0.0, 0.03, 0.06, 0.10, np.inf)


def reversibility_by_depth(rev: np.ndarray, y: np.ndarray) -> list[tuple[float, float, float, float, int]]:
    """The reversibility (:func:`reversibility`, ``(y, x)``) by depth below the surface.

    A column's surface is its top filled RVE (finite reversibility); per band
    of :data:`DEPTHS` below it that holds an RVE: the band's edges (m), the
    median reversibility, its 10 % quantile and the RVEs in the band.
    """
    filled = np.isfinite(rev)
    top = np.array([y[filled[:, j]].max() if filled[:, j].any() else np.nan for j in range(rev.shape[1])])
    depth = top[None, :] - y[:, None]
    out = []
    for lo, hi in zip(DEPTHS[:-1], DEPTHS[1:]):
        band = filled & (depth >= lo) & (depth < hi)
        if band.any():
            out.append((lo, hi, float(np.median(rev[band])), float(np.percentile(rev[band], 10)), int(band.sum())))
    return out


def tilt_asymmetry(pr: xr.Dataset, name: str) -> np.ndarray | None:
    """``|Δ(+) + Δ(−)| / (|Δ(+)| + |Δ(−)|)`` per RVE of the increment `name` of a pile's opposite
    tilts (the first pair of tiltpNN / tiltmNN probes of its ``probes.nc``): 0 in a linear pile;
    None without such a pair."""
    probes = [str(p) for p in pr["probe"].values]
    plus = [p for p in probes if p.startswith("tiltp")]
    minus = [p.replace("tiltp", "tiltm") for p in plus]
    if not plus or minus[0] not in probes:
        return None
    a, b = pr[name].sel(probe=plus[0]).values, pr[name].sel(probe=minus[0]).values
    norm_a, norm_b = np.linalg.norm(a, axis=(-2, -1)), np.linalg.norm(b, axis=(-2, -1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.norm(a + b, axis=(-2, -1)) / (norm_a + norm_b)


def general_fit_summary(gm: xr.Dataset) -> dict[str, Any]:
    """What an ensemble's general fits show (its ``general_moduli.nc``, :func:`general_fit_dataset`).

    Returns
    -------
    dict
        ``slips``: the pile-probe-RVEs left out as slipped; per m of 1 and 5 in
        ``fits``: ``identified`` (RVEs whose fit is identified and positive
        definite), ``tried`` (RVEs with enough samples for a fit) and
        ``condition`` (the median condition number over those); at m = 5 over
        the identified RVEs (None without one) in ``m5``: ``explained`` (per
        law, the median fraction of the stress increments it explains),
        ``anisotropy`` (median ``E_max / E_min``) and ``axes`` (per field axis
        present, the unsigned angle between it and the stiffest axis, mean
        and count, :func:`analysis.orientation.axis_angle_difference`);
        ``reversibility`` (10 %, 50 % and 90 % quantiles and the count over
        RVEs, None without one) and ``by_depth`` (:func:`reversibility_by_depth`).
    """
    flags = gm["general_flag"].attrs
    few = int(dict(zip(flags["flag_meanings"].split(), flags["flag_masks"]))["insufficient_samples"])
    out: dict[str, Any] = {"slips": int(gm["slip_left_out"].sum()), "fits": {}, "m5": None}
    for m in (1, 5):
        fit = gm.sel(points=m)
        tried = (fit["general_flag"].values & few) == 0           # enough samples for a fit
        out["fits"][m] = {"identified": int((fit["general_flag"].values == 0).sum()), "tried": int(tried.sum()),
                          "condition": float(np.median(fit["condition"].values[tried]))}
    fit = gm.sel(points=5)
    ok = fit["general_flag"].values == 0
    if ok.any():
        axis = np.where(ok, fit["axis_deg"].values, np.nan)
        gaps = {name: np.abs(axis_angle_difference(axis, gm[name].values)) for name in AXES_FROM_FIELDS if name in gm}
        out["m5"] = {"explained": {law: float(np.median(fit[f"explained_{law}"].values[ok]))
                                   for law in ("general", "cubic", "isotropic")},
                     "anisotropy": float(np.median(fit["anisotropy"].values[ok])),
                     "axes": {name: (float(np.nanmean(g)) if np.isfinite(g).any() else np.nan, int(np.isfinite(g).sum()))
                              for name, g in gaps.items()}}
    rev = gm["reversibility"].values
    out["reversibility"] = (*(float(v) for v in np.nanpercentile(rev, [10, 50, 90])), int(np.isfinite(rev).sum())) \
        if np.isfinite(rev).any() else None
    out["by_depth"] = reversibility_by_depth(rev, gm["y"].values) if np.isfinite(rev).any() else []
    return out


#: The gravity reductions of the probe-level scenes, by probe stage.
LEVELS = {"reduced05": 0.05, "reduced": 0.10, "reduced15": 0.15}


def level_of(stage: str) -> float:
    """The reduction of a probe stage (``reduced`` is 10 %, ``reducedNN`` NN %)."""
    return LEVELS[stage]


def pile_levels(pr: xr.Dataset, params: dict) -> dict:
    """Is one pile's probe response linear in the gravity reduction (``config/scenes/probe_levels.yaml``)?

    From the pile's ``probes.nc``: ``compliance``, per reduction of
    :data:`LEVELS`, the median over the core RVEs (``analysis.history``:
    ``|x| <= shoulder_outer``, ``y <= core_height``) of ``u_yy / Delta``;
    ``linearity``, ``c(Delta) / c(10 %) - 1`` at the other levels (0 for a pile
    that answers in proportion); ``slips``, per probe the RVEs of
    :func:`analysis.ensemble.slipped`; ``reversibility``, the median over RVEs
    of :func:`reversibility`.
    """
    h = params["history"]
    probes = [str(p) for p in pr["probe"].values]
    x, y = pr["x"].values, pr["y"].values
    core = (np.abs(x)[None, :] <= h["shoulder_outer"] + 1e-9) & (y[:, None] <= h["core_height"] + 1e-9)
    strain = pr["strain_increment"].transpose("probe", "y", "x", "i", "j").values
    ratio = params["ensemble"]["slip_strain_ratio"]
    out = {"compliance": {}, "slips": {}}
    for k, stage in enumerate(probes):
        u = strain[k]
        out["slips"][stage] = int(slipped(u, ratio).sum())
        if stage in LEVELS:
            uyy = np.where(core, u[..., 1, 1], np.nan) / level_of(stage)
            finite = uyy[np.isfinite(uyy)]
            out["compliance"][stage] = float(np.median(finite)) if finite.size else float("nan")
    base = out["compliance"].get("reduced", float("nan"))
    out["linearity"] = {s: c / base - 1.0 for s, c in out["compliance"].items() if s != "reduced"}
    rev = reversibility(strain, probes)
    out["reversibility"] = float(np.nanmedian(rev)) if np.isfinite(rev).any() else float("nan")
    return out


SCALARS = ("condition", "axis_deg", "E_max", "E_min", "anisotropy", "explained_general",
           "explained_isotropic", "explained_cubic")
#: Scalars of each pile's own fit kept per pile (dimension ``pile``).
PILE_SCALARS = ("condition", "condition_gravity", "axis_deg", "soft_axis_deg", "anisotropy")
#: Angles whose standard error over piles is taken on the deviations of each
#: pile's angle from the ensemble fit's, folded into (-90, 90] (axes have no sign).
AXIS_SCALARS = ("axis_deg", "soft_axis_deg")
#: The scalars of the general fit with a standard error over piles.
FIT_SCALARS = SCALARS + ("condition_gravity", "soft_axis_deg")
META = {
    "stiffness": ("general symmetric stiffness in Mandel notation (xx, yy, sqrt2 xy), dsigma_M = C du_M", "N/m"),
    "condition": ("condition number of the fit's design matrix (strains only); above max_condition: not "
                  "identified", "1"),
    "condition_gravity": ("condition number of the fit of the gravity probes alone (reductions and tilts)", "1"),
    "axis_deg": ("direction of the largest uniaxial Young's modulus, from the vertical, counter-clockwise", "degree"),
    "soft_axis_deg": ("direction of the smallest uniaxial Young's modulus, from the vertical, counter-clockwise",
                      "degree"),
    "E_max": ("largest uniaxial Young's modulus over directions", "N/m"),
    "E_min": ("smallest uniaxial Young's modulus over directions", "N/m"),
    "anisotropy": ("E_max / E_min", "1"),
    "explained_general": ("fraction of the stress increments explained by the general law", "1"),
    "explained_isotropic": ("fraction of the stress increments explained by the isotropic law (Eq. 21 fit)", "1"),
    "explained_cubic": ("fraction of the stress increments explained by the cubic law (Eq. 16 fit)", "1"),
    "reversibility": ("1 - |u(restored)| / |u(reduced)|: the part of the reduction's strain that comes back", "1"),
}


#: The paper's laws fitted to the same samples as the general one (Mandel stiffness, unmasked).
LAW_STIFFNESS = {
    "stiffness_isotropic": "Mandel stiffness of the isotropic law (K, G minimising S', Eq. 21) fitted to the same "
                           "samples",
    "stiffness_cubic": "Mandel stiffness of the cubic law (lambda1-3 minimising S, Eq. 16) fitted to the same samples",
}

#: Orientations of the ensemble fields copied next to the stiffness axis.
AXES_FROM_FIELDS = ("fabric_orientation", "stress_orientation")


def general_fit_dataset(piles: list[xr.Dataset], params: dict[str, Any],
                        ensemble: xr.Dataset | None = None) -> xr.Dataset:
    """The general fit of the ensemble-mean probe increments, with standard errors over piles.

    Parameters
    ----------
    piles : list of xarray.Dataset
        Per-pile files of :func:`probe_increments`, all with the same probes
        and grid.
    params : dict
        The analysis parameters (``moduli.min_points`` as the least number
        of valid samples at m = 5; ``ensemble.slip_strain_ratio``, see the
        module docstring).
    ensemble : xarray.Dataset, optional
        The protocol's ensemble fields: their fabric and stress orientations
        (:data:`AXES_FROM_FIELDS`) are copied in, to compare with the
        stiffness axis.

    Returns
    -------
    xarray.Dataset
    """
    probes, loading, gravity, other = _probe_groups(piles)
    stress = np.stack([ds["stress_increment"].values for ds in piles])        # (pile, probe, y, x, 2, 2)
    strain = np.stack([ds["strain_increment"].values for ds in piles])
    rev_each = np.stack([reversibility(strain[k], probes) for k in range(len(piles))])
    ratio = params["ensemble"]["slip_strain_ratio"]
    left_out = np.zeros(strain.shape[:4], dtype=bool)                      # (pile, probe, y, x)
    for k in range(len(piles)):
        for p in loading:
            left_out[k, p] = slipped(strain[k, p], ratio)
    stress = np.where(left_out[..., None, None], np.nan, stress)
    strain = np.where(left_out[..., None, None], np.nan, strain)
    out = _fits_by_points(stress, strain, loading, gravity, bool(other), params)
    rev_mean, rev_sem, rev_count = nan_mean_sem(rev_each)
    stiffness, scalars = _fit_variables(out)
    data = {
        **stiffness,
        "reversibility": var(("y", "x"), rev_mean, *META["reversibility"]),
        "reversibility_sem": var(("y", "x"), rev_sem, "standard error of reversibility over piles", "1"),
        "reversibility_count": var(("y", "x"), rev_count, "piles with a reversibility at this RVE", "1"),
        "slip_left_out": var(("probe", "y", "x"), left_out.sum(axis=0).astype(np.int32),
                             "piles left out of the fits at this RVE for this probe: they slipped", "1"),
        **scalars,
    }
    ds = xr.Dataset(data, coords=_general_fit_coords(piles, probes))
    if ensemble is not None:
        _add_field_axes(ds, ensemble)
    ref = piles[0]
    ds.attrs.update({"probes": " ".join(probes), "loading_probes": " ".join(probes[k] for k in loading),
                     "gravity_probes": " ".join(probes[k] for k in gravity),
                     "other_probes": " ".join(probes[k] for k in other),
                     "six_constants_max_condition": SIX_CONSTANTS_MAX_CONDITION,
                     "n_seeds": len(piles), "max_condition": ge.MAX_CONDITION,
                     "slip_strain_ratio": "none" if ratio is None else float(ratio),
                     "slip_left_out_total": int(left_out.sum()),
                     "protocol": ref.attrs.get("protocol", ""), "rve_size": ref.attrs.get("rve_size", "")})
    return ds


def _probe_groups(piles):
    """The probes of the piles' files and their indices by kind.

    Parameters
    ----------
    piles : list of xarray.Dataset
        Per-pile files of :func:`probe_increments`.

    Returns
    -------
    probes : list of str
        The probe stages, in the files' order.
    loading, gravity, other : list of int
        Indices into `probes` of the loading probes (all but ``restored``),
        of those among them that change gravity, and of the others.

    Raises
    ------
    InputError
        When two piles' files differ in probes or grid.
    """
    probes = [str(p) for p in piles[0]["probe"].values]
    for ds in piles[1:]:
        if [str(p) for p in ds["probe"].values] != probes or ds.sizes != piles[0].sizes:
            raise InputError("general-fit: the piles' probe files differ in probes or grid "
                             f"({probes} against {[str(p) for p in ds['probe'].values]})")
    loading = [k for k, p in enumerate(probes) if p != RESTORED]
    gravity = [k for k in loading if GRAVITY_PROBE.fullmatch(probes[k])]
    other = [k for k in loading if k not in gravity]
    return probes, loading, gravity, other


def _fits_by_points(stress, strain, loading, gravity, has_other, params):
    """The general fit of the mean increments and of each pile's, for every m in :data:`POINTS`.

    Parameters
    ----------
    stress, strain : ndarray, shape (pile, probe, y, x, 2, 2)
        The increments of every pile, NaN where a pile slipped.
    loading, gravity : list of int
        Indices of the loading probes and of the gravity probes among them.
    has_other : bool
        Whether a loading probe is not a gravity change.
    params : dict
        The analysis parameters (``moduli.min_points``).

    Returns
    -------
    dict of str to list
        Per name (stiffness and the laws' stiffnesses, their standard error,
        flags, sample counts, the six-constants masks, :data:`FIT_SCALARS`
        and their standard errors, the per-pile :data:`PILE_SCALARS`), one
        array per m.
    """
    mean_stress, _, _ = nan_mean_sem(stress)
    mean_strain, _, _ = nan_mean_sem(strain)
    out: dict[str, list] = {name: [] for name in ("stiffness", *LAW_STIFFNESS, "stiffness_sem", "flag", "n_samples",
                                                  "six", "six_piles", *FIT_SCALARS,
                                                  *[f"{s}_sem" for s in FIT_SCALARS],
                                                  *[f"{s}_pile" for s in PILE_SCALARS])}
    for m in POINTS:
        need = max(ge.MIN_SAMPLES, 1 if m == 1 else params["moduli"]["min_points"])
        whole = _fit(mean_stress[loading], mean_strain[loading], m, need)
        _add_gravity_only(whole, mean_stress, mean_strain, gravity, m, need)
        each = [_fit(stress[k][loading], strain[k][loading], m, need) for k in range(stress.shape[0])]
        for k, e in enumerate(each):
            _add_gravity_only(e, stress[k], strain[k], gravity, m, need)
        for name in ("stiffness", *LAW_STIFFNESS):
            out[name].append(whole[name])
        out["stiffness_sem"].append(nan_mean_sem(np.stack([e["stiffness"] for e in each]))[1])
        out["flag"].append(whole["flag"])
        out["n_samples"].append(whole["n_samples"])
        out["six"].append(six_constants(whole, has_other))
        out["six_piles"].append(np.sum([six_constants(e, has_other) for e in each], axis=0))
        for s in FIT_SCALARS:
            out[s].append(whole[s])
            per_pile = np.stack([e[s] for e in each])
            if s in AXIS_SCALARS:
                per_pile = axis_angle_difference(per_pile, whole[s])
            out[f"{s}_sem"].append(nan_mean_sem(per_pile)[1])
        for s in PILE_SCALARS:
            out[f"{s}_pile"].append(np.stack([e[s] for e in each]))
    return out


def _fit_variables(out):
    """The general fit's variables of the output file, in two groups.

    Parameters
    ----------
    out : dict of str to list
        The fits by points (:func:`_fits_by_points`).

    Returns
    -------
    stiffness : dict of str to xarray.Variable
        The stiffness matrices, their standard error, flags and sample counts.
    scalars : dict of str to xarray.Variable
        The scalars with their standard errors, the per-pile scalars and the
        six-constants masks.
    """
    stiffness = {
        "stiffness": var(("points", "y", "x", "mandel_i", "mandel_j"), np.array(out["stiffness"]),
                         *META["stiffness"]),
        **{name: var(("points", "y", "x", "mandel_i", "mandel_j"), np.array(out[name]), text, "N/m")
           for name, text in LAW_STIFFNESS.items()},
        "stiffness_sem": var(("points", "y", "x", "mandel_i", "mandel_j"), np.array(out["stiffness_sem"]),
                             "standard error of stiffness over pile-by-pile fits", "N/m"),
        "general_flag": var(("points", "y", "x"), np.array(out["flag"]), "general fit flags", "1",
                            **ge.GENERAL_FLAGS),
        "n_samples": var(("points", "y", "x"), np.array(out["n_samples"]), "valid samples (probes x points)",
                         "1"),
    }
    data = {}
    for s in FIT_SCALARS:
        ln, units = META[s]
        data[s] = var(("points", "y", "x"), np.array(out[s]), ln, units)
        how = ("of the piles' angles from this one, folded into (-90, 90]" if s in AXIS_SCALARS
               else "over pile-by-pile fits")
        data[f"{s}_sem"] = var(("points", "y", "x"), np.array(out[f"{s}_sem"]),
                               f"standard error of {s} {how}", units)
    for s in PILE_SCALARS:
        ln, units = META[s]
        data[f"{s}_pile"] = var(("points", "pile", "y", "x"), np.array(out[f"{s}_pile"]),
                                f"{ln}: each pile's own fit", units)
    data["six_constants"] = var(("points", "y", "x"), np.array(out["six"], dtype=np.int8),
                                "1 where the fit pins all six constants: a probe that is not a gravity change among "
                                "its samples, identified, positive definite and condition <= six_constants_max_condition",
                                "1")
    data["six_constants_piles"] = var(("points", "y", "x"), np.array(out["six_piles"], dtype=np.int32),
                                      "piles whose own fit pins all six constants here (as six_constants)", "1")
    return stiffness, data


def _general_fit_coords(piles, probes):
    """The coordinates of the general fit's file: points, pile labels, the
    piles' grid, probes and Mandel components.

    Parameters
    ----------
    piles : list of xarray.Dataset
        Per-pile files of :func:`probe_increments`.
    probes : list of str
        Their probe stages.

    Returns
    -------
    dict of str to xarray.Variable
    """
    ref = piles[0]
    labels = [f"{ds.attrs.get('protocol', '')} seed {ds.attrs.get('seed', k)}".strip() for k, ds in enumerate(piles)]
    return {"points": var("points", np.array(POINTS), "RVE points per fit (1: the RVE, 5: and its 4 "
                                                      "grid neighbours)", "1"),
            "pile": var("pile", np.array(labels, dtype=object), "the pile of a per-pile fit", "1"),
            "y": ref["y"].variable, "x": ref["x"].variable,
            "probe": var("probe", np.array(probes, dtype=object), "probe stage", "1"),
            "mandel_i": var("mandel_i", np.array(["xx", "yy", "xy"], dtype=object), "Mandel component", "1"),
            "mandel_j": var("mandel_j", np.array(["xx", "yy", "xy"], dtype=object), "Mandel component", "1")}


def _add_field_axes(ds, ensemble):
    """Copy the ensemble's fabric and stress orientations (:data:`AXES_FROM_FIELDS`)
    into `ds`, each with the stiffest axis's angle from it.

    Parameters
    ----------
    ds : xarray.Dataset
        The general fit (modified in place).
    ensemble : xarray.Dataset
        The protocol's ensemble fields.

    Raises
    ------
    InputError
        When an orientation lies on another grid than the fit.
    """
    for name in AXES_FROM_FIELDS:
        if name in ensemble:
            if ensemble[name].shape != ds["reversibility"].shape:
                raise InputError(f"general-fit: the ensemble's {name} is on another grid")
            ds[name] = ensemble[name].variable
            gap = axis_angle_difference(ds["axis_deg"].values, ensemble[name].values[None])
            what = name.split("_")[0]
            ds[f"axis_to_{what}_deg"] = var(("points", "y", "x"), gap,
                                            f"stiffest axis minus the ensemble's {what} axis, folded into "
                                            "(-90, 90]", "degree")
