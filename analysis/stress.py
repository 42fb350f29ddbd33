"""Stress from contact forces (paper Eq. 2).

Sign convention (docs/formats.md#conventions): Eq. 2 as written with ``f`` the force acting
**on** the particle, so compression is negative. The branch vector of particle
``p`` at contact ``c`` is ``x^c = (contact_x - x_p, contact_y - y_p)``. The
state file gives ``force_x, force_y`` acting on ``contact_i``; ``contact_j``
receives the negative. Contacts with the support (``contact_j = -1``)
contribute to their particle only (the support is not a particle).

RVE average: Eq. 2 with the prefactor ``1/V^p`` replaced by ``1/V`` (V the
RVE area) and summed over the member particles,
``sigma_ij = (1/V) sum_p sum_c x_i^c f_j^c = sum_p (V^p/V) sigma^p_ij``,
i.e. the area average over the RVE of the field equal to the particle stress
``sigma^p`` inside particle ``p`` and zero in the voids ("weighting each
particle with its volume fraction", Sect. 3).

Symmetry: the antisymmetric part of ``sum_c x_i f_j`` is the torque of the
contact forces about the particle's centre of mass. Gravity acts at the
centre of mass and exerts no torque, so at rest it vanishes particle by
particle (the missing force balance, ``sum_c f = -m g``, makes the particle
moment depend on the origin, which Eq. 2 fixes at the centre of mass, but
does not make it asymmetric). We report the **symmetric part** as ``stress``
and the antisymmetric remainder ``(sigma_xy - sigma_yx)/2`` separately as a
diagnostic of how far the state is from rest.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .rve import rve_sum
from .states import State


def scatter_tensor(index: np.ndarray, a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Sum of the outer products ``a ⊗ b`` (rows of (k, 2) arrays) per ``index``: ``(n, 2, 2)``."""
    out = np.empty((n, 2, 2))
    for r in range(2):
        for c in range(2):
            out[:, r, c] = np.bincount(index, weights=a[:, r] * b[:, c], minlength=n)
    return out


def contact_ends(state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (particle, branch vector, force on that particle) at the contacts.

    Each particle–particle contact appears twice (once per particle, forces
    opposite), a support contact once. Returns ``(particle, branch (k,2), force (k,2))``.
    """
    c = np.column_stack([state.contact_x, state.contact_y])
    f = np.column_stack([state.force_x, state.force_y])
    i, j = state.contact_i, state.contact_j
    pp = j >= 0
    part = np.concatenate([i, j[pp]])
    pos = np.column_stack([state.x, state.y])
    branch = np.concatenate([c - pos[i], c[pp] - pos[j[pp]]])
    force = np.concatenate([f, -f[pp]])
    return part, branch, force


def particle_stress_moment(state: State) -> np.ndarray:
    """Contact moment ``sum_c x_i^c f_j^c`` of every particle: the sum in paper Eq. 2.

    Parameters
    ----------
    state : State
        A particle state (docs/formats.md#state-files).

    Returns
    -------
    numpy.ndarray
        ``(n_particles, 2, 2)``, N m, first index of the branch vector, second
        of the force acting on the particle (compression negative); support
        contacts count for their particle.
    """
    part, branch, force = contact_ends(state)
    return scatter_tensor(part, branch, force, state.n_particles)


def particle_stress(state: State) -> np.ndarray:
    """Particle stress ``sigma^p_ij = (1/V^p) sum_c x_i^c f_j^c`` (paper Eq. 2).

    Parameters
    ----------
    state : State

    Returns
    -------
    numpy.ndarray
        ``(n_particles, 2, 2)`` in N/m (2D), ``V^p`` = the particle's ``area``.
    """
    return particle_stress_moment(state) / state.area[:, None, None]


def rve_stress(W: sp.csr_matrix, moments: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """RVE stress ``(1/V) sum_{p in RVE} sum_c x_i^c f_j^c`` (Eq. 2 averaged, Sect. 3).

    Equals ``sum_p (V^p/V) sigma^p``: the area average of the particle
    stresses of Eq. 2 over the RVE, voids counting as zero stress.

    Parameters
    ----------
    W : scipy.sparse matrix
        ``(n_rve, n_particles)`` 0/1 membership (:func:`analysis.rve.membership`).
    moments : numpy.ndarray
        ``(n_particles, 2, 2)`` from :func:`particle_stress_moment`.
    volume : numpy.ndarray
        ``(n_rve,)`` RVE areas V (m²).

    Returns
    -------
    numpy.ndarray
        ``(n_rve, 2, 2)`` in N/m, the full (not symmetrised) tensor.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        return rve_sum(W, moments) / np.asarray(volume)[:, None, None]


def symmetric_part(t: np.ndarray) -> np.ndarray:
    """``(t + t^T)/2`` over the last two axes."""
    return 0.5 * (t + np.swapaxes(t, -1, -2))


def antisymmetric_component(t: np.ndarray) -> np.ndarray:
    """``(t_xy - t_yx)/2``, the one independent antisymmetric component in 2D."""
    return 0.5 * (t[..., 0, 1] - t[..., 1, 0])
