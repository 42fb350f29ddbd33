"""The state of a simulation: a plain structure of the arrays a run changes.

Arrays are sized for a fixed *capacity* of particles, of which the first ``n``
are active (pouring activates them one by one, so nothing is reallocated
while a pile grows):

* ``r``: scaled derivatives of (x, y, θ), shape ``(n_values, 3, capacity)``
  (see :mod:`sim.integrators`);
* the candidate pair list ``pi, pj`` with one tangential spring and one set
  of narrow-phase witnesses per pair (:mod:`sim.broadphase`,
  :mod:`sim.warmstart`), and one spring per particle and fixed body (and per
  particle and slot of its contacts with a rough base, :class:`sim.scene.RoughBase`);
* the contact rows of the last force evaluation (``pout``, ``bout``) and the
  kernels' buffers (predictions, world corners, per-thread scratch).

What a run does not change is in :class:`sim.scene.Scene`.  A
:class:`Snapshot` copies the part of a state that a run continues from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .step import BLOCK, PRED_SIZE, ROW_SIZE, Workspace
from .geometry import make_scratch
from .warmstart import WITNESS_DTYPE

#: Length of each thread's narrow-phase output row (it needs GEOMETRY_SIZE):
#: 512 bytes, so that no two threads write into one cache line (with rows of
#: 10 values they did, at every contact).
THREAD_ROW = 64


@dataclass
class State:
    """Everything a run changes (see the module docstring).

    Attributes
    ----------
    n : int
        Active particles.
    r : numpy.ndarray, shape (n_values, 3, capacity)
        Scaled derivatives ``dt^k/k! d^k q/dt^k``.
    time : float
        Simulated time, s.
    step : int
        Steps done.
    gravity : tuple of float
        Gravity vector, m/s².
    pi, pj : numpy.ndarray
        Candidate pairs (``pi < pj``), sorted.
    spring, axis, cross : numpy.ndarray
        Each pair's tangential spring and narrow-phase witnesses.
    pdamping : numpy.ndarray
        Each pair's coefficient of the normal damping
        (:func:`sim.contact_law.pair_damping_coefficients`).
    pout, pforce : numpy.ndarray
        Each pair's contact row and forces of the last evaluation.
    pair_offset, pair_index : numpy.ndarray
        The pairs of each particle (CSR).
    x_ref, y_ref : numpy.ndarray
        Each particle's reference centre: where it was when its pairs were
        last tested (:mod:`sim.rebuild`).
    stale : bool
        The whole pair list must be built before the next step (the
        particle set, the state or its velocities were set).
    moved : bool
        A particle moved too far from its reference: its pairs must be
        refreshed before the next step.
    bspring, bout : numpy.ndarray
        Tangential spring and contact row of each body and particle, then of
        each slot of the rough base and particle (:class:`sim.step.Bodies`).
    base_owner : numpy.ndarray, shape (base_slots, capacity)
        The base polygon each slot of each particle was last tested against
        (-1: none since the particle was placed).
    base_axis, base_cross : numpy.ndarray
        The narrow-phase witnesses of each slot (``slot * capacity +
        particle``) against its base polygon, as ``axis``, ``cross`` of a pair.
    wx, wy, box, pred, work
        The kernels' buffers: world corners (of the particles, then the
        fixed ones of a rough base's polygons), bounding boxes, predictions,
        per-thread scratch (:class:`sim.step.Workspace`).
    """

    n: int
    r: np.ndarray
    time: float
    step: int
    gravity: tuple
    pi: np.ndarray
    pj: np.ndarray
    spring: np.ndarray
    axis: np.ndarray
    cross: np.ndarray
    pdamping: np.ndarray
    pout: np.ndarray
    pforce: np.ndarray
    pair_offset: np.ndarray
    pair_index: np.ndarray
    x_ref: np.ndarray
    y_ref: np.ndarray
    stale: bool
    moved: bool
    bspring: np.ndarray
    bout: np.ndarray
    base_owner: np.ndarray
    base_axis: np.ndarray
    base_cross: np.ndarray
    wx: np.ndarray
    wy: np.ndarray
    box: np.ndarray
    pred: np.ndarray
    work: Workspace


def new_state(scene, gravity) -> State:
    """An empty :class:`State` of `scene` (no active particle) under `gravity` (m/s²)."""
    shapes, capacity = scene.shapes, scene.capacity
    n_bodies = len(scene.body_ids) + scene.base_slots
    max_corners = int(np.max(shapes.node_count)) if capacity else 3
    base_x, base_y = np.empty(0), np.empty(0)
    if scene.base is not None:
        max_corners = max(max_corners, int(np.max(scene.base.shapes.node_count)))
        base_x, base_y = scene.base.wx, scene.base.wy
    witnesses = scene.base_slots * capacity
    n_threads = numba.config.NUMBA_NUM_THREADS
    return State(
        n=0, r=np.zeros((len(scene.coeffs), 3, capacity)), time=0.0, step=0,
        gravity=(float(gravity[0]), float(gravity[1])),
        pi=np.empty(0, np.int64), pj=np.empty(0, np.int64), spring=np.empty(0),
        axis=np.empty(0, WITNESS_DTYPE), cross=np.empty((0, 4), WITNESS_DTYPE),
        pdamping=np.empty(0),
        pout=np.zeros((0, ROW_SIZE)), pforce=np.zeros((0, 4)),
        pair_offset=np.zeros(1, np.int64), pair_index=np.empty(0, np.int64),
        x_ref=np.empty(0), y_ref=np.empty(0), stale=True, moved=False,
        bspring=np.zeros((n_bodies, capacity)), bout=np.zeros((n_bodies, capacity, ROW_SIZE)),
        base_owner=np.full((scene.base_slots, capacity), -1, np.int64),
        base_axis=np.full(witnesses, -1, WITNESS_DTYPE),
        base_cross=np.full((witnesses, 4), -1, WITNESS_DTYPE),
        wx=np.concatenate([np.zeros_like(shapes.node_x), base_x]),
        wy=np.concatenate([np.zeros_like(shapes.node_y), base_y]),
        box=np.zeros((capacity, 4)), pred=np.zeros((capacity, PRED_SIZE)),
        work=Workspace(np.stack([make_scratch(max_corners) for _ in range(n_threads)]),
                       np.zeros((n_threads, THREAD_ROW)), np.zeros(capacity // BLOCK + 1)))


def forget_particle(state: State, k):
    """Clear particle ``k``'s contact history: the springs and witnesses of its
    pairs, its springs with the bodies and its witnesses against a rough base's
    polygons, as for contacts never made."""
    state.bspring[:, k] = 0.0
    state.base_owner[:, k] = -1
    its_pairs = (state.pi == k) | (state.pj == k)
    state.spring[its_pairs] = 0.0
    state.axis[its_pairs] = -1
    state.cross[its_pairs] = -1


#: The fields of a :class:`State` that a run continues from (the others are
#: rebuilt or rewritten before they are read), with the contact rows of its
#: last force evaluation (``pout``, ``bout``), so that a restored state reports
#: its own contacts.
SNAPSHOT_FIELDS = ("n", "r", "time", "step", "gravity", "pi", "pj", "spring", "axis", "cross",
                   "pout", "bspring", "bout", "base_owner", "base_axis", "base_cross")


class Snapshot:
    """A copy of the :data:`SNAPSHOT_FIELDS` of a :class:`State`, as attributes
    of the same names: enough to continue the run exactly (:func:`restore`)."""

    __slots__ = SNAPSHOT_FIELDS

    def __init__(self, state: State):
        _copy_fields(state, self)


def restore(state: State, snap: Snapshot):
    """Return `state` to `snap`; the pair list is rebuilt before the next step."""
    _copy_fields(snap, state)
    state.stale = True


def _copy_fields(source, target):
    """Copy the :data:`SNAPSHOT_FIELDS` of `source` to `target`, arrays as copies."""
    for name in SNAPSHOT_FIELDS:
        value = getattr(source, name)
        setattr(target, name, value.copy() if isinstance(value, np.ndarray) else value)
