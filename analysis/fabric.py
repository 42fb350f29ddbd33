"""Fabric tensor of polygonal particles (paper Eqs 10–12, Sect. 4).

``n^c`` is the unit vector from the particle's centre of mass to the contact
point (Eq. 11). Contacts with the support count like any other contact of the
particle (the support touches the particle at that point; leaving it out
would make the bottom row look under-connected). The RVE fabric is the
volume-weighted average ``sum_p V^p F^p / sum_p V^p`` over member particles
(Sect. 4.1), so its trace is the area-weighted mean contact number.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .orientation import principal_values
from .rve import rve_sum
from .states import State
from .stress import contact_ends, scatter_tensor


def particle_fabric(state: State) -> np.ndarray:
    """Single-particle fabric ``F^p_ij = sum_c n_i^c n_j^c`` (Eqs 10–11).

    Its trace is the contact number ``C^p`` (Eq. 12). A contact point that
    coincides with the centre (zero branch vector) has no direction and is
    skipped.

    Parameters
    ----------
    state : State

    Returns
    -------
    numpy.ndarray
        ``(n_particles, 2, 2)``, dimensionless.
    """
    part, branch, _ = contact_ends(state)
    norm = np.hypot(branch[:, 0], branch[:, 1])
    ok = norm > 0
    n = branch[ok] / norm[ok, None]
    return scatter_tensor(part[ok], n, n, state.n_particles)


def rve_fabric(W: sp.csr_matrix, fabric: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Volume-weighted RVE fabric ``sum_p V^p F^p / sum_p V^p`` (Sect. 4.1, Eqs 10–12).

    Parameters
    ----------
    W : scipy.sparse matrix
        ``(n_rve, n_particles)`` membership.
    fabric : numpy.ndarray
        ``(n_particles, 2, 2)`` from :func:`particle_fabric`.
    area : numpy.ndarray
        ``(n_particles,)`` particle areas ``V^p``.

    Returns
    -------
    numpy.ndarray
        ``(n_rve, 2, 2)``; NaN for an RVE without particles.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        return rve_sum(W, area[:, None, None] * fabric) / rve_sum(W, area)[:, None, None]


def fabric_trace(F: np.ndarray) -> np.ndarray:
    """``tr F = F_max + F_min`` (Eq. 12 averaged: mean contact number)."""
    return F[..., 0, 0] + F[..., 1, 1]


def deviatoric_fraction(F: np.ndarray) -> np.ndarray:
    """Deviatoric fraction ``F_D / tr F = (F_max - F_min)/(F_max + F_min)`` (Sect. 4.2)."""
    lo, hi = principal_values(F)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (hi - lo) / (hi + lo)
