"""The contacts of a state's last force evaluation: listed, their history loaded,
a body's surface stretched under them, and the net force they leave."""

from __future__ import annotations

import numpy as np

from .broadphase import carry_history, match_pairs
from .contact_law import tangential_stiffness
from .scene import BODY_BASE
from .step import ROW, ROW_SIZE
from .warmstart import WITNESS_DTYPE


def contacts(state, scene):
    """The active contacts of the last force evaluation (docs/formats.md#state-files).

    Returns
    -------
    dict of numpy.ndarray
        ``i``, ``j`` (j < 0: a body; ``BODY_BASE - b``: base polygon b),
        ``x``, ``y`` (force point), ``fx``,
        ``fy`` (total force on i), ``nx``, ``ny`` (normal from i to j),
        ``area``, ``spring`` (tangential history), ``witness`` (n, 4): the
        crossing edges the narrow phase starts from next step
        (:mod:`sim.warmstart`; -1 for the half-plane bodies).
    """
    rows = state.pout
    act = np.flatnonzero(rows[:, ROW["active"]] > 0) if rows.shape[0] else np.empty(0, int)
    parts_i = [state.pi[act]]
    parts_j = [state.pj[act]]
    parts_rows = [rows[act]]
    parts_spring = [state.spring[act]]
    parts_witness = [state.cross[act]]
    n_half = len(scene.body_ids)
    for b in range(n_half + scene.base_slots):
        brow = state.bout[b, :state.n]
        bact = np.flatnonzero(brow[:, ROW["active"]] > 0)
        parts_i.append(bact)
        parts_j.append(np.full(len(bact), scene.body_ids[b], np.int64) if b < n_half else
                       BODY_BASE - state.base_owner[b - n_half, bact])
        parts_rows.append(brow[bact])
        parts_spring.append(state.bspring[b, bact])
        parts_witness.append(np.full((len(bact), 4), -1, np.int64) if b < n_half else
                             state.base_cross[(b - n_half) * scene.capacity + bact])
    allrows = np.concatenate(parts_rows) if parts_rows else np.zeros((0, ROW_SIZE))
    return {
        "i": np.concatenate(parts_i).astype(np.int64),
        "j": np.concatenate(parts_j).astype(np.int64),
        "x": allrows[:, ROW["sx"]], "y": allrows[:, ROW["sy"]],
        "fx": allrows[:, ROW["fx"]], "fy": allrows[:, ROW["fy"]],
        "nx": allrows[:, ROW["nx"]], "ny": allrows[:, ROW["ny"]],
        "area": allrows[:, ROW["area"]],
        "spring": np.concatenate(parts_spring),
        "witness": np.concatenate(parts_witness),
    }


def touching(state, scene):
    """Mask of the active particles with a contact (a particle or a body) in
    the last force evaluation: :func:`contacts`'s ``i`` and ``j``, read from
    the rows' active flags alone, without listing the contacts (a pour asks
    at every release)."""
    mask = np.zeros(state.n, bool)
    rows = state.pout
    if rows.shape[0]:
        act = rows[:, ROW["active"]] > 0
        mask[state.pi[act]] = True
        mask[state.pj[act]] = True
    if state.bout.shape[0]:
        mask |= np.any(state.bout[:, :state.n, ROW["active"]] > 0, axis=0)
    return mask


def load_history(state, scene, ci, cj, spring, witness=None):
    """Load the history of contacts ``(ci, cj)`` (j < 0: a body, i < j otherwise)
    into `state`, whose pair list must be current.

    ``spring`` is their tangential springs, ``witness`` (n_contacts, 4) their
    narrow-phase witnesses (:mod:`sim.warmstart`; as from :func:`contacts`),
    which a restart needs to retrace the run bit for bit.
    """
    for b, bid in enumerate(scene.body_ids):
        sel = cj == bid
        state.bspring[b, ci[sel]] = spring[sel]
    if scene.base_slots:
        sel = cj <= BODY_BASE
        polygon = BODY_BASE - cj[sel]
        slot = polygon % scene.base_slots
        state.bspring[len(scene.body_ids) + slot, ci[sel]] = spring[sel]
        state.base_owner[slot, ci[sel]] = polygon
        if witness is not None:
            at = slot * scene.capacity + ci[sel]
            state.base_axis[at] = -1
            state.base_cross[at] = witness[sel]
    pair = cj >= 0
    lo = np.minimum(ci[pair], cj[pair])
    hi = np.maximum(ci[pair], cj[pair])
    order = np.lexsort((hi, lo))
    match = match_pairs(lo[order], hi[order], state.pi, state.pj)
    state.spring = carry_history(match, spring[pair][order])
    if witness is not None:
        state.cross = carry_history(match, witness[pair][order].astype(WITNESS_DTYPE),
                                    fill=-1)


def stretch_body(state, scene, body_id, strain):
    """Stretch the surface of a half-plane body by ``strain`` along itself.

    The surface point at ``q`` moves tangentially by ``strain (q − p)·t t``
    (``p`` the body's point, ``t`` its tangent), which in the contact law
    is a move of each tangential spring's anchor: the spring of every
    particle touching the body in the last force evaluation changes by
    ``−(2/7) Y strain (s − p)·t`` at its force point ``s`` (the spring
    opposes the particle's displacement relative to the surface).  The
    Coulomb cap applies at the next step, as for any spring.  The body
    itself stays where it is: a half-plane is the same after a move along
    its surface, so nothing but the springs remembers the stretch (state
    files and restarts need nothing new).  For the support (``p = 0``,
    ``t = x̂``) a contact at ``x`` is dragged by ``strain · x``.

    Parameters
    ----------
    state : sim.state.State
    scene : sim.scene.Scene
        It must have the body.
    body_id : int
        ``BODY_SUPPORT`` (-1), ``BODY_LEFT`` or ``BODY_RIGHT``.
    strain : float
        The increment of the surface's tangential strain (dimensionless,
        > 0 stretches).

    Returns
    -------
    int
        The contacts whose spring was moved.
    """
    b = int(np.flatnonzero(scene.body_ids == body_id)[0])
    rows = state.bout[b, :state.n]
    act = np.flatnonzero(rows[:, ROW["active"]] > 0)
    tx, ty = -rows[act, ROW["ny"]], rows[act, ROW["nx"]]
    along = ((rows[act, ROW["sx"]] - scene.body_p[b, 0]) * tx
             + (rows[act, ROW["sy"]] - scene.body_p[b, 1]) * ty)
    state.bspring[b, act] -= tangential_stiffness(float(scene.model.youngs_modulus)) * strain * along
    return int(act.size)


def net_forces(state, scene):
    """Net force (n, 2) on each active particle from the last evaluation plus gravity."""
    c = contacts(state, scene)
    n = state.n
    f = np.zeros((n, 2))
    np.add.at(f[:, 0], c["i"], c["fx"])
    np.add.at(f[:, 1], c["i"], c["fy"])
    pair = c["j"] >= 0
    np.add.at(f[:, 0], c["j"][pair], -c["fx"][pair])
    np.add.at(f[:, 1], c["j"][pair], -c["fy"][pair])
    m = scene.shapes.mass[:n]
    f[:, 0] += m * state.gravity[0]
    f[:, 1] += m * state.gravity[1]
    return f
