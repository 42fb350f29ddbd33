"""The pair-list rebuild policy.

The candidate pairs are those within the Verlet skin (:mod:`sim.broadphase`).
The list is rebuilt before the next step once a particle has moved more than
:data:`REBUILD_FRACTION` of the skin since the last build (the kernels report
it, :func:`sim.step.advance_on`), and after any change of the particle set or
a return to a snapshot.  Tangential springs and narrow-phase witnesses stay
with their pairs across a rebuild.
"""

from __future__ import annotations

import numpy as np

from .broadphase import candidate_pairs, carry_history, match_pairs, particle_pair_index
from .step import ROW_SIZE

#: Displacement since the last build, as a fraction of the skin, that calls
#: for a rebuild: two particles closing in on each other by that much each
#: stay within the skin of the pair they are in.
REBUILD_FRACTION = 0.45


def rebuild_distance_sq(skin):
    """The squared displacement (m²) that calls for a rebuild of a list of `skin` (m)."""
    return (REBUILD_FRACTION * skin) ** 2


def rebuild(state, scene, tangential, parallel):
    """Rebuild the pair list of `state` from its current centres.

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
    pi, pj = candidate_pairs(x, y, scene.shapes.radius, n, scene.skin, parallel)
    match = match_pairs(state.pi, state.pj, pi, pj)
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
    state.pair_offset, state.pair_index = particle_pair_index(pi, pj, n)
    state.pout = np.zeros((len(pi), ROW_SIZE))
    state.pforce = np.zeros((len(pi), 4))
    state.x_ref = x.copy()
    state.y_ref = y.copy()
    state.stale = False
