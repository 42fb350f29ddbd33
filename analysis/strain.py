"""Best-fit displacement gradient of Cambou et al. (paper Eqs 3–9).

Index order (docs/formats.md#conventions): ``eps_ij = du_j/dx_i``, i.e. an affine field moves
the contact pair by ``dDelta u_j = eps_ij l_i`` (Eq. 4, written there as
``dDelta u_i = eps_ji l_j``).

Derivation from Eq. 6 (the printed Eqs 9a–d contain typos, so we do not
transcribe them): ``Z = sum_c sum_j (dDelta u_j^c - eps_ij l_i^c)^2``;
``dZ/d eps_kl = -2 sum_c (dDelta u_l^c - eps_il l_i^c) l_k^c = 0`` gives
``M eps = B`` with ``M_ki = sum_c l_k^c l_i^c`` and ``B_kl = sum_c l_k^c dDelta u_l^c``
(Eq. 7 written for both columns), hence ``eps = M^{-1} B`` (Eq. 8 with
``z = M^{-1}``).

Data: the contacts are the particle–particle pairs of the ``relaxed`` state
(each unordered pair once; the support has no centre and is excluded), the
branch vector ``l^c = r_j - r_i`` joins the two centres in the relaxed state,
``dDelta u^c = du_j - du_i`` (Eq. 3) with ``du = r(reduced) - r(relaxed)``
(centre translations only; rotations are excluded, as in the paper). A
contact belongs to an RVE when both its particles do.

An RVE is refused (NaN and a flag) when it has fewer than ``min_contacts``
contacts or when ``M`` is ill-conditioned (``cond(M) > max_condition``; branch
vectors that do not span the plane give an infinite condition number).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .orientation import principal_values
from .rve import pair_membership, rve_sum
from .states import State

FLAG_MASKED = 1
FLAG_TOO_FEW_CONTACTS = 2
FLAG_ILL_CONDITIONED = 4
STRAIN_FLAGS = {"flag_masks": np.array([FLAG_MASKED, FLAG_TOO_FEW_CONTACTS, FLAG_ILL_CONDITIONED], dtype=np.int32),
                "flag_meanings": "rve_masked too_few_contacts ill_conditioned_or_not_spanning"}


def contact_pairs(state: State) -> tuple[np.ndarray, np.ndarray]:
    """The particle–particle contacts of ``state`` as unique unordered pairs ``(i, j)``, ``i < j``."""
    pp = state.contact_j >= 0
    a, b = state.contact_i[pp], state.contact_j[pp]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = np.unique(lo * np.int64(state.n_particles) + hi)
    return key // state.n_particles, key % state.n_particles


def relative_translations(relaxed: State, reduced: State, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Branch vectors ``l^c = r_j - r_i`` (relaxed) and relative translations (Eq. 3).

    ``dDelta u^c = du_j - du_i`` with ``du = r(reduced) - r(relaxed)``.
    Returns two ``(n_contacts, 2)`` arrays.
    """
    r0 = np.column_stack([relaxed.x, relaxed.y])
    du = np.column_stack([reduced.x, reduced.y]) - r0
    return r0[j] - r0[i], du[j] - du[i]


def condition_number(M: np.ndarray) -> np.ndarray:
    """Condition number ``lambda_max/lambda_min`` of symmetric positive semi-definite 2×2 matrices.

    Infinite when the smaller eigenvalue vanishes to rounding (branch vectors
    that do not span the plane) or the matrix is zero.
    """
    lo, hi = principal_values(M)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = hi / lo
    tiny = lo <= 1e-12 * np.abs(hi)
    return np.where(tiny | ~np.isfinite(cond), np.inf, cond)


def cambou_gradient(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve Eq. 7 for the best-fit translation gradient, ``eps = M^{-1} B`` (Eq. 8).

    ``M_ki = sum_c l_k l_i`` and ``B_kl = sum_c l_k dDelta u_l``; returns
    ``eps_ij = du_j/dx_i`` (contract index order), shape ``(..., 2, 2)``.
    Singular ``M`` gives non-finite entries; callers screen with
    :func:`condition_number` first.
    """
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    inv = np.empty_like(M)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv[..., 0, 0] = M[..., 1, 1] / det
        inv[..., 1, 1] = M[..., 0, 0] / det
        inv[..., 0, 1] = -M[..., 0, 1] / det
        inv[..., 1, 0] = -M[..., 1, 0] / det
    return np.einsum("...ik,...kj->...ij", inv, B)


def best_fit_strain(W: sp.csr_matrix, relaxed: State, reduced: State, min_contacts: int,
                    max_condition: float, masked: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Cambou best-fit displacement gradient for every RVE (Eqs 3–8 solved as above).

    Parameters
    ----------
    W : sparse (n_rve, n_particles) membership matrix.
    relaxed, reduced : the two stages of one pile.
    min_contacts, max_condition : refusal thresholds.
    masked : optional boolean (n_rve,) of RVEs already refused (flag 1).

    Returns
    -------
    dict with ``displacement_gradient`` (n_rve, 2, 2), ``n_contacts``,
    ``condition`` (of M), ``residual`` (RMS of the non-affine part of
    ``dDelta u`` over RMS of ``dDelta u``) and ``flag`` (bit mask).
    """
    i, j = contact_pairs(relaxed)
    l, ddu = relative_translations(relaxed, reduced, i, j)
    Wc = pair_membership(W, i, j)
    n_c = np.asarray(Wc.sum(axis=1)).ravel()
    M = rve_sum(Wc, l[:, :, None] * l[:, None, :])
    B = rve_sum(Wc, l[:, :, None] * ddu[:, None, :])
    cond = condition_number(M)
    flag = np.zeros(W.shape[0], dtype=np.int32)
    if masked is not None:
        flag |= np.where(masked, FLAG_MASKED, 0).astype(np.int32)
    flag |= np.where(n_c < min_contacts, FLAG_TOO_FEW_CONTACTS, 0).astype(np.int32)
    flag |= np.where(~(cond <= max_condition), FLAG_ILL_CONDITIONED, 0).astype(np.int32)
    eps = cambou_gradient(M, B)
    eps[flag != 0] = np.nan
    # non-affine residual, exactly, pair by pair
    coo = Wc.tocoo()
    r, c = coo.row, coo.col
    res = ddu[c] - np.einsum("ki,kij->kj", l[c], eps[r])
    ss_res = np.bincount(r, weights=np.sum(res * res, axis=1), minlength=W.shape[0])
    ss_tot = np.bincount(r, weights=np.sum(ddu[c] ** 2, axis=1), minlength=W.shape[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        residual = np.sqrt(ss_res / ss_tot)
    residual[(flag != 0) | (ss_tot <= 0)] = np.nan
    return {"displacement_gradient": eps, "n_contacts": n_c.astype(np.int64), "condition": cond,
            "residual": residual, "flag": flag}
