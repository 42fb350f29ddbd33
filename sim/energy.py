"""Kinetic, gravitational and elastic energy of a state, J/m (per unit depth)."""

from __future__ import annotations

import numpy as np

from .contact_law import tangential_stiffness
from .step import ROW, ROW_SIZE


def kinetic_energy(state, scene):
    """Translational plus rotational kinetic energy of the active particles, J/m."""
    n = state.n
    v = state.r[1, :2, :n].T / scene.dt
    w = state.r[1, 2, :n] / scene.dt
    return 0.5 * float(np.sum(scene.shapes.mass[:n] * np.sum(v * v, axis=1)) +
                       np.sum(scene.shapes.inertia[:n] * w * w))


def potential_energy(state, scene):
    """Gravitational energy ``−Σ m g·x`` of the active particles, J/m."""
    n = state.n
    x = state.r[0, :2, :n]
    g = state.gravity
    return -float(np.sum(scene.shapes.mass[:n] * (g[0] * x[0] + g[1] * x[1])))


def elastic_energy(state, scene):
    """Stored contact energy (estimate), J/m.

    Normal: ``F⊥ A / (2 L)``, exact for an edge-on-edge contact
    (``A = L d``, ``F⊥ ∝ d``); tangential: ``F∥*² / (2 k∥)``.  It can be low
    by :data:`sim.blowup.ELASTIC_UNDERESTIMATE` of itself.
    """
    e = 0.0
    kt = tangential_stiffness(float(scene.model.youngs_modulus))
    n = state.n
    for rows, spring in ((state.pout, state.spring),
                         (state.bout[:, :n].reshape(-1, ROW_SIZE), state.bspring[:, :n].ravel())):
        act = rows[:, ROW["active"]] > 0
        a = rows[act, ROW["area"]]
        length = np.maximum(rows[act, ROW["length"]], np.sqrt(a))
        f = np.hypot(rows[act, ROW["fx"]], rows[act, ROW["fy"]])
        e += float(np.sum(f * a / (2.0 * np.maximum(length, scene.eps))))
        e += float(np.sum(spring[act] ** 2)) / (2.0 * kt)
    return e
