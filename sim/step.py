"""The time step: contact forces, then force gathering, corrector and predictor.

A step is two parallel passes without write races:

1. :func:`pair_forces` (over candidate pairs): narrow phase and contact law
   at the predicted positions and velocities; each pair writes only its own
   force row, spring and witness (and on a run's last step its full row of
   ``Pairs.out``, which the checks and state files read);
2. :func:`gather_and_correct` (over particles): sums the forces of the pairs a
   particle belongs to (in the fixed order of the broad phase's index, so the
   sum is deterministic), adds its contacts with the fixed bodies (support,
   walls, and the polygons of a rough base: :func:`_base_contacts`; their
   spring history is per particle) and gravity, applies the
   integrator's corrector and then already the next step's predictor for
   this particle (:func:`sim.integrators.nordsieck_step`: its predicted
   position and velocity, ``Particles.pred``), and after each block of
   :data:`BLOCK` particles their world corners and bounding boxes
   (:func:`_place_block`), while their data are in cache.

``Particles.r`` always holds the corrected state (what state files save);
the prediction lives in ``pred`` (:func:`sim.integrators.nordsieck_predicted`,
bit for bit the values the corrector starts from).  A run of steps
(:data:`ADVANCE_SERIAL`, :data:`ADVANCE_PARALLEL`) starts with one :func:`predict_and_place` pass and the last
step predicts nothing.

The state reaches the kernels bundled in four named tuples, so that a kernel's
signature says what it uses: :class:`Particles`, :class:`Pairs`,
:class:`Bodies` and the contact law's parameters :class:`Law`; the integrator's
settings come as :class:`Motion`, the per-thread work arrays as
:class:`Workspace`.

Rows of ``Pairs.out`` (per pair) and ``Bodies.out`` (per body and particle),
see :data:`ROW`: the narrow phase's output (area, c1, c2, force point s,
normal n pointing from i to j, contact-line length), then the force on i, the
torques on i and j, the overlap fraction and an active flag.

Contacts live for thousands of steps, and most candidate pairs that do not
touch stay apart for as long.  Each candidate pair keeps a witness of its last
narrow phase (:mod:`sim.warmstart`): the edge that separated it, or the edges
that crossed at its contact points.  While the witness holds, a pair costs a
projection of one polygon's corners (apart) or two segment crossings and a few
inside tests (in contact); only the others are clipped
(:func:`sim.geometry.polygon_overlap_range`).  Both tests are exact.

Work a scene does not need is skipped, decided per run by flags: without
damping (γ = 0) no damping force, without friction (μ = 0) no tangential force
and no spring history (the springs are neither read nor written), and without
rotation no orientation is corrected (its rates stay zero, so its prediction
is θ itself).  Where a flag is off, the full law would compute exactly zero
for the skipped term.

Every kernel exists in a serial and a parallel build (:data:`KERNELS_SERIAL`,
:data:`KERNELS_PARALLEL`, :func:`sim.builds.build`): below a few hundred
particles starting a parallel region costs more than the work.  The
loops touch arrays only by index (no array views per pair or particle), so no
reference counts are updated in the hot loops.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np
from numba import prange

from .builds import build
from .contact_law import (characteristic_length, damping_coefficient, elastic_force,
                          normal_force, reduced_mass, tangential_force, tangential_mass)
from .geometry import halfplane_overlap_range, polygon_overlap_range
from .integrators import nordsieck_predicted, nordsieck_step
from .kernel_cache import njit
from .rotation import cos_sin
from .warmstart import axis_separates, find_axis, find_crossings, overlap_from_crossings

ROW = {"area": 0, "c1x": 1, "c1y": 2, "c2x": 3, "c2y": 4, "sx": 5, "sy": 6, "nx": 7,
       "ny": 8, "length": 9, "fx": 10, "fy": 11, "torque_i": 12, "torque_j": 13,
       "ratio": 14, "active": 15}
ROW_SIZE = 16
GEOMETRY_SIZE = 10  # the narrow phase's part of a row (area .. length)
PRED_SIZE = 8  # x, y, θ, r1x, r1y, r1θ, cos θ, sin θ of Particles.pred
BLOCK = 256  # particles per parallel work item of the predictor and the gather
PAIR_BLOCK = 128  # pairs per parallel work item of the pair pass

Particles = namedtuple("Particles", "r pred node_offset node_x node_y wx wy box mass "
                                    "inv_mass inv_inertia area")
Particles.__doc__ = """The particles' state and shapes (capacity-sized arrays).

r : (n_values, 3, capacity) scaled derivatives of (x, y, θ)
(:mod:`sim.integrators`), corrected; pred : (capacity, PRED_SIZE) the step's
prediction of ``r_0`` and ``r_1`` (x, y, θ, then their scaled rates:
velocity × dt) and the cosine and sine of its θ (one row of 64 bytes per
particle); node_offset, node_x, node_y : CSR body-frame corners; wx, wy :
world corners (of the prediction); box : (capacity, 4) bounding boxes (xmin,
xmax, ymin, ymax); mass, inv_mass, inv_inertia, area : per particle.
"""

Pairs = namedtuple("Pairs", "i j spring damping axis cross out force offset index")
Pairs.__doc__ = """The candidate pairs of the broad phase (:mod:`sim.broadphase`).

i, j : particle indices (i < j, sorted); spring : tangential spring force;
damping : the coefficient γ sqrt(Y m⊥) of the normal damping of each pair
(:func:`sim.contact_law.pair_damping_coefficients`; it saves a division and
a square root per contact and step); axis : (n_pairs,) separating edge,
cross : (n_pairs, 4) crossing edges (witnesses of the last step,
:mod:`sim.warmstart`, of type :data:`sim.warmstart.WITNESS_DTYPE`); out :
(n_pairs, ROW_SIZE) rows; force : (n_pairs, 4) the force on i (x, y) and the
torques on i and j, zero where the pair does not touch (the gather's
compact copy of the rows' force columns); offset, index : CSR list of the
pairs of each particle
(:func:`sim.broadphase.particle_pair_index`: ``2 p`` where the particle is
the pair's i, ``2 p + 1`` where it is its j).
"""

Bodies = namedtuple("Bodies", "point normal friction spring out base_offset base_box "
                              "base_centre base_area base_top owner axis cross")
Bodies.__doc__ = """Fixed bodies of infinite mass: half-planes ``{q : (q − point)·normal < 0}``
and the polygons of a rough base (:class:`sim.scene.RoughBase`).

point, normal : (n_bodies, 2), normal is the unit outward normal; friction :
(n_bodies,) μ with particles; spring : (n_bodies + slots, capacity)
tangential springs; out : (n_bodies + slots, capacity, ROW_SIZE) rows: first
those of the half-planes, then ``slots`` rows per particle for its contacts
with base polygons (polygon b in row ``n_bodies + b % slots``);
base_offset : (n_base + 1,) where the base polygons' world corners lie in
``Particles.wx, wy`` (after the particles'; they never change); base_box :
(n_base, 4) their bounding boxes, in increasing x; base_centre : (n_base, 2);
base_area : (n_base,); base_top : their highest corner; owner : (slots,
capacity) the base polygon each slot of each particle was last tested
against (-1: none); axis, cross : (slots × capacity,) and (slots × capacity,
4) the narrow-phase witnesses of slot s of particle i at ``s * capacity +
i``, as those of a pair.
"""

Law = namedtuple("Law", "youngs_modulus damping friction eps damped tangential "
                        "body_tangential")
Law.__doc__ = """Contact-law parameters and the flags of the terms that can be nonzero.

youngs_modulus (N/m), damping γ, friction μ between particles, eps (length
tolerance of the narrow phase, m); damped: damping force on; tangential:
tangential force between particles; body_tangential: with bodies.
"""

Motion = namedtuple("Motion", "dt coeffs gravity_x gravity_y drag spin_drag rotate")
Motion.__doc__ = """Integrator settings: time step (s), corrector coefficients, gravity
(m/s²), background drag on the translation and on the rotation (1/s; the
first while relaxing only, the second also ``pour.spin_drag`` while pouring)
and whether θ is integrated."""

Workspace = namedtuple("Workspace", "scratch out block_moved")
Workspace.__doc__ = """Work arrays: per thread (indexed by Numba's thread id) the
clipping scratch (n_threads, 7, cap) (:func:`sim.geometry.make_scratch`) and a
narrow-phase output row (n_threads, >= GEOMETRY_SIZE; rows of 512 bytes, so
that two threads never write one cache line); per block of BLOCK particles
the largest squared displacement (n_blocks,)."""


def predict_and_place(n, pt, motion, work):
    """Prediction, world corners and bounding boxes of the first n particles.

    Starts a run of steps (:func:`advance_on`); within it,
    :func:`gather_and_correct` predicts each particle right after correcting it.

    Parameters
    ----------
    n : int
        Active particles.
    pt : Particles
        ``pred, wx, wy, box`` receive the prediction, corners and boxes;
        ``r`` is not changed.
    motion : Motion
    work : Workspace
    """
    # fields are unpacked once: taking an array out of a tuple inside the loop
    # would update its reference count at every access
    r, pred, node_offset, node_x, node_y, wx, wy, box = pt[:8]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_blocks):
        start = blk * BLOCK
        stop = min(start + BLOCK, n)
        for i in range(start, stop):
            nordsieck_predicted(r, i, pred)
        _place_block(start, stop, pred, node_offset, node_x, node_y, wx, wy, box)


@njit(cache=True, inline="always")
def _place_block(start, stop, pred, node_offset, node_x, node_y, wx, wy, box):
    """World corners and bounding boxes of particles ``start .. stop - 1`` at
    their predictions ``pred``.

    Two loops: first the cosine and sine of every particle of the block
    (into ``pred[i, 6:8]``, :func:`sim.rotation.cos_sin`), then the corners.
    In one loop each particle's corners waited for its cosine and sine (a
    chain the processor could not overlap with the next particle's work);
    apart, the corners loop has no long chain.  Called from the kernels'
    loops themselves: wrapped in one more inlined function, whose array
    arguments Numba then reference-counts at every call, the prediction cost
    four times as much.
    """
    for i in range(start, stop):
        pred[i, 6], pred[i, 7] = cos_sin(pred[i, 2])
    for i in range(start, stop):
        x = pred[i, 0]
        y = pred[i, 1]
        c = pred[i, 6]
        s = pred[i, 7]
        x0 = np.inf
        x1 = -np.inf
        y0 = np.inf
        y1 = -np.inf
        # unsigned corner indices: Numba then indexes without its test for
        # negative indices (three integer operations per array access)
        for k in range(np.uint64(node_offset[i]), np.uint64(node_offset[i + 1])):
            px = x + c * node_x[k] - s * node_y[k]
            py = y + s * node_x[k] + c * node_y[k]
            wx[k] = px
            wy[k] = py
            x0 = min(x0, px)
            x1 = max(x1, px)
            y0 = min(y0, py)
            y1 = max(y1, py)
        box[i, 0] = x0
        box[i, 1] = x1
        box[i, 2] = y0
        box[i, 3] = y1


@njit(cache=True, inline="always")
def _contact_force(geo, spring, vrx, vry, l, damping, inv_mi, inv_mj, ri, rj, inv_ii,
                   inv_ij, law, friction, dt, tangential):
    """Force on i of one contact whose narrow phase is in ``geo`` (Appendix).

    ``vrx, vry`` is the relative velocity at the force point (read only when
    ``law.damped`` or ``tangential``), ``damping`` the coefficient of the
    normal damping (:func:`sim.contact_law.damping_coefficient`, read only
    when ``law.damped``); without ``law.damped`` the normal force
    is the elastic one, without ``tangential`` there is no tangential force
    and the spring is returned unchanged.

    Returns
    -------
    (float, float, float)
        Force on i (x, y) and the updated spring.
    """
    nx = geo[7]
    ny = geo[8]
    if law.damped:
        f_el, f_n = normal_force(geo[0], geo[9] * (vrx * nx + vry * ny), l, damping,
                                 law.youngs_modulus)
    else:
        f_el = elastic_force(geo[0], l, law.youngs_modulus)
        f_n = f_el
    fx = -f_n * nx
    fy = -f_n * ny
    if tangential:
        tx = -ny
        ty = nx
        t_force, spring = tangential_force(
            spring, vrx * tx + vry * ty, f_el,
            tangential_mass(inv_mi, inv_mj, ri, rj, inv_ii, inv_ij), law.youngs_modulus,
            friction, dt)
        fx -= t_force * tx
        fy -= t_force * ty
    return fx, fy, spring


@njit(cache=True, inline="always")
def _write_row(rows, p, geo, fx, fy, torque_i, torque_j, ratio):
    """Row p of ``rows`` (2D): the narrow phase ``geo``, the force, torques, ratio, active."""
    for k in range(GEOMETRY_SIZE):
        rows[p, k] = geo[k]
    rows[p, 10] = fx
    rows[p, 11] = fy
    rows[p, 12] = torque_i
    rows[p, 13] = torque_j
    rows[p, 14] = ratio
    rows[p, 15] = 1.0


@njit(cache=True, error_model="numpy")
def _clip_pair(wx, wy, a0, a1, b0, b1, xi, yi, xj, yj, eps, geo, S, axis, cross, p):
    """The general narrow phase of pair p, for when its witness failed; finds a new one.

    Not inlined: it runs for few pairs a step, and inlined into the pair loop
    it slowed every pair down.

    Returns
    -------
    bool
        Whether the pair overlaps (then ``geo`` holds its geometry).
    """
    if polygon_overlap_range(wx, wy, a0, a1, wx, wy, b0, b1, xi, yi, xj, yj, eps, geo, S):
        axis[p] = -1
        find_crossings(wx, wy, a0, a1, b0, b1, geo, cross, p)
        return True
    axis[p] = find_axis(wx, wy, a0, a1, b0, b1)
    cross[p, 0] = -1
    return False


def pair_forces(pt, pairs, law, dt, work, record):
    """Narrow phase and contact law for every candidate pair.

    Writes ``pairs.force[p]`` (zero when the pair does not overlap), its
    witness (``pairs.axis[p]``, ``pairs.cross[p]``) and, with ``record``, row
    p of ``pairs.out`` (active flag 0 when the pair does not overlap); with
    ``law.tangential`` it updates ``pairs.spring[p]`` (reset to zero when the
    pair does not overlap, so a new contact starts with an unloaded spring).

    Parameters
    ----------
    pt : Particles
    pairs : Pairs
    law : Law
    dt : float
        Time step, s (velocities are ``pred[:, 3:] / dt``).
    work : Workspace
    record : bool
        Whether to write the rows: only the last step of a run does, since
        only its rows are read (checks, contacts, state files).
    """
    # fields are unpacked once: taking an array out of a tuple inside the loop
    # would update its reference count at every access
    _, pred, node_offset, _, _, wx, wy, box, _, inv_mass, inv_inertia, area = pt
    pi, pj, spring, damping, axis, cross, out, force, _, _ = pairs
    scratch, geo_rows = work[:2]
    tangential = law.tangential
    inv_dt = 1.0 / dt
    n_pairs = pi.shape[0]
    n_blocks = (n_pairs + PAIR_BLOCK - 1) // PAIR_BLOCK
    for blk in prange(n_blocks):
        tid = numba.get_thread_id()
        S = scratch[tid]
        geo = geo_rows[tid]
        for p in range(blk * PAIR_BLOCK, min(blk * PAIR_BLOCK + PAIR_BLOCK, n_pairs)):
            # unsigned particle indices: Numba then indexes without its test
            # for negative indices (as the corner indices of sim.warmstart)
            i = np.uint64(pi[p])
            j = np.uint64(pj[p])
            if record:
                out[p, 15] = 0.0
            for k in range(4):
                force[p, k] = 0.0
            a0 = node_offset[i]
            a1 = node_offset[i + np.uint64(1)]
            b0 = node_offset[j]
            b1 = node_offset[j + np.uint64(1)]
            if (box[i, 1] < box[j, 0] or box[j, 1] < box[i, 0] or
                    box[i, 3] < box[j, 2] or box[j, 3] < box[i, 2] or
                    (axis[p] >= 0 and axis_separates(wx, wy, a0, a1, b0, b1, axis[p]))):
                if tangential:
                    spring[p] = 0.0
                continue
            xi = pred[i, 0]
            yi = pred[i, 1]
            xj = pred[j, 0]
            yj = pred[j, 1]
            if not (overlap_from_crossings(wx, wy, a0, a1, b0, b1, xi, yi, xj, yj, law.eps,
                                           geo, cross, p) or
                    _clip_pair(wx, wy, a0, a1, b0, b1, xi, yi, xj, yj, law.eps, geo, S, axis,
                               cross, p)):
                if tangential:
                    spring[p] = 0.0
                continue
            rix = geo[5] - xi
            riy = geo[6] - yi
            rjx = geo[5] - xj
            rjy = geo[6] - yj
            ri = math.sqrt(rix * rix + riy * riy)
            rj = math.sqrt(rjx * rjx + rjy * rjy)
            l = max(characteristic_length(ri, rj), law.eps)
            vrx = 0.0
            vry = 0.0
            if law.damped or tangential:
                wi = pred[i, 5] * inv_dt
                wj = pred[j, 5] * inv_dt
                vrx = (pred[i, 3] - pred[j, 3]) * inv_dt - wi * riy + wj * rjy
                vry = (pred[i, 4] - pred[j, 4]) * inv_dt + wi * rix - wj * rjx
            fx, fy, sp = _contact_force(geo, spring[p] if tangential else 0.0, vrx, vry, l,
                                        damping[p], inv_mass[i], inv_mass[j], ri, rj,
                                        inv_inertia[i], inv_inertia[j], law, law.friction, dt,
                                        tangential)
            if tangential:
                spring[p] = sp
            tq_i = rix * fy - riy * fx
            tq_j = -(rjx * fy - rjy * fx)
            if record:
                _write_row(out, p, geo, fx, fy, tq_i, tq_j, geo[0] / min(area[i], area[j]))
            force[p, 0] = fx
            force[p, 1] = fy
            force[p, 2] = tq_i
            force[p, 3] = tq_j


@njit(cache=True, error_model="numpy")
def _body_contact(b, i, pred, node_offset, wx, wy, inv_mass, inv_inertia, area, bodies,
                  law, dt, S, geo, record):
    """Force (x, y) and torque on particle i (at its prediction ``pred[i]``) from
    body b, whose box it reaches.

    Not inlined: most particles touch no body, and the clipping inlined into
    the gather's loop slowed every particle down.
    """
    px = bodies.point[b, 0]
    py = bodies.point[b, 1]
    if not halfplane_overlap_range(wx, wy, node_offset[i], node_offset[i + 1], px, py,
                                   bodies.normal[b, 0], bodies.normal[b, 1], law.eps, geo,
                                   S):
        _clear_body_contact(bodies.out, bodies.spring, b, i, law.body_tangential, record)
        return 0.0, 0.0, 0.0
    wi = pred[i, 5] / dt
    rix = geo[5] - pred[i, 0]
    riy = geo[6] - pred[i, 1]
    ri = math.sqrt(rix * rix + riy * riy)
    l = max(characteristic_length(ri, np.inf), law.eps)
    damping = (damping_coefficient(reduced_mass(inv_mass[i], 0.0), law.youngs_modulus,
                                   law.damping) if law.damped else 0.0)
    fx, fy, s = _contact_force(
        geo, bodies.spring[b, i] if law.body_tangential else 0.0,
        pred[i, 3] / dt - wi * riy, pred[i, 4] / dt + wi * rix, l, damping, inv_mass[i], 0.0,
        ri, 0.0, inv_inertia[i], 0.0, law, bodies.friction[b], dt, law.body_tangential)
    if law.body_tangential:
        bodies.spring[b, i] = s
    tq = rix * fy - riy * fx
    if record:
        _write_row(bodies.out[b], i, geo, fx, fy, tq, 0.0, geo[0] / area[i])
    return fx, fy, tq


@njit(cache=True, error_model="numpy")
def _base_contacts(i, pred, node_offset, wx, wy, box, inv_mass, inv_inertia, area, bodies,
                   law, dt, S, geo, record):
    """Force (x, y) and torque on particle i (at its prediction ``pred[i]``) from
    the polygons of the rough base.

    Called for a particle whose box reaches below the base's top.  The
    candidates are the polygons whose x range meets that of i's box (found
    by bisection: the ranges follow each other).  Each is tested as a pair
    is (:func:`pair_forces`: the slot's witness, else the clipping, which
    finds a new one; a slot taken over by another polygon starts without a
    witness), and each contact is that of two particles, the base polygon's
    inverse mass and inertia zero: the same law, Young's modulus and
    friction ``law.friction`` as between particles.  Not inlined, as
    :func:`_body_contact`.

    Returns
    -------
    (float, float, float, int)
        Force (x, y) and torque on i, and the slots in contact as bits
        (slot s: ``1 << s``); the caller clears the others
        (:func:`_clear_body_contact`), so a new contact starts with an
        unloaded spring.
    """
    base_box = bodies.base_box
    first = bodies.point.shape[0]
    slots = bodies.owner.shape[0]
    axis = bodies.axis
    cross = bodies.cross
    capacity = bodies.owner.shape[1]
    a0 = node_offset[i]
    a1 = node_offset[i + 1]
    used = 0
    fx = 0.0
    fy = 0.0
    tq = 0.0
    lo = 0
    hi = base_box.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if base_box[mid, 1] < box[i, 0]:
            lo = mid + 1
        else:
            hi = mid
    for b in range(lo, min(lo + slots, base_box.shape[0])):
        if base_box[b, 0] > box[i, 1]:
            break
        if base_box[b, 2] > box[i, 3] or base_box[b, 3] < box[i, 2]:
            continue
        s = b % slots
        p = s * capacity + i
        if bodies.owner[s, i] != b:
            bodies.owner[s, i] = b
            axis[p] = -1
            cross[p, 0] = -1
        b0 = bodies.base_offset[b]
        b1 = bodies.base_offset[b + 1]
        if axis[p] >= 0 and axis_separates(wx, wy, a0, a1, b0, b1, axis[p]):
            continue
        xi = pred[i, 0]
        yi = pred[i, 1]
        xb = bodies.base_centre[b, 0]
        yb = bodies.base_centre[b, 1]
        if not (overlap_from_crossings(wx, wy, a0, a1, b0, b1, xi, yi, xb, yb, law.eps,
                                       geo, cross, p) or
                _clip_pair(wx, wy, a0, a1, b0, b1, xi, yi, xb, yb, law.eps, geo, S, axis,
                           cross, p)):
            continue
        row = first + s
        rix = geo[5] - xi
        riy = geo[6] - yi
        ri = math.sqrt(rix * rix + riy * riy)
        rb = math.sqrt((geo[5] - xb) ** 2 + (geo[6] - yb) ** 2)
        l = max(characteristic_length(ri, rb), law.eps)
        damping = (damping_coefficient(reduced_mass(inv_mass[i], 0.0), law.youngs_modulus,
                                       law.damping) if law.damped else 0.0)
        wi = pred[i, 5] / dt
        cfx, cfy, sp = _contact_force(
            geo, bodies.spring[row, i] if law.tangential else 0.0,
            pred[i, 3] / dt - wi * riy, pred[i, 4] / dt + wi * rix, l, damping, inv_mass[i],
            0.0, ri, rb, inv_inertia[i], 0.0, law, law.friction, dt, law.tangential)
        if law.tangential:
            bodies.spring[row, i] = sp
        ctq = rix * cfy - riy * cfx
        if record:
            _write_row(bodies.out[row], i, geo, cfx, cfy, ctq, 0.0,
                       geo[0] / min(area[i], bodies.base_area[b]))
        used |= 1 << s
        fx += cfx
        fy += cfy
        tq += ctq
    return fx, fy, tq, used


@njit(cache=True, inline="always")
def _clear_body_contact(bout, bspring, b, i, body_tangential, record):
    """Unload the spring of particle i with body b, which it does not touch, and
    with ``record`` mark its row inactive."""
    if body_tangential:
        bspring[b, i] = 0.0
    if record:
        bout[b, i, 15] = 0.0


def gather_and_correct(n, pt, pairs, bodies, law, motion, work, x_ref, y_ref, record):
    """Total force and torque on each particle, the corrector (Eq. 1), and the
    next step's predictor.

    ``motion.drag`` and ``motion.spin_drag`` (1/s) add the background damping
    ``−drag·m·v`` and ``−spin_drag·I·ω`` (when each is set: :class:`Motion`).

    Parameters
    ----------
    n : int
        Active particles.
    pt, pairs, bodies, law, motion, work
        See the module docstring.
    x_ref, y_ref : numpy.ndarray
        Each particle's reference centre, where its pairs were last tested
        (:mod:`sim.rebuild`).
    record : bool
        The last step of a run: write the body rows (``bodies.out``) and do
        not predict a next step (otherwise: no rows, and the next step's
        ``pred``, corners and boxes).

    Returns
    -------
    float
        The largest squared displacement of a corrected centre from its
        reference, m².
    """
    r, pred, node_offset, node_x, node_y, wx, wy, box, mass, inv_mass, inv_inertia, area = pt
    force, offset, index = pairs[7:]
    point, normal, _, bspring, bout = bodies[:5]
    base_slots = bodies.owner.shape[0]
    base_top = bodies.base_top
    scratch, geo_rows, block_moved = work
    coeffs = motion.coeffs
    dt = motion.dt
    drag = motion.drag
    spin_drag = motion.spin_drag
    gx = motion.gravity_x
    gy = motion.gravity_y
    rotate = motion.rotate
    n_bodies = point.shape[0]
    half_dt2 = 0.5 * dt * dt
    n_blocks = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_blocks):
        tid = numba.get_thread_id()
        S = scratch[tid]
        geo = geo_rows[tid]
        bm = 0.0
        start = blk * BLOCK
        stop = min(start + BLOCK, n)
        for i in range(start, stop):
            fx = mass[i] * gx
            fy = mass[i] * gy
            tq = 0.0
            for q in range(offset[i], offset[i + 1]):
                # index 2 p where i is pair p's i, 2 p + 1 where it is its j:
                # the force on j is minus that on i (sign × force: the same bits
                # as a subtraction), its torque the next column; no branch
                side = index[q] & 1
                p = index[q] >> 1
                sign = 1.0 - 2.0 * side
                fx += sign * force[p, 0]
                fy += sign * force[p, 1]
                tq += force[p, 2 + side]
            for b in range(n_bodies):
                # the corner of i's box deepest into the body decides whether to clip
                mx = normal[b, 0]
                my = normal[b, 1]
                if ((box[i, 0] if mx > 0.0 else box[i, 1]) - point[b, 0]) * mx + \
                        ((box[i, 2] if my > 0.0 else box[i, 3]) - point[b, 1]) * my >= 0.0:
                    _clear_body_contact(bout, bspring, b, i, law.body_tangential, record)
                    continue
                bfx, bfy, btq = _body_contact(b, i, pred, node_offset, wx, wy, inv_mass,
                                              inv_inertia, area, bodies, law, dt, S, geo,
                                              record)
                fx += bfx
                fy += bfy
                tq += btq
            if base_slots:
                touched = 0
                if box[i, 2] < base_top:
                    bfx, bfy, btq, touched = _base_contacts(i, pred, node_offset, wx, wy, box,
                                                            inv_mass, inv_inertia, area, bodies,
                                                            law, dt, S, geo, record)
                    fx += bfx
                    fy += bfy
                    tq += btq
                for s in range(base_slots):
                    if not (touched >> s) & 1:
                        _clear_body_contact(bout, bspring, n_bodies + s, i, law.tangential,
                                            record)
            ax = fx * inv_mass[i]
            ay = fy * inv_mass[i]
            # the drag's divisions only where there is drag: without it the
            # term is a zero, whose subtraction changes no bit (the sums start
            # at +0.0, so they are never -0.0)
            if drag != 0.0:
                ax -= drag * pred[i, 3] / dt
                ay -= drag * pred[i, 4] / dt
            nordsieck_step(r, i, 0, half_dt2 * ax, coeffs, pred, not record)
            nordsieck_step(r, i, 1, half_dt2 * ay, coeffs, pred, not record)
            if rotate:
                alpha = tq * inv_inertia[i]
                if spin_drag != 0.0:
                    alpha -= spin_drag * pred[i, 5] / dt
                nordsieck_step(r, i, 2, half_dt2 * alpha, coeffs, pred, not record)
            elif not record:
                # θ keeps its value (zero rates): its prediction is θ itself
                pred[i, 2] = r[0, 2, i]
                pred[i, 5] = 0.0
            dx = r[0, 0, i] - x_ref[i]
            dy = r[0, 1, i] - y_ref[i]
            bm = max(bm, dx * dx + dy * dy)
        if not record:
            _place_block(start, stop, pred, node_offset, node_x, node_y, wx, wy, box)
        block_moved[blk] = bm
    # the blocks' maxima, not a reduction variable of the parallel loop:
    # reductions need Numba's reference counting, which the kernels go without
    moved = 0.0
    for blk in range(n_blocks):
        moved = max(moved, block_moved[blk])
    return moved


KERNELS = (predict_and_place, pair_forces, gather_and_correct)


# The serial builds go without Numba's reference counting (NRT): they
# allocate nothing, and with it every array handed to an inlined helper
# was counted at every pair (atomic operations; the pair pass took about
# 30 % longer).  The parallel builds keep it: without it they were
# slower than the old code's parallel builds in 3 of 6 paired timings,
# with it faster in 2 of 2 (reason not found; left for the next person).
#: Parallel builds of (predict, pairs, gather), for a few hundred particles and more.
KERNELS_PARALLEL = tuple(build(k, True, nrt=True) for k in KERNELS)
#: Serial builds of the same kernels.
KERNELS_SERIAL = tuple(build(k, False, nrt=False) for k in KERNELS)


def advance_on(kernels):
    """:func:`advance` for one set of kernels (:data:`KERNELS_PARALLEL` or
    :data:`KERNELS_SERIAL`), which it calls as constants.

    Not handed in as an argument: Numba types a tuple of dispatchers in
    Python at every call (``inspect.signature`` of each), about 0.3 ms per
    run of steps, which a pour makes every few dozen steps (11 % of a
    700-particle pour's time under cProfile).  Not cached either: a closure
    over dispatchers is compiled in each process, well under a second.
    """
    predict, pair_pass, gather = kernels

    @njit(cache=False)
    def advance(n_steps, n, pt, pairs, bodies, law, motion, work, x_ref, y_ref, rebuild_sq):
        """Run up to ``n_steps`` steps; stop early when the pair list needs a rebuild.

        Parameters
        ----------
        n_steps, n : int
            Steps to run, active particles.
        pt, pairs, bodies, law, motion, work
            See the module docstring.
        x_ref, y_ref : numpy.ndarray
            Reference centres (:mod:`sim.rebuild`).
        rebuild_sq : float
            Squared displacement from a reference that calls for a refresh
            of the pair list, m².

        Returns
        -------
        done : int
            Steps done.
        moved : bool
            Some particle moved more than ``sqrt(rebuild_sq)`` from its
            reference centre: the list must be refreshed before the next step
            (also when that happened in the last of the ``n_steps``).
        """
        predict(n, pt, motion, work)
        for s in range(n_steps):
            last = s + 1 == n_steps
            pair_pass(pt, pairs, law, motion.dt, work, last)
            if gather(n, pt, pairs, bodies, law, motion, work, x_ref, y_ref, last) > rebuild_sq:
                return s + 1, True
        return n_steps, False

    return advance


#: Runs of steps (:func:`advance_on`) on the parallel and on the serial kernels.
ADVANCE_PARALLEL = advance_on(KERNELS_PARALLEL)
ADVANCE_SERIAL = advance_on(KERNELS_SERIAL)
