"""Blow-up detection: non-finite values, deep overlaps, energy rising with no work done.

:func:`check` looks at a state after a chunk of steps; the run loop
(:mod:`sim.run_loop`) returns to the last state that passed and raises
:class:`BlowUpError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .energy import elastic_energy, kinetic_energy, potential_energy
from .step import ROW

#: How much :func:`sim.energy.elastic_energy` can underestimate the stored
#: energy, as a fraction of itself.  For an overlap of area ``A ∝ d^p`` at
#: depth d (contact line ``L = dA/dd``) the work of ``F⊥ = Y A / l`` is
#: ``∫F⊥ dd = p/(p+1) · F⊥ A / L``; the estimate ``F⊥ A / (2L)`` is exact for
#: an edge (p = 1) and 3/4 of it for a corner (p = 2), i.e. low by 1/3.
ELASTIC_UNDERESTIMATE = 1.0 / 3.0

#: Rise of the total energy, as a fraction of the energy scale, that counts as
#: a blow-up: well above the bounded energy error of a stable step, about
#: ``(ω dt)² / 8`` for Verlet.
ENERGY_TOLERANCE = 0.25


class BlowUpError(RuntimeError):
    """The run became unstable; ``last_good`` holds the last state that passed the checks."""

    def __init__(self, message, last_good=None):
        super().__init__(message)
        self.last_good = last_good


@dataclass
class EnergyReference:
    """What the energy check compares with, since the last insertion or gravity change.

    Attributes
    ----------
    energy : float or None
        The lowest upper bound of the true total energy seen; None until the
        first full check.
    movable : float
        Kinetic plus elastic energy at that first check, J/m.
    """

    energy: float | None = None
    movable: float = 0.0

    def reset(self):
        """Start afresh: particles were placed or gravity changed (work was done)."""
        self.energy = None
        self.movable = 0.0


def check(state, scene, reference: EnergyReference, start=False):
    """Blow-up detector: a description of the first problem found, or ``None``.

    Checks non-finite positions or velocities; an overlap above
    ``max_overlap_fraction`` of the smaller particle's area; total energy
    (kinetic + gravitational + elastic) rising by more than
    :data:`ENERGY_TOLERANCE` of the energy scale since the last insertion or
    gravity change, although no work is done.  The scale is ``Σ m |g| R`` or
    the kinetic plus elastic energy at the reference, whichever is larger.
    The elastic energy is an estimate that can be low by up to
    :data:`ELASTIC_UNDERESTIMATE` of itself, so the reference is the lowest
    *upper* bound of the true energy seen and the current energy its lower
    bound: releasing compressed corner contacts is not a rise.

    With ``start`` (after a new simulation's first step) only the first
    two, and only between particles: a start inside the support or a wall
    is resolved (it pushes the particle out), and the energy reference is
    taken at the first full check, once such a start has relaxed.

    Parameters
    ----------
    state : sim.state.State
    scene : sim.scene.Scene
    reference : EnergyReference
        Taken at the first full check, lowered at each later one.
    start : bool
    """
    problem = _bad_values(state, scene.model.max_overlap_fraction, start)
    if problem or start:
        return problem
    elastic = elastic_energy(state, scene)
    energy = kinetic_energy(state, scene) + potential_energy(state, scene) + elastic
    # the true energy lies in [energy, energy + ELASTIC_UNDERESTIMATE * elastic]
    upper = energy + ELASTIC_UNDERESTIMATE * elastic
    if reference.energy is None:
        reference.energy = upper
        reference.movable = kinetic_energy(state, scene) + elastic
        return None
    scale = _energy_scale(state, scene, reference.movable)
    if energy - reference.energy > ENERGY_TOLERANCE * scale:
        return (f"total energy rose by {energy - reference.energy:.3g} J/m "
                f"(> {ENERGY_TOLERANCE:.0%} of the energy scale {scale:.3g} J/m) "
                "with no work done")
    reference.energy = min(reference.energy, upper)
    return None


def _bad_values(state, max_overlap, start):
    """Non-finite values or an overlap deeper than ``max_overlap`` (between
    particles only with ``start``), described; or None."""
    n = state.n
    if not np.all(np.isfinite(state.r[:, :, :n])):
        bad = int(np.argmax(~np.all(np.isfinite(state.r[:, :, :n]), axis=(0, 1))))
        return f"non-finite position or velocity of particle {bad}"
    ratio = 0.0
    rows = state.pout
    if rows.shape[0]:
        ratio = float(np.max(rows[:, ROW["ratio"]] * rows[:, ROW["active"]]))
    if not start and state.bout.shape[0]:
        b = state.bout[:, :n]
        ratio = max(ratio, float(np.max(b[..., ROW["ratio"]] * b[..., ROW["active"]])))
    if ratio > max_overlap:
        return (f"an overlap of {ratio:.3g} of a particle's area exceeds "
                f"model.max_overlap_fraction = {max_overlap}")
    return None


def _energy_scale(state, scene, movable):
    n = max(state.n, 1)
    g = np.hypot(*state.gravity)
    lift = float(np.sum(scene.shapes.mass[:n] * g * scene.shapes.radius[:n]))
    return max(lift, movable, 1e-300)
