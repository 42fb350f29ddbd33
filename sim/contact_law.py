"""The contact force law of the paper's Appendix, one function per formula.

All functions are Numba kernels operating on scalars, called from the pair and
body loops of :mod:`sim.step`.  Notation (Appendix, Fig. 6): ``A`` overlap
area, ``l`` characteristic length, ``n`` unit normal of the contact line
pointing from particle i to particle j, ``t = (−n_y, n_x)`` the tangent,
``v_rel`` the velocity of i's material point at the force point ``s`` relative
to j's.

Sign conventions.  The normal force on i is ``−(F⊥ + D⊥) n``.  The tangential
force on i is ``−T t`` where ``T`` is the (capped) Cundall–Strack spring plus
tangential damping; the spring integrates ``(2/7) Y v∥ dt`` so its force
opposes the accumulated relative tangential displacement and the damping
opposes the relative tangential velocity, which is how a contact can stick
(the block on the incline) while always resisting the relative motion.
"""

from __future__ import annotations

import math

import numpy as np

from .kernel_cache import njit


@njit(cache=True, inline="always")
def characteristic_length(ri, rj):
    """Contact length ``l = r_i r_j / (r_i + r_j)`` (Appendix).

    For a fixed body (support, wall) pass ``rj = inf``: then ``l = r_i``.
    Where the contact point lies on both centres (coincident centres:
    ``r_i = r_j = 0``) the limit is ``l = 0``; callers floor ``l`` (the pair
    pass at ``eps``), so the force is finite and the blow-up detector, not a
    division by zero, stops the run.
    """
    if math.isinf(rj):
        return ri
    if ri + rj <= 0.0:
        return 0.0
    return ri * rj / (ri + rj)


@njit(cache=True, inline="always")
def tangential_stiffness(youngs_modulus):
    """Stiffness ``k∥ = (2/7) Y`` of the tangential (Cundall–Strack) spring, N/m.

    The paper's Appendix, (iii): the Cundall–Strack spring (Cundall & Strack,
    Géotechnique 29, 47–65, 1979) loads as ``F*∥ ← F*∥ + (2/7) Y v∥ Δt`` and
    its damping is ``D∥ = v∥ sqrt((2/7) Y m∥)``; the factor 2/7 "is adapted to
    Hertzian stress for spherical particles".  Written ``2.0 / 7.0 * Y`` (the
    constant 2/7 rounded once, then one product), the same double wherever it
    is used, in the kernels and in Python.
    """
    return 2.0 / 7.0 * youngs_modulus


@njit(cache=True, inline="always")
def reduced_mass(inv_mi, inv_mj):
    """Normal reduced mass ``m⊥ = m_i m_j / (m_i + m_j)`` from inverse masses (Appendix)."""
    return 1.0 / (inv_mi + inv_mj)


@njit(cache=True, inline="always")
def tangential_mass(inv_mi, inv_mj, ri, rj, inv_ii, inv_ij):
    """Tangential mass ``m∥ = 1 / (1/m_i + 1/m_j + r_i²/I_i + r_j²/I_j)`` (Appendix)."""
    return 1.0 / (inv_mi + inv_mj + ri * ri * inv_ii + rj * rj * inv_ij)


@njit(cache=True, inline="always")
def elastic_force(area, l, youngs_modulus):
    """Elastic normal force ``F⊥ = Y A / l`` (Appendix, (i))."""
    return youngs_modulus * area / l


@njit(cache=True, inline="always")
def damping_coefficient(m_perp, youngs_modulus, damping):
    """Coefficient ``γ sqrt(Y m⊥)`` of the normal damping (Appendix, (ii)), N s/m.

    It depends on the two masses only, so the pair pass takes it per pair
    from the pair list (:func:`pair_damping_coefficients`) instead of a
    division and a square root per contact and step.
    """
    return damping * math.sqrt(youngs_modulus * m_perp)


@njit(cache=True)
def pair_damping_coefficients(pi, pj, inv_mass, youngs_modulus, damping):
    """:func:`damping_coefficient` of each pair ``(pi[p], pj[p])`` from the
    particles' inverse masses; the same bits as computed per contact."""
    out = np.empty(pi.shape[0])
    for p in range(pi.shape[0]):
        out[p] = damping_coefficient(reduced_mass(inv_mass[pi[p]], inv_mass[pj[p]]),
                                     youngs_modulus, damping)
    return out


@njit(cache=True, inline="always")
def normal_force(area, area_rate, l, coefficient, youngs_modulus):
    """Elastic plus damping normal force ``F⊥ + D⊥`` (Appendix, (i) and (ii)).

    ``F⊥ = Y A / l`` and ``D*⊥ = γ sqrt(Y m⊥) dA/dt / l``, with the
    coefficient ``γ sqrt(Y m⊥)`` of :func:`damping_coefficient`.  On approach
    (``dA/dt > 0``) ``D⊥ = D*⊥``; on separation ``D⊥ = max(D*⊥, −F⊥)`` so the
    total never attracts.  ``dA/dt`` is the exact rate ``L v_n`` of the
    contact-line length times the normal approach speed (the paper's
    ``ΔA / Δt`` is its finite-difference estimate).

    Returns
    -------
    (float, float)
        Elastic part ``F⊥`` and total ``F⊥ + D⊥`` (>= 0).
    """
    f_el = elastic_force(area, l, youngs_modulus)
    d = coefficient * area_rate / l
    # only a separation (d < 0) can pass -F⊥; one test, not two, so that the
    # compiler selects instead of branching (the sign of dA/dt is a coin toss
    # in a settled pile, a mispredicted branch per contact)
    if d < -f_el:
        d = -f_el
    return f_el, f_el + d


@njit(cache=True, inline="always")
def tangential_force(spring, v_par, f_el, m_par, youngs_modulus, friction, dt):
    """Cundall–Strack tangential force with Coulomb cap (Appendix, (iii)).

    ``F*∥(t+dt) = min(F*∥(t) + (2/7) Y v∥ dt, μ F⊥)`` is the spring (its
    magnitude capped, sign kept), ``D∥ = v∥ sqrt((2/7) Y m∥)`` the damping, and
    the total is ``± min(|F*∥ + D∥|, μ F⊥)``.  Static and dynamic μ are equal.

    Parameters
    ----------
    spring : float
        Spring force from the previous step (0 for a new contact), N.
    v_par : float
        Relative tangential velocity ``v_rel · t``, m/s.
    f_el : float
        Elastic normal force ``F⊥`` (the cap is ``μ F⊥``), N.

    Returns
    -------
    (float, float)
        The total tangential force ``T`` and the updated spring.
    """
    k_t = tangential_stiffness(youngs_modulus)
    cap = friction * f_el
    s = spring + k_t * v_par * dt
    if s > cap:
        s = cap
    elif s < -cap:
        s = -cap
    total = s + v_par * math.sqrt(k_t * m_par)
    if total > cap:
        total = cap
    elif total < -cap:
        total = -cap
    return total, s
