"""The general 2D linear elastic fit: a symmetric 3 × 3 stiffness per RVE (#14).

The paper fits isotropic and cubic elasticity to one probe per pile (the
10 % gravity reduction). Here the six independent constants of the most
general 2D linear elastic law are fitted to all the probes an RVE has (the
gravity reduction, tilted gravity, ...), in Mandel notation, where a
symmetric tensor ``t`` is the vector

    t_M = (t_xx, t_yy, √2 t_xy)

so that ``Δσ_M = C Δu_M`` with ``C`` symmetric and the elastic energy density
``½ Δu_M · C Δu_M``. ``C`` is the least-squares solution over the RVE's
samples (its probes × its m points, as in :mod:`analysis.elastic`). Each
sample gives three equations, so six unknowns need at least two samples
whose strains are independent: one gravity probe scales the load the pile
already carries, its strains at neighbouring points are nearly parallel, and
the fit is then not identified. Nor do gravity probes of any number pin all
six: in a linear elastic pile the strain at a point is linear in the change
of gravity, a vector of two components, so the strains of all reductions and
tilts at one point span two shapes, and ``C + t w wᵀ`` (``w`` normal to both
in Mandel space) fits them as well as ``C``; only the m = 5 neighbouring
points, assumed to be one material, or a load of another kind (the support
stretch of :func:`sim.probe.stretch_file`, stage ``stretched``) break that
tie. The **condition number** of the design matrix
(the ratio of its largest to its smallest singular value) says how well the
data pin ``C``: it depends on the strains alone; above
:data:`MAX_CONDITION` the fit is flagged ``not_identified``.

From ``C``: the **directional Young's modulus** ``E(α) = 1 / (m_M · C⁻¹ m_M)``
with ``m = n ⊗ n`` for the unit vector ``n`` at angle α from the vertical
(counter-clockwise, as in :mod:`analysis.orientation`) is the stiffness under
uniaxial stress along ``n``; its maximum gives the **stiffness axis**
(degrees, in (−90, 90]) and ``E_max / E_min`` the **anisotropy ratio** (1 for
isotropic and for cubic with ``λ3 = (λ1 − λ2)/2``). The isotropic
(K, G) and cubic (λ1, λ2, λ3) laws of the paper are special cases
(:func:`isotropic_stiffness`, :func:`cubic_stiffness`), and
:func:`explained_fraction` tells how much of the measured stress increments a
law reproduces.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

#: Condition number above which the general fit is reported as not identified:
#: the relative error of C can reach the condition number times the relative
#: error of the data, so at 100 data known to 0.1 % pin C to 10 %.
MAX_CONDITION = 100.0

#: Samples (probe × point) needed at least: two, for six unknowns and three
#: equations per sample.
MIN_SAMPLES = 2

GENERAL_NOT_IDENTIFIED = 1
GENERAL_INSUFFICIENT_SAMPLES = 2
GENERAL_NOT_POSITIVE = 4
GENERAL_FLAGS = {"flag_masks": np.array([1, 2, 4], dtype=np.int32),
                 "flag_meanings": "not_identified insufficient_samples not_positive_definite"}

#: Directions (degrees from the vertical) at which E(α) is evaluated for the axes.
ANGLES_DEG = np.arange(-89.5, 90.0, 0.5)

SQRT2 = np.sqrt(2.0)


def mandel(t: np.ndarray) -> np.ndarray:
    """Mandel vectors ``(..., 3)`` = (xx, yy, √2 xy) of tensors ``(..., 2, 2)`` (symmetric part)."""
    t = np.asarray(t, float)
    return np.stack((t[..., 0, 0], t[..., 1, 1], SQRT2 * 0.5 * (t[..., 0, 1] + t[..., 1, 0])), axis=-1)


def _design(u_m: np.ndarray) -> np.ndarray:
    """Rows of ``Δσ_M = A c`` for ``c = (C11, C22, C33, C12, C13, C23)``: ``(..., 3, 6)`` per sample."""
    e1, e2, e3 = u_m[..., 0], u_m[..., 1], u_m[..., 2]
    z = np.zeros_like(e1)
    return np.stack((np.stack((e1, z, z, e2, e3, z), axis=-1),
                     np.stack((z, e2, z, e1, z, e3), axis=-1),
                     np.stack((z, z, e3, z, e1, e2), axis=-1)), axis=-2)


def _matrix(c: np.ndarray) -> np.ndarray:
    """The symmetric ``(..., 3, 3)`` stiffness of the parameter vectors ``(..., 6)``."""
    c11, c22, c33, c12, c13, c23 = np.moveaxis(c, -1, 0)
    return np.stack((np.stack((c11, c12, c13), -1), np.stack((c12, c22, c23), -1),
                     np.stack((c13, c23, c33), -1)), -2)


def fit_general_stiffness(sigma: np.ndarray, u: np.ndarray, min_samples: int = MIN_SAMPLES,
                          max_condition: float = MAX_CONDITION) -> dict[str, np.ndarray]:
    """Least-squares symmetric Mandel stiffness from samples of Δσ and Δu.

    Parameters
    ----------
    sigma, u : arrays ``(..., n, 2, 2)``
        Stress (N/m) and strain increments of the ``n`` samples of each fit
        (probes × points); a sample with any non-finite component is left out.
    min_samples : int
        Fewer valid samples give NaN and the flag ``insufficient_samples``.
    max_condition : float
        A larger condition number gives NaN and the flag ``not_identified``
        (the condition number itself is always reported).

    Returns
    -------
    dict
        ``stiffness`` ``(..., 3, 3)`` N/m, ``condition`` (largest over
        smallest singular value of the design matrix; inf when singular),
        ``n_samples``, ``flag`` (:data:`GENERAL_FLAGS`; a fit that is not
        positive definite keeps its values but is flagged
        ``not_positive_definite``).

    Raises
    ------
    InputError
        When there are valid samples and every one of them has a zero
        strain: the probes moved nothing, and nothing can be identified
        anywhere (one line, instead of a file of fits that are all flagged).
    """
    s_m, u_m = mandel(sigma), mandel(u)
    valid = np.all(np.isfinite(s_m), axis=-1) & np.all(np.isfinite(u_m), axis=-1)
    n = valid.sum(axis=-1)
    s_m = np.where(valid[..., None], s_m, 0.0)
    u_m = np.where(valid[..., None], u_m, 0.0)
    if valid.any() and not u_m.any():
        raise InputError(f"general fit: nothing identified, the strain increment of every one of the "
                         f"{int(valid.sum())} valid samples (probe x point) is zero: the probes moved no "
                         "particle; look at the probe states and their increments (python -m analysis probes)")
    a = _design(u_m)                                   # (..., n, 3, 6)
    shape = a.shape[:-3]
    a = a.reshape(*shape, -1, 6)
    b = s_m.reshape(*shape, -1)
    # the strains set the design's scale: divide it out so that the
    # condition number and the rank test see the geometry of the strains only
    scale = np.sqrt(np.sum(a * a, axis=(-2, -1)) / 6.0)
    safe = np.where(scale > 0, scale, 1.0)
    uu, sv, vt = np.linalg.svd(a / safe[..., None, None], full_matrices=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(sv[..., -1] > 0, sv[..., 0] / sv[..., -1], np.inf)
        coef = np.einsum("...ji,...j->...i", uu, b) / sv
        c = np.einsum("...ij,...i->...j", vt, coef) / safe[..., None]
    flag = (np.where(~(condition <= max_condition), GENERAL_NOT_IDENTIFIED, 0)
            | np.where(n < min_samples, GENERAL_INSUFFICIENT_SAMPLES, 0)).astype(np.int32)
    stiffness = np.where((flag == 0)[..., None, None], _matrix(c), np.nan)
    flag |= np.where((flag == 0) & ~positive_definite(stiffness), GENERAL_NOT_POSITIVE, 0).astype(np.int32)
    return {"stiffness": stiffness, "condition": condition, "n_samples": n, "flag": flag}


def positive_definite(stiffness: np.ndarray) -> np.ndarray:
    """Whether each symmetric ``(..., 3, 3)`` stiffness has only positive
    eigenvalues (a stable elastic law: every strain costs energy); False where NaN."""
    stiffness = np.asarray(stiffness, float)
    finite = np.all(np.isfinite(stiffness), axis=(-2, -1))
    eig = np.linalg.eigvalsh(np.where(finite[..., None, None], stiffness, np.eye(3)))
    return finite & np.all(eig > 0, axis=-1)


def isotropic_stiffness(K: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Mandel stiffness of the paper's isotropic law (tr Δσ = 2K tr Δu, dev Δσ = 2G dev Δu)."""
    K, G = np.asarray(K, float), np.asarray(G, float)
    z = np.zeros_like(K + G)
    return np.stack((np.stack((K + G, K - G, z), -1), np.stack((K - G, K + G, z), -1),
                     np.stack((z, z, 2 * G), -1)), -2)


def cubic_stiffness(l1: np.ndarray, l2: np.ndarray, l3: np.ndarray) -> np.ndarray:
    """Mandel stiffness of the paper's cubic law (λ1 = C_xxxx, λ2 = C_xxyy, λ3 = C_xyxy)."""
    l1, l2, l3 = (np.asarray(a, float) for a in (l1, l2, l3))
    z = np.zeros_like(l1 + l2 + l3)
    return np.stack((np.stack((l1, l2, z), -1), np.stack((l2, l1, z), -1),
                     np.stack((z, z, 2 * l3), -1)), -2)


def explained_fraction(stiffness: np.ndarray, sigma: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``1 − Σ|Δσ_M − C Δu_M|² / Σ|Δσ_M|²`` over the valid samples ``(..., n, 2, 2)``.

    1: the law reproduces every stress increment; 0: no better than zero
    stress; NaN where the law or the data are missing.
    """
    s_m, u_m = mandel(sigma), mandel(u)
    valid = np.all(np.isfinite(s_m), axis=-1) & np.all(np.isfinite(u_m), axis=-1)
    s_m = np.where(valid[..., None], s_m, 0.0)
    u_m = np.where(valid[..., None], u_m, 0.0)
    predicted = np.einsum("...ij,...nj->...ni", stiffness, u_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 1.0 - np.sum((s_m - predicted) ** 2, axis=(-2, -1)) / np.sum(s_m ** 2, axis=(-2, -1))
    return np.where(np.isfinite(out), out, np.nan)


def directional_modulus(stiffness: np.ndarray, angles_deg: np.ndarray = ANGLES_DEG) -> np.ndarray:
    """Young's modulus ``E(α)`` (N/m) under uniaxial stress along the directions
    ``α`` (degrees from the vertical, counter-clockwise): ``(..., n_angles)``;
    NaN where ``C`` is missing or singular."""
    a = np.radians(np.asarray(angles_deg, float))
    nx, ny = -np.sin(a), np.cos(a)
    m = np.stack((nx * nx, ny * ny, SQRT2 * nx * ny), axis=-1)      # (n_angles, 3)
    stiffness = np.asarray(stiffness, float)
    ok = np.all(np.isfinite(stiffness), axis=(-2, -1))
    ok &= np.abs(np.linalg.det(np.where(ok[..., None, None], stiffness, np.eye(3)))) > 0
    compliance = np.linalg.inv(np.where(ok[..., None, None], stiffness, np.eye(3)))
    with np.errstate(divide="ignore", invalid="ignore"):
        e = 1.0 / np.einsum("ai,...ij,aj->...a", m, compliance, m)
    return np.where(ok[..., None] & np.isfinite(e), e, np.nan)


def stiffness_axes(stiffness: np.ndarray, angles_deg: np.ndarray = ANGLES_DEG) -> dict[str, np.ndarray]:
    """The stiffest direction and the anisotropy of ``C`` from :func:`directional_modulus`.

    Returns
    -------
    dict
        ``axis_deg`` (direction of the largest E, degrees from the vertical,
        counter-clockwise, at the resolution of ``angles_deg``; NaN when the
        ratio is 1 to 1e-9), ``soft_axis_deg`` (that of the smallest E; for a
        general anisotropic law not always normal to ``axis_deg``), ``E_max``,
        ``E_min`` (N/m), ``anisotropy``
        (``E_max / E_min``); all NaN where ``C`` is not positive definite.
    """
    e = directional_modulus(stiffness, angles_deg)
    ok = np.all(np.isfinite(e), axis=-1) & positive_definite(stiffness)
    filled = np.where(ok[..., None], e, 1.0)
    e_max, e_min = filled.max(axis=-1), filled.min(axis=-1)
    angles = np.asarray(angles_deg, float)
    axis, soft = angles[np.argmax(filled, axis=-1)], angles[np.argmin(filled, axis=-1)]
    ratio = e_max / e_min
    anisotropic = ok & (ratio > 1.0 + 1e-9)
    return {"axis_deg": np.where(anisotropic, axis, np.nan),
            "soft_axis_deg": np.where(anisotropic, soft, np.nan),
            "E_max": np.where(ok, e_max, np.nan), "E_min": np.where(ok, e_min, np.nan),
            "anisotropy": np.where(ok, ratio, np.nan)}
