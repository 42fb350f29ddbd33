"""The pair-list rebuild policy.

The candidate pairs are those within the Verlet skin (:mod:`sim.broadphase`)
at each particle's *reference centre*, where it was when its pairs were last
tested.  The list is refreshed before the next step once a particle has
moved more than :data:`REBUILD_FRACTION` of the skin from its reference (the
kernels report it, :func:`sim.step.advance_on`; ``State.moved``): only the
particles past :data:`REFRESH_FRACTION` of that distance take new references
and have their pairs tested anew
(:func:`sim.broadphase.refreshed_pairs`), so a falling particle does not
rebuild everyone's list.  Every pair stays valid while both its particles
are within that distance of their references, wherever those lie.  After
any change of the particle set, a return to a snapshot or new velocities
(``State.stale``), and when many particles moved, the whole list is built
from the current centres.  Tangential springs and narrow-phase witnesses
stay with their pairs across either.
"""

from __future__ import annotations

import numpy as np

from .broadphase import (candidate_pairs, carry_history, match_pairs, particle_pair_index,
                         refreshed_pairs)
from .contact_law import pair_damping_coefficients
from .step import ROW_SIZE

#: Displacement from a particle's reference centre, as a fraction of the
#: skin, that calls for a refresh: two particles closing in on each other by
#: that much each stay within the skin of the pair they are in.
REBUILD_FRACTION = 0.45

#: At a refresh, the particles that moved more than this fraction of the
#: limit take new references (:func:`rebuild`).
REFRESH_FRACTION = 0.5

#: Up to this many moved particles only their pairs are refreshed; beyond it
#: the whole list is built.  Each moved particle's pairs cost a scan of all n
#: particles, the whole build about 20 tests per particle (its 3 × 3 cells).
MOST_REFRESHED = 16


def rebuild_distance_sq(skin):
    """The squared displacement (m²) that calls for a rebuild of a list of `skin` (m)."""
    return (REBUILD_FRACTION * skin) ** 2


def rebuild(state, scene, tangential, parallel):
    """Refresh the pair list of `state` (module docstring): the pairs of the
    particles that moved past :data:`REFRESH_FRACTION` of the limit, or,
    where ``state.stale`` or more than :data:`MOST_REFRESHED` moved, the
    whole list from the current centres.

    Parameters
    ----------
    state : sim.state.State
    scene : sim.scene.Scene
    tangential : bool
        Whether pairs carry tangential springs (else they restart at 0).
    parallel : bool
        Use the parallel build of the broad phase.
    """
    n = state.n
    x = np.ascontiguousarray(state.r[0, 0, :n])
    y = np.ascontiguousarray(state.r[0, 1, :n])
    moved = None
    if not state.stale:
        # past half the limit, not only past it: particles creeping through a
        # settling pile are then swept along by the refreshes that falling
        # ones call for, instead of each calling one of its own
        moved = ((x - state.x_ref) ** 2 + (y - state.y_ref) ** 2 >
                 REFRESH_FRACTION ** 2 * rebuild_distance_sq(scene.skin))
        if np.count_nonzero(moved) > MOST_REFRESHED:
            moved = None
    if moved is None:
        pi, pj = candidate_pairs(x, y, scene.shapes.radius, n, scene.skin, parallel)
        match = match_pairs(state.pi, state.pj, pi, pj)
        state.x_ref = x.copy()
        state.y_ref = y.copy()
    else:
        state.x_ref[moved] = x[moved]
        state.y_ref[moved] = y[moved]
        pi, pj, match = refreshed_pairs(state.x_ref, state.y_ref, scene.shapes.radius, n,
                                        scene.skin, moved, state.pi, state.pj)
    if tangential:
        state.spring = carry_history(match, state.spring)
    else:
        state.spring = np.zeros(len(pi))
    # the witnesses stay with their pairs, so that no result depends on when
    # the list was rebuilt (nor on a restart, which rebuilds it)
    state.axis = carry_history(match, state.axis, fill=-1)
    state.cross = carry_history(match, state.cross, fill=-1)
    if not scene.rotate:
        # orientations are fixed: no angular velocity (so θ's prediction is θ)
        state.r[1:, 2, :n] = 0.0
    state.pi, state.pj = pi, pj
    state.pdamping = pair_damping_coefficients(pi, pj, scene.inv_mass,
                                               float(scene.model.youngs_modulus),
                                               float(scene.model.damping))
    state.pair_offset, state.pair_index = particle_pair_index(pi, pj, n)
    state.pout = np.zeros((len(pi), ROW_SIZE))
    state.pforce = np.zeros((len(pi), 4))
    state.stale = False
    state.moved = False
