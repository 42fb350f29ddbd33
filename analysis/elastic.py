"""Local elastic constants from incremental stress and strain (paper Sect. 5, Eqs 16–22).

Data: two estimates side by side (issue 27). **Per pile**: each pile's own
fits at each RVE, then ``<name>_pile_mean``, their mean over the piles whose
own fit is valid there, with ``<name>_sem``, the standard error over those
piles (``analysis.moduli.uncertainty: pile_fits``; ``bootstrap``: the standard
deviation of the fits to bootstrap resamples of the seeds instead).
**Ensemble**: ``<name>``, the same fits of the **ensemble-averaged**
incremental fields (``stress_increment``, ``strain_increment`` of
``results/ensemble/{protocol}/fields.nc``), the paper's way, kept for the
comparison with it. The per-pile fields leave out the RVEs where a pile slipped
under the probe, as the ensemble does (``analysis.ensemble.slip_strain_ratio``,
:func:`analysis.ensemble.leave_out_slips`). The sign of both increments (unloading, reduced − relaxed)
cancels in every modulus.

Points: ``m = 1`` uses the RVE centre itself; ``m = 5`` uses the centre and
its four nearest grid neighbours (±spacing in x and y; with the default 1.5 cm
spacing and 8 cm RVEs these are points "near the centre of the RVE"), of
which at least ``analysis.moduli.min_points`` must be valid.

Two ways of fitting, as in the paper, plus their average:

* ``compliance``: minimise the compliance sum S̃ (Eq. 18, cubic: Eq. 19, then
  Eq. 20); for the isotropic model S̃ restricted to ``s3 = s1 − s2`` (the
  compliance analogue of S′).
* ``modulus``: minimise S (Eq. 16) restricted to cubic symmetry
  (``lambda_xxxy = lambda_xyyy = 0``, ``lambda_yyyy = lambda_xxxx``), and S′
  (Eq. 21, solution Eq. 22) for the isotropic model.
* ``average``: the mean of the two for every reported quantity.

Notes on the paper's formulas (documented, tested in tests/test_analysis_elastic.py):

* ``E = 3G − G²/K`` (``youngs_modulus``, as in the paper and docs/formats.md) is
  the 3D relation with the 2D Lamé constant ``lambda = K − G``; the 2D
  Young's modulus of an isotropic sheet is ``4KG/(K + G)``
  (``youngs_modulus_2d``), which is what ``E_p`` and ``E_b`` reduce to in the
  isotropic limit. The two agree only for K = G.
* The paper's ``E_b = lambda1 + lambda2`` is the response to equal biaxial
  strain, not the uniaxial Young's modulus along the bisectors. Rotating the
  cubic stiffness by 45° gives ``E_b = 4 lambda3 (lambda1 + lambda2) / (lambda1 + lambda2 + 2 lambda3)``,
  reported as ``E_b`` (and ``E_av = (E_p + E_b)/2``); the printed
  expressions are kept as ``E_b_paper`` and ``E_av_paper``. They coincide when
  ``lambda3 = (lambda1 + lambda2)/2``.

Degenerate data (fewer valid points than required, a zero denominator such
as all-zero strain, or a non-finite result) give NaN and a flag, never inf.

Positive definiteness and conditioning (:func:`fit_quality`). Both laws are
diagonal in the Mandel basis (``u_M = (u_xx, u_yy, √2 u_xy)``, as in
:mod:`analysis.general_elastic`), with the **mode stiffnesses**

* isotropic: ``2K`` (volumetric, ``u_xx + u_yy``) and ``2G`` (twice: ``u_xx − u_yy`` and ``u_xy``);
* cubic: ``λ1 + λ2`` (volumetric), ``λ1 − λ2`` (``u_xx − u_yy``) and ``2λ3`` (``u_xy``),

since the energy density of the cubic law (Eq. 13 with Eq. 15's cubic terms) is
``W = ½[λ1(u_xx² + u_yy²) + 2λ2 u_xx u_yy + 4λ3 u_xy²]
= ¼(λ1 + λ2)(u_xx + u_yy)² + ¼(λ1 − λ2)(u_xx − u_yy)² + 2λ3 u_xy²``.
A fitted law is a stable material (every strain costs energy) only if every
mode stiffness is positive: **K > 0 and G > 0**; for the cubic law
**λ1 > |λ2| and λ3 > 0** (λ1 + λ2 > 0 and λ1 − λ2 > 0). ``λ2 < 0`` is allowed
(a negative Poisson ratio), so ``λ1 > 0, λ2 > 0`` is neither necessary nor
sufficient. A fit that is not positive definite is masked
(``not_positive_definite``): a negative modulus of a pile at rest is a failed
fit, not a material property.

The **condition number** of a fit is ``κ = max|μ| / min|μ|`` over its mode
stiffnesses μ: the 2-norm condition number of the fitted Mandel stiffness and
equally of its inverse, the compliance. It is the conditioning of the inversion
that turns the fitted compliances into moduli (Eq. 20): the 2 × 2 block
``[[s1, s2], [s2, s1]]`` has the determinant ``s1² − s2² = (s1 + s2)(s1 − s2)``
and the condition number ``|s1 + s2| / |s1 − s2|`` (or its inverse), so
``λ1 = s1/(s1² − s2²)`` diverges exactly as κ does, and a compliance error δ on
the scale of the largest compliance gives the stiffest modulus a relative error
κ δ / max|s|; read the other way (an error on the scale of the stiffest
modulus), it is the relative error of the softest one in the fits of moduli.
The design matrix of the least-squares problems (Eqs 16, 18, 21) is not used:
each mode is its own one-parameter regression (the normal equations are
diagonal, Eqs 19, 22), so the design's condition number only compares the
sizes of the strain (or stress) modes, e.g. ``√(<(tr u)²> / <(u_xx − u_yy)² + 4u_xy²>)``
for S′, which stays finite however far a mode's stress and strain decorrelate,
and at m = 1 every cubic mode has one sample. A fit with ``κ`` above
``analysis.moduli.max_condition`` is masked (``ill_conditioned``). E, E_p, E_b,
E_av, G_av are harmonic or arithmetic means of mode stiffnesses, hence bounded
by them once the fit is positive definite and well conditioned; so are the means
over piles of valid fits (every mode stiffness is linear in the fitted
constants, with fixed eigenvectors), which need no second test.

Masking (``isotropic_mask_reason``, ``cubic_mask_reason``, bits
:data:`MASK_REASON_FLAGS`): a masked fit has NaN in every quantity of its law;
its condition number is kept. The ``average`` of the two fitting methods is
masked where either is.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from .general_elastic import cubic_stiffness, isotropic_stiffness, positive_definite
from .params import DEFAULTS

FIT_INSUFFICIENT_POINTS = 1
FIT_DEGENERATE = 2
FIT_NONFINITE = 4
FIT_ILL_CONDITIONED = 8
FIT_NOT_POSITIVE = 16
FIT_FEW_PILES = 32
MASK_REASON_FLAGS = {"flag_masks": np.array([1, 2, 4, 8, 16, 32], dtype=np.int32),
                     "flag_meanings": "insufficient_points degenerate_denominator non_finite_result "
                                      "ill_conditioned not_positive_definite few_valid_piles"}

#: The schema's defaults of ``analysis.moduli`` (the defaults of the functions below).
_DEFAULT = DEFAULTS["moduli"]

FITS = ("compliance", "modulus", "average")
POINTS = (1, 5)
ISOTROPIC = ("bulk_modulus", "shear_modulus", "youngs_modulus", "youngs_modulus_2d")
CUBIC = ("lambda1", "lambda2", "lambda3", "s1", "s2", "s3", "bulk_modulus_cubic", "E_p", "E_b", "E_av",
         "G_p", "G_b", "G_av", "E_b_paper", "E_av_paper")
#: The quantities of each law, which share its mask.
LAWS = {"isotropic": ISOTROPIC, "cubic": CUBIC}


# ---------------------------------------------------------------- helpers
def _components(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """xx, yy and the symmetrised xy component of tensors ``(..., 2, 2)``."""
    return t[..., 0, 0], t[..., 1, 1], 0.5 * (t[..., 0, 1] + t[..., 1, 0])


class _Moments:
    """Averages ``<A B>`` over the valid points (last axis) of stress/strain samples."""

    def __init__(self, sigma: np.ndarray, u: np.ndarray):
        sxx, syy, sxy = _components(np.asarray(sigma, float))
        uxx, uyy, uxy = _components(np.asarray(u, float))
        valid = np.isfinite(sxx) & np.isfinite(syy) & np.isfinite(sxy)
        valid &= np.isfinite(uxx) & np.isfinite(uyy) & np.isfinite(uxy)
        self.n = valid.sum(axis=-1)
        z = lambda a: np.where(valid, a, 0.0)  # noqa: E731
        self.T, self.D, self.S = z(sxx + syy), z(sxx - syy), z(sxy)  # trace, difference, shear of stress
        self.t, self.d, self.e = z(uxx + uyy), z(uxx - uyy), z(uxy)  # same for strain

    def mean(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sum(a * b, axis=-1) / self.n


def _ratio(num: np.ndarray, den: np.ndarray, scale: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """``num/den`` with NaN and a flag where ``|den| <= rtol*scale`` (or zero) or the result is not finite."""
    num, den, scale = np.broadcast_arrays(np.asarray(num, float), np.asarray(den, float), np.asarray(scale, float))
    degenerate = ~(np.abs(den) > rtol * np.abs(scale)) | (den == 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        val = num / np.where(degenerate, 1.0, den)
    nonfinite = ~np.isfinite(val) & ~degenerate
    flag = np.where(degenerate, FIT_DEGENERATE, 0) | np.where(nonfinite, FIT_NONFINITE, 0)
    return np.where(flag == 0, val, np.nan), flag.astype(np.int32)


def _finalise(values: list[np.ndarray], flag: np.ndarray, n: np.ndarray, min_points: int):
    flag = flag | np.where(n < min_points, FIT_INSUFFICIENT_POINTS, 0).astype(np.int32)
    bad = flag != 0
    return [np.where(bad, np.nan, v) for v in values] + [flag.astype(np.int32)]


# ---------------------------------------------------------------- fits, one equation each
def fit_isotropic_moduli(sigma: np.ndarray, u: np.ndarray, min_points: int = 1, rtol: float = 1e-12):
    """Bulk and shear modulus minimising S′ (Eq. 21), i.e. Eq. 22.

    ``K = <tr σ tr u> / (2 <(tr u)²>)``,
    ``G = (<(σxx−σyy)(uxx−uyy)> + 4<σxy uxy>) / (2(<(uxx−uyy)²> + 4<uxy²>))``.
    Samples are along the last axis before the tensor axes: ``(..., m, 2, 2)``.
    Returns ``(K, G, flag)``.
    """
    m = _Moments(sigma, u)
    scale = m.mean(m.t, m.t) + m.mean(m.d, m.d) + 4 * m.mean(m.e, m.e)
    K, f1 = _ratio(m.mean(m.T, m.t), 2 * m.mean(m.t, m.t), scale, rtol)
    G, f2 = _ratio(m.mean(m.D, m.d) + 4 * m.mean(m.S, m.e), 2 * (m.mean(m.d, m.d) + 4 * m.mean(m.e, m.e)), scale, rtol)
    return tuple(_finalise([K, G], f1 | f2, m.n, min_points))


def fit_isotropic_compliances(sigma: np.ndarray, u: np.ndarray, min_points: int = 1, rtol: float = 1e-12):
    """Bulk and shear modulus minimising S̃ (Eq. 18) restricted to isotropy, ``s3 = s1 − s2``.

    With ``a = s1 + s2 = 1/(2K)`` and ``b = s1 − s2 = s3 = 1/(2G)``,
    ``S̃ = ½ Σ [(tr u − a tr σ)² + ((uxx−uyy) − b(σxx−σyy))² + 4(uxy − b σxy)²]``, so
    ``a = <tr u tr σ>/<(tr σ)²>`` and
    ``b = (<(uxx−uyy)(σxx−σyy)> + 4<uxy σxy>)/(<(σxx−σyy)²> + 4<σxy²>)``.
    Returns ``(K, G, flag)``.
    """
    m = _Moments(sigma, u)
    scale = m.mean(m.T, m.T) + m.mean(m.D, m.D) + 4 * m.mean(m.S, m.S)
    a, f1 = _ratio(m.mean(m.t, m.T), m.mean(m.T, m.T), scale, rtol)
    b, f2 = _ratio(m.mean(m.d, m.D) + 4 * m.mean(m.e, m.S), m.mean(m.D, m.D) + 4 * m.mean(m.S, m.S), scale, rtol)
    ascale = np.abs(a) + np.abs(b)
    K, f3 = _ratio(1.0, 2 * a, ascale, rtol)
    G, f4 = _ratio(1.0, 2 * b, ascale, rtol)
    return tuple(_finalise([K, G], f1 | f2 | f3 | f4, m.n, min_points))


def fit_cubic_compliances(sigma: np.ndarray, u: np.ndarray, min_points: int = 1, rtol: float = 1e-12):
    """Cubic compliances ``s1, s2, s3`` minimising S̃ (Eq. 18), i.e. Eq. 19.

    ``s1 + s2 = <tr u tr σ>/<(tr σ)²>``, ``s1 − s2 = <(uxx−uyy)(σxx−σyy)>/<(σxx−σyy)²>``,
    ``s3 = <uxy σxy>/<σxy²>``. Returns ``(s1, s2, s3, flag)``.
    """
    m = _Moments(sigma, u)
    scale = m.mean(m.T, m.T) + m.mean(m.D, m.D) + 4 * m.mean(m.S, m.S)
    p, f1 = _ratio(m.mean(m.t, m.T), m.mean(m.T, m.T), scale, rtol)
    q, f2 = _ratio(m.mean(m.d, m.D), m.mean(m.D, m.D), scale, rtol)
    s3, f3 = _ratio(m.mean(m.e, m.S), m.mean(m.S, m.S), scale, rtol)
    return tuple(_finalise([(p + q) / 2, (p - q) / 2, s3], f1 | f2 | f3, m.n, min_points))


def cubic_moduli_from_compliances(s1: np.ndarray, s2: np.ndarray, s3: np.ndarray, rtol: float = 1e-12):
    """Eq. 20: ``lambda1 = s1/(s1²−s2²)``, ``lambda2 = −s2/(s1²−s2²)``, ``lambda3 = 1/(2 s3)``.

    Returns ``(lambda1, lambda2, lambda3, flag)``.
    """
    s1, s2, s3 = (np.asarray(a, float) for a in (s1, s2, s3))
    det = s1 * s1 - s2 * s2
    scale = s1 * s1 + s2 * s2
    l1, f1 = _ratio(s1, det, scale, rtol)
    l2, f2 = _ratio(-s2, det, scale, rtol)
    l3, f3 = _ratio(1.0, 2 * s3, np.abs(s1) + np.abs(s2) + np.abs(s3), rtol)
    flag = f1 | f2 | f3 | np.where(np.isfinite(s1) & np.isfinite(s2) & np.isfinite(s3), 0, FIT_NONFINITE)
    return tuple(_finalise([l1, l2, l3], flag.astype(np.int32), np.ones(np.shape(s1)), 1))


def compliances_from_cubic_moduli(l1: np.ndarray, l2: np.ndarray, l3: np.ndarray, rtol: float = 1e-12):
    """Inverse of Eq. 20: ``s1 = lambda1/(lambda1²−lambda2²)``, ``s2 = −lambda2/(…)``, ``s3 = 1/(2 lambda3)``."""
    return cubic_moduli_from_compliances(l1, l2, l3, rtol)  # Eq. 20 is its own inverse in this form


def fit_cubic_moduli(sigma: np.ndarray, u: np.ndarray, min_points: int = 1, rtol: float = 1e-12):
    """Cubic moduli minimising S (Eq. 16) with ``lambda_xxxy = lambda_xyyy = 0``, ``lambda_yyyy = lambda_xxxx``.

    Then ``S = ½ Σ [(tr σ − (λ1+λ2) tr u)² + ((σxx−σyy) − (λ1−λ2)(uxx−uyy))²] + 2 Σ (σxy − 2λ3 uxy)²``,
    so ``λ1+λ2 = <tr σ tr u>/<(tr u)²>``, ``λ1−λ2 = <(σxx−σyy)(uxx−uyy)>/<(uxx−uyy)²>``,
    ``2λ3 = <σxy uxy>/<uxy²>``. Returns ``(lambda1, lambda2, lambda3, flag)``.
    """
    m = _Moments(sigma, u)
    scale = m.mean(m.t, m.t) + m.mean(m.d, m.d) + 4 * m.mean(m.e, m.e)
    p, f1 = _ratio(m.mean(m.T, m.t), m.mean(m.t, m.t), scale, rtol)
    q, f2 = _ratio(m.mean(m.D, m.d), m.mean(m.d, m.d), scale, rtol)
    r, f3 = _ratio(m.mean(m.S, m.e), m.mean(m.e, m.e), scale, rtol)
    return tuple(_finalise([(p + q) / 2, (p - q) / 2, r / 2], f1 | f2 | f3, m.n, min_points))


def youngs_modulus_isotropic(K: np.ndarray, G: np.ndarray) -> np.ndarray:
    """``E = 3G − G²/K`` as in Sect. 5 of the paper (NaN where K = 0)."""
    K, G = np.asarray(K, float), np.asarray(G, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        E = 3 * G - G * G / K
    return np.where(np.isfinite(E), E, np.nan)


def youngs_modulus_2d(K: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Young's modulus of an isotropic 2D medium under uniaxial stress, ``4KG/(K+G)``."""
    K, G = np.asarray(K, float), np.asarray(G, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        E = 4 * K * G / (K + G)
    return np.where(np.isfinite(E), E, np.nan)


def cubic_engineering_moduli(l1: np.ndarray, l2: np.ndarray, l3: np.ndarray) -> dict[str, np.ndarray]:
    """Bulk, Young's and shear moduli of a 2D cubic (square-symmetric) medium (Sect. 5).

    ``K = (λ1+λ2)/2``; ``E_p = (λ1²−λ2²)/λ1`` (uniaxial stress along x or y);
    ``E_b = 4λ3(λ1+λ2)/(λ1+λ2+2λ3)`` (uniaxial stress along a bisector, from the
    stiffness rotated by 45°: λ1' = (λ1+λ2)/2 + λ3, λ2' = (λ1+λ2)/2 − λ3);
    ``E_av = (E_p+E_b)/2``; ``G_p = λ3``; ``G_b = (λ1−λ2)/2``; ``G_av = (G_p+G_b)/2``.
    ``E_b_paper = λ1+λ2`` and ``E_av_paper = λ1 + ½(λ1−λ2)λ2/λ1`` are the
    paper's printed expressions (see module docstring).
    """
    l1, l2, l3 = (np.asarray(a, float) for a in (l1, l2, l3))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {
            "bulk_modulus_cubic": 0.5 * (l1 + l2),
            "E_p": (l1 * l1 - l2 * l2) / l1,
            "E_b": 4 * l3 * (l1 + l2) / (l1 + l2 + 2 * l3),
            "G_p": l3,
            "G_b": 0.5 * (l1 - l2),
            "E_b_paper": l1 + l2,
            "E_av_paper": l1 + 0.5 * (l1 - l2) * l2 / l1,
        }
    out["E_av"] = 0.5 * (out["E_p"] + out["E_b"])
    out["G_av"] = 0.5 * l3 + 0.25 * (l1 - l2)
    return {k: np.where(np.isfinite(v), v, np.nan) for k, v in out.items()}


# ---------------------------------------------------------------- conditioning and masks
def law_stiffness(fitted: dict[str, np.ndarray], law: str) -> np.ndarray:
    """The Mandel stiffness ``(..., 3, 3)`` (N/m) of a fitted law.

    Parameters
    ----------
    fitted : dict
        The law's moduli: ``bulk_modulus`` and ``shear_modulus`` (isotropic),
        ``lambda1``, ``lambda2``, ``lambda3`` (cubic).
    law : {"isotropic", "cubic"}

    Returns
    -------
    numpy.ndarray
        :func:`analysis.general_elastic.isotropic_stiffness` or
        :func:`analysis.general_elastic.cubic_stiffness` of those moduli.
    """
    if law == "isotropic":
        return isotropic_stiffness(fitted["bulk_modulus"], fitted["shear_modulus"])
    return cubic_stiffness(fitted["lambda1"], fitted["lambda2"], fitted["lambda3"])


def fit_quality(stiffness: np.ndarray,
                max_condition: float = _DEFAULT["max_condition"]) -> tuple[np.ndarray, np.ndarray]:
    """Condition number and positive definiteness of fitted stiffnesses (module docstring).

    Parameters
    ----------
    stiffness : array ``(..., 3, 3)``
        Symmetric Mandel stiffness of a fitted law (N/m), NaN where there is no fit.
    max_condition : float
        Condition numbers above it are flagged :data:`FIT_ILL_CONDITIONED`.

    Returns
    -------
    condition : numpy.ndarray ``(...)``
        ``κ = max|μ| / min|μ|`` over the eigenvalues μ (the mode stiffnesses):
        1 for equal modes, inf where one vanishes, NaN where there is no fit.
    reason : numpy.ndarray ``(...)``, int32
        :data:`FIT_ILL_CONDITIONED` and :data:`FIT_NOT_POSITIVE` where they
        apply (any eigenvalue ≤ 0), 0 else and where there is no fit.
    """
    stiffness = np.asarray(stiffness, float)
    finite = np.all(np.isfinite(stiffness), axis=(-2, -1))
    mu = np.abs(np.linalg.eigvalsh(np.where(finite[..., None, None], stiffness, np.eye(3))))
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(mu.min(axis=-1) > 0, mu.max(axis=-1) / mu.min(axis=-1), np.inf)
    condition = np.where(finite, condition, np.nan)
    reason = (np.where(finite & ~(condition <= max_condition), FIT_ILL_CONDITIONED, 0)
              | np.where(finite & ~positive_definite(stiffness), FIT_NOT_POSITIVE, 0))
    return condition, reason.astype(np.int32)


def mask_counts(reason: np.ndarray) -> dict[str, int]:
    """How many fits were made and why they are masked, from their mask bits.

    Parameters
    ----------
    reason : array of int
        ``mask_reason`` bits (:data:`MASK_REASON_FLAGS`) of any set of fits.

    Returns
    -------
    dict
        ``fitted``: the fits with enough valid points (no
        ``insufficient_points``); of those, ``masked`` (any bit),
        ``ill_conditioned`` and ``not_positive_definite`` (a fit may be both).
    """
    reason = np.asarray(reason)
    fitted = (reason & FIT_INSUFFICIENT_POINTS) == 0
    return {"fitted": int(fitted.sum()), "masked": int(np.sum(fitted & (reason != 0))),
            "ill_conditioned": int(np.sum(fitted & (reason & FIT_ILL_CONDITIONED > 0))),
            "not_positive_definite": int(np.sum(fitted & (reason & FIT_NOT_POSITIVE > 0)))}


def _mask_law(fitted: dict[str, np.ndarray], law: str, max_condition: float) -> None:
    """Add the law's condition number to ``fitted`` and mask its quantities (in place)."""
    condition, bits = fit_quality(law_stiffness(fitted, law), max_condition)
    reason = (fitted[f"{law}_mask_reason"] | bits).astype(np.int32)
    for k in LAWS[law]:
        fitted[k] = np.where(reason == 0, fitted[k], np.nan)
    fitted[f"{law}_mask_reason"] = reason
    fitted[f"{law}_condition"] = condition


# ---------------------------------------------------------------- on a grid
def gather_points(field: np.ndarray, m: int) -> np.ndarray:
    """Samples for each grid point: ``(ny, nx, m, 2, 2)`` from a field ``(ny, nx, 2, 2)``.

    ``m = 1``: the point itself; ``m = 5``: itself and its 4 grid neighbours
    (NaN beyond the grid edge).
    """
    if m == 1:
        return field[:, :, None]
    if m != 5:
        raise ValueError(f"points must be 1 or 5, got {m}")
    pad = np.pad(field, ((1, 1), (1, 1), (0, 0), (0, 0)), constant_values=np.nan)
    ny, nx = field.shape[:2]
    shifts = [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)]
    return np.stack([pad[1 + dy:1 + dy + ny, 1 + dx:1 + dx + nx] for dy, dx in shifts], axis=2)


def fit_all(stress_increment: np.ndarray, strain_increment: np.ndarray, min_points: int = _DEFAULT["min_points"],
            rtol: float = _DEFAULT["degenerate_rtol"],
            max_condition: float = _DEFAULT["max_condition"]) -> dict[str, np.ndarray]:
    """Every fit on a grid, masked where it is not a stable, well-conditioned law.

    Parameters
    ----------
    stress_increment, strain_increment : arrays ``(ny, nx, 2, 2)``
        The increments (N/m and 1) of one pile or of the ensemble.
    min_points : int
        Valid points out of 5 needed for the m = 5 fits.
    rtol : float
        Denominators below this fraction of the data scale count as zero.
    max_condition : float
        Fits with a larger condition number are masked (:func:`fit_quality`).

    Returns
    -------
    dict
        For every quantity of :data:`ISOTROPIC` and :data:`CUBIC` an array
        ``(fit=3, points=2, ny, nx)``, NaN where its law is masked;
        ``isotropic_mask_reason`` and ``cubic_mask_reason``
        (:data:`MASK_REASON_FLAGS`; 0 = valid), ``isotropic_condition`` and
        ``cubic_condition`` (kept where masked), ``n_points``.
    """
    qual = tuple(f"{law}_{k}" for law in LAWS for k in ("mask_reason", "condition"))
    res: dict[str, list] = {k: [[None] * len(POINTS) for _ in FITS] for k in ISOTROPIC + CUBIC + qual + ("n_points",)}
    for ip, m in enumerate(POINTS):
        sig, u = gather_points(stress_increment, m), gather_points(strain_increment, m)
        need = 1 if m == 1 else min_points
        n = _Moments(sig, u).n
        iso = {"compliance": fit_isotropic_compliances(sig, u, need, rtol),
               "modulus": fit_isotropic_moduli(sig, u, need, rtol)}
        s1, s2, s3, fs = fit_cubic_compliances(sig, u, need, rtol)
        l1c, l2c, l3c, fc = cubic_moduli_from_compliances(s1, s2, s3, rtol)
        l1m, l2m, l3m, fm = fit_cubic_moduli(sig, u, need, rtol)
        s1m, s2m, s3m, fi = compliances_from_cubic_moduli(l1m, l2m, l3m, rtol)
        cub = {"compliance": (l1c, l2c, l3c, s1, s2, s3, fs | fc), "modulus": (l1m, l2m, l3m, s1m, s2m, s3m, fm)}
        per_fit: dict[str, dict[str, np.ndarray]] = {}
        for fit in ("compliance", "modulus"):
            K, G, fiso = iso[fit]
            l1, l2, l3, a1, a2, a3, fcub = cub[fit]
            d = {"bulk_modulus": K, "shear_modulus": G, "youngs_modulus": youngs_modulus_isotropic(K, G),
                 "youngs_modulus_2d": youngs_modulus_2d(K, G), "lambda1": l1, "lambda2": l2, "lambda3": l3,
                 "s1": a1, "s2": a2, "s3": a3, **cubic_engineering_moduli(l1, l2, l3),
                 "isotropic_mask_reason": fiso, "cubic_mask_reason": fcub, "n_points": n}
            per_fit[fit] = d
        # the average of the unmasked values (its own condition number), masked where either method is
        avg = {k: 0.5 * (per_fit["compliance"][k] + per_fit["modulus"][k]) for k in ISOTROPIC + CUBIC}
        for fit in ("compliance", "modulus"):
            for law in LAWS:
                _mask_law(per_fit[fit], law, max_condition)
        for law in LAWS:
            avg[f"{law}_mask_reason"] = (per_fit["compliance"][f"{law}_mask_reason"]
                                         | per_fit["modulus"][f"{law}_mask_reason"])
            _mask_law(avg, law, max_condition)
        avg["n_points"] = n
        per_fit["average"] = avg
        for ifit, fit in enumerate(FITS):
            for k in res:
                res[k][ifit][ip] = per_fit[fit][k]
    return {k: np.array(v) for k, v in res.items()}


def fit_piles(stacks_sigma: np.ndarray, stacks_u: np.ndarray, min_points: int = _DEFAULT["min_points"],
              rtol: float = _DEFAULT["degenerate_rtol"],
              max_condition: float = _DEFAULT["max_condition"]) -> list[dict[str, np.ndarray]]:
    """Each pile's own fits: :func:`fit_all` of each of the per-pile fields ``(n_piles, ny, nx, 2, 2)``."""
    return [fit_all(stacks_sigma[s], stacks_u[s], min_points, rtol, max_condition) for s in range(len(stacks_sigma))]


def pile_statistics(fits: list[dict[str, np.ndarray]],
                    min_valid_piles: float = _DEFAULT["min_valid_piles"]) -> dict[str, np.ndarray]:
    """Mean and standard error over piles of the piles' own fits, masked fits left out.

    Parameters
    ----------
    fits : list of dict
        :func:`fit_all` of each pile (:func:`fit_piles`).
    min_valid_piles : float
        Share of the piles with a fit at an RVE (enough valid points) whose
        fit must be valid for the mean there to be kept.

    Returns
    -------
    dict
        ``<name>_pile_mean`` and ``<name>_sem`` (fit, points, y, x) for every
        quantity, NaN where the mean is masked; per law ``<law>_n_piles``
        (valid fits), ``<law>_mask_reason_pile_mean`` (``insufficient_points``
        where no pile has a fit, ``few_valid_piles`` where none or fewer than
        ``min_valid_piles`` of those are valid), and each pile's
        ``<law>_mask_reason_piles`` and ``<law>_condition_piles``
        (pile, fit, points, y, x).
    """
    from .ensemble import nan_mean_sem

    out: dict[str, np.ndarray] = {}
    for law, names in LAWS.items():
        reason = np.stack([f[f"{law}_mask_reason"] for f in fits])
        tried = ((reason & FIT_INSUFFICIENT_POINTS) == 0).sum(axis=0)
        valid = (reason == 0).sum(axis=0)
        few = (valid == 0) | (valid < min_valid_piles * tried)
        mean_reason = np.where(tried == 0, FIT_INSUFFICIENT_POINTS, np.where(few, FIT_FEW_PILES, 0))
        for k in names:
            mean, sem, _ = nan_mean_sem(np.stack([f[k] for f in fits]))
            out[f"{k}_pile_mean"] = np.where(mean_reason == 0, mean, np.nan)
            out[f"{k}_sem"] = np.where(mean_reason == 0, sem, np.nan)
        out[f"{law}_n_piles"] = valid.astype(np.int32)
        out[f"{law}_mask_reason_pile_mean"] = mean_reason.astype(np.int32)
        out[f"{law}_mask_reason_piles"] = reason.astype(np.int32)
        out[f"{law}_condition_piles"] = np.stack([f[f"{law}_condition"] for f in fits])
    return out


def fit_uncertainty(stacks_sigma: np.ndarray, stacks_u: np.ndarray, method: str, min_points: int, rtol: float,
                    samples: int = 200, seed: int = 0, max_condition: float = _DEFAULT["max_condition"],
                    min_valid_piles: float = _DEFAULT["min_valid_piles"]) -> dict[str, np.ndarray]:
    """Uncertainty of every fitted quantity from per-seed fields ``(n_seeds, ny, nx, 2, 2)``.

    ``pile_fits``: standard error over seeds of the valid fits done on each
    pile (:func:`pile_statistics`). ``bootstrap``: standard deviation over
    resamples (seeds drawn with replacement) of the valid fits to the
    resampled ensemble means. NaN with fewer than two seeds.
    """
    n_seeds = stacks_sigma.shape[0]
    keys = ISOTROPIC + CUBIC
    if n_seeds < 2:
        shape = (len(FITS), len(POINTS)) + stacks_sigma.shape[1:3]
        return {k: np.full(shape, np.nan) for k in keys}
    if method == "pile_fits":
        stats = pile_statistics(fit_piles(stacks_sigma, stacks_u, min_points, rtol, max_condition), min_valid_piles)
        return {k: stats[f"{k}_sem"] for k in keys}
    if method == "bootstrap":
        rng = np.random.default_rng(seed)
        fits = []
        for _ in range(samples):  # loop over resamples
            pick = rng.integers(0, n_seeds, n_seeds)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                fits.append(fit_all(np.nanmean(stacks_sigma[pick], axis=0), np.nanmean(stacks_u[pick], axis=0),
                                    min_points, rtol, max_condition))
        out = {}
        for k in keys:
            st = np.stack([f[k] for f in fits])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                out[k] = np.where(np.isfinite(st).sum(0) >= 2, np.nanstd(st, axis=0, ddof=1), np.nan)
        return out
    raise ValueError(f"uncertainty method {method!r} not in ('pile_fits', 'bootstrap')")


META: dict[str, tuple[str, str]] = {
    "bulk_modulus": ("bulk modulus K, isotropic fit (Eqs 21-22)", "N m-1"),
    "shear_modulus": ("shear modulus G, isotropic fit (Eqs 21-22)", "N m-1"),
    "youngs_modulus": ("Young's modulus E = 3G - G^2/K (paper, Sect. 5)", "N m-1"),
    "youngs_modulus_2d": ("2D Young's modulus 4KG/(K+G) of the isotropic fit", "N m-1"),
    "lambda1": ("cubic modulus lambda_xxxx", "N m-1"),
    "lambda2": ("cubic modulus lambda_xxyy", "N m-1"),
    "lambda3": ("cubic modulus lambda_xyxy", "N m-1"),
    "s1": ("cubic compliance s_xxxx", "m N-1"),
    "s2": ("cubic compliance s_xxyy", "m N-1"),
    "s3": ("cubic compliance s_xyxy", "m N-1"),
    "bulk_modulus_cubic": ("bulk modulus (lambda1 + lambda2)/2 of the cubic fit", "N m-1"),
    "E_p": ("Young's modulus along x and y, (lambda1^2 - lambda2^2)/lambda1", "N m-1"),
    "E_b": ("Young's modulus along the bisectors, 4 lambda3 (lambda1+lambda2)/(lambda1+lambda2+2 lambda3)", "N m-1"),
    "E_av": ("(E_p + E_b)/2", "N m-1"),
    "G_p": ("shear modulus along the principal directions, lambda3", "N m-1"),
    "G_b": ("shear modulus along the bisectors, (lambda1 - lambda2)/2", "N m-1"),
    "G_av": ("(G_p + G_b)/2", "N m-1"),
    "E_b_paper": ("paper's printed E_b = lambda1 + lambda2 (biaxial, see comment)", "N m-1"),
    "E_av_paper": ("paper's printed E_av = lambda1 + (lambda1 - lambda2) lambda2 / (2 lambda1)", "N m-1"),
    "n_points": ("valid data points entering the fit", "1"),
}
for _law in LAWS:
    META.update({
        f"{_law}_mask_reason": (f"why the {_law} fit of the ensemble mean is masked (bit mask, 0 = valid)", "1"),
        f"{_law}_condition": (f"condition number max|mode stiffness| / min|mode stiffness| of the {_law} fit "
                              "of the ensemble mean", "1"),
        f"{_law}_mask_reason_piles": (f"why each pile's own {_law} fit is masked (bit mask, 0 = valid)", "1"),
        f"{_law}_condition_piles": (f"condition number of each pile's own {_law} fit", "1"),
        f"{_law}_n_piles": (f"piles whose own {_law} fit is valid (enter the mean over piles)", "1"),
        f"{_law}_mask_reason_pile_mean": (f"why the mean over piles of the {_law} fits is masked "
                                          "(bit mask, 0 = valid)", "1"),
    })


def moduli_dataset(ensemble, piles: list, params: dict[str, Any]):
    """``moduli.nc`` (docs/formats.md#elastic-moduli): the fits of the ensemble mean and the piles' own fits.

    Parameters
    ----------
    ensemble : xarray.Dataset
        The ensemble fields (``stress_increment``, ``strain_increment``).
    piles : list of xarray.Dataset
        The per-pile fields (none: no mean over piles and no uncertainty).
    params : dict
        The analysis settings (``moduli``, ``ensemble.slip_strain_ratio``).

    Returns
    -------
    xarray.Dataset
    """
    import xarray as xr

    from .ensemble import leave_out_slips
    from .netcdf import var

    mp = params["moduli"]
    fit_args = (mp["min_points"], mp["degenerate_rtol"], mp["max_condition"])
    sig = ensemble["stress_increment"].transpose("y", "x", "i", "j").values
    u = ensemble["strain_increment"].transpose("y", "x", "i", "j").values
    res = fit_all(sig, u, *fit_args)
    stats: dict[str, np.ndarray] = {}
    if piles:
        piles, _ = leave_out_slips(piles, params["ensemble"]["slip_strain_ratio"])
        ss = np.stack([p["stress_increment"].transpose("y", "x", "i", "j").values for p in piles])
        su = np.stack([p["strain_increment"].transpose("y", "x", "i", "j").values for p in piles])
        stats = pile_statistics(fit_piles(ss, su, *fit_args), mp["min_valid_piles"])
        if mp["uncertainty"] == "pile_fits":
            unc = {k: stats[f"{k}_sem"] for k in ISOTROPIC + CUBIC}
        else:
            unc = fit_uncertainty(ss, su, mp["uncertainty"], mp["min_points"], mp["degenerate_rtol"],
                                  mp["bootstrap_samples"], mp["bootstrap_seed"], mp["max_condition"])
    else:
        nan = np.full(res["bulk_modulus"].shape, np.nan)
        unc = {k: nan for k in ISOTROPIC + CUBIC}
        stats = {f"{k}_pile_mean": nan for k in ISOTROPIC + CUBIC}
        for law in LAWS:
            stats[f"{law}_n_piles"] = np.zeros(nan.shape, np.int32)
            stats[f"{law}_mask_reason_pile_mean"] = np.full(nan.shape, FIT_INSUFFICIENT_POINTS, np.int32)
    dims = ("fit", "points", "y", "x")
    coords = {
        "fit": var("fit", np.array(FITS), "fitting method (compliances, moduli, or their average)", "1"),
        "points": var("points", np.array(POINTS, dtype=np.int32), "number m of data points per fit", "1"),
        "y": ensemble["y"].variable, "x": ensemble["x"].variable,
    }
    if piles:
        seeds = [int(p.attrs.get("seed", k)) for k, p in enumerate(piles)]
        coords["seed"] = var("seed", np.array(seeds, dtype=np.int32), "seed of the pile", "1")
    ds = xr.Dataset(coords=coords)
    for k in ISOTROPIC + CUBIC:
        ln, un = META[k]
        ds[k] = var(dims, res[k], f"{ln}, fit of the ensemble mean", un)
        ds[f"{k}_pile_mean"] = var(dims, stats[f"{k}_pile_mean"], f"{ln}, mean over piles of the piles' own fits", un)
        ds[f"{k}_sem"] = var(dims, unc[k], f"uncertainty of {k} and {k}_pile_mean ({mp['uncertainty']})", un)
    for law in LAWS:
        ds[f"{law}_mask_reason"] = var(dims, res[f"{law}_mask_reason"], *META[f"{law}_mask_reason"],
                                       **MASK_REASON_FLAGS)
        ds[f"{law}_condition"] = var(dims, res[f"{law}_condition"], *META[f"{law}_condition"])
        ds[f"{law}_n_piles"] = var(dims, stats[f"{law}_n_piles"], *META[f"{law}_n_piles"])
        ds[f"{law}_mask_reason_pile_mean"] = var(dims, stats[f"{law}_mask_reason_pile_mean"],
                                                 *META[f"{law}_mask_reason_pile_mean"], **MASK_REASON_FLAGS)
        if piles:
            ds[f"{law}_mask_reason_piles"] = var(("seed",) + dims, stats[f"{law}_mask_reason_piles"],
                                                 *META[f"{law}_mask_reason_piles"], **MASK_REASON_FLAGS)
            ds[f"{law}_condition_piles"] = var(("seed",) + dims, stats[f"{law}_condition_piles"],
                                               *META[f"{law}_condition_piles"])
    ds["n_points"] = var(dims, res["n_points"].astype(np.int32), *META["n_points"])
    ds["E_b"].attrs["comment"] = ("uniaxial Young's modulus along the bisectors from the cubic stiffness rotated by "
                                  "45 degrees; the paper prints lambda1 + lambda2 (kept as E_b_paper)")
    ds["youngs_modulus"].attrs["comment"] = "3D relation with the 2D Lame constant K - G; see youngs_modulus_2d"
    ds.attrs.update({
        "data": "ensemble-mean stress_increment and strain_increment (reduced - relaxed); <name>_pile_mean: "
                "the mean over piles of each pile's own fit",
        "uncertainty_method": mp["uncertainty"],
        "points_meaning": "m=1: the RVE centre; m=5: the centre and its 4 grid neighbours (spacing apart)",
        "min_points_m5": mp["min_points"],
        "max_condition": float(mp["max_condition"]),
        "min_valid_piles": float(mp["min_valid_piles"]),
        "positive_definite_meaning": "isotropic: K > 0 and G > 0; cubic: lambda1 > |lambda2| and lambda3 > 0",
        "n_seeds": int(ensemble.attrs.get("n_seeds", len(piles))),
    })
    for a in ("rve_shape", "rve_size", "protocol", "grid_spacing"):
        if a in ensemble.attrs:
            ds.attrs[a] = ensemble.attrs[a]
    return ds
