"""The time step: predictor, contact forces, force gathering and corrector.

A step is three parallel passes without write races:

1. :func:`predict_and_place` (over particles): integrator predictor, corners in
   world coordinates, bounding boxes;
2. :func:`pair_forces` (over candidate pairs): narrow phase and contact law;
   each pair writes only its own row of ``pout`` and its own spring;
3. :func:`gather_and_correct` (over particles): sums the rows of the pairs a
   particle belongs to (in the fixed order of the broad phase's index, so the
   sum is deterministic), adds its contacts with the fixed bodies (support,
   walls; their spring history is per particle) and gravity, then applies the
   corrector.

Rows of ``pout`` (per pair) and ``bout`` (per body and particle), see
:data:`ROW`: the narrow phase's output (area, c1, c2, force point s, normal n
pointing from i to j, contact-line length), then the force on i, the torques
on i and j, the overlap fraction and an active flag.  ``scratch`` holds one
clipping work array per thread (:func:`sim.geometry.make_scratch`), indexed by
Numba's thread id.

Work a scene does not need is skipped, decided per run by flags: without
damping (γ = 0) no damping force, without friction (μ = 0) no tangential force
and no spring history (``spring`` and ``bspring`` are neither read nor
written), and without rotation no orientation is predicted or corrected (the
corners are placed with the cached ``cos θ, sin θ`` of ``cs``).  Where a
flag is off, the full law would compute exactly zero for the skipped term.
"""

from __future__ import annotations

import math
import warnings

import numba
import numpy as np
from numba import njit, prange

from .contact_law import (characteristic_length, elastic_force, normal_force,
                          reduced_mass, tangential_force, tangential_mass)
from .geometry import halfplane_overlap_range, polygon_overlap_range

ROW = {"area": 0, "c1x": 1, "c1y": 2, "c2x": 3, "c2y": 4, "sx": 5, "sy": 6, "nx": 7,
       "ny": 8, "length": 9, "fx": 10, "fy": 11, "torque_i": 12, "torque_j": 13,
       "ratio": 14, "active": 15}
ROW_SIZE = 16
BLOCK = 256  # particles per parallel work item of the predictor


def predict_and_place(r, n, node_offset, node_x, node_y, wx, wy, box, rotate, cs):
    """Integrator predictor, world corners and bounding boxes of the first n particles.

    Parameters
    ----------
    r : numpy.ndarray, shape (n_values, 3, capacity)
        Scaled derivatives of (x, y, θ); replaced by their prediction (θ only
        when ``rotate``).
    node_offset, node_x, node_y : numpy.ndarray
        Body-frame corners (CSR).
    wx, wy : numpy.ndarray
        Output world corners.
    box : numpy.ndarray, shape (capacity, 4)
        Output bounding boxes (xmin, xmax, ymin, ymax).
    rotate : bool
        Whether orientations are integrated.
    cs : numpy.ndarray, shape (capacity, 2)
        ``cos θ, sin θ`` of each particle, used instead of θ when not ``rotate``.
    """
    nv = r.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_blocks):
        lo = blk * BLOCK
        hi = min(lo + BLOCK, n)
        # Pascal-triangle predictor as repeated in-place sweeps, particles
        # innermost so the loop vectorises
        for d in range(3 if rotate else 2):
            for top in range(nv - 1, 0, -1):
                for k in range(top - 1, nv - 1):
                    for i in range(lo, hi):
                        r[k, d, i] += r[k + 1, d, i]
        for i in range(lo, hi):
            if rotate:
                _place(r, i, math.cos(r[0, 2, i]), math.sin(r[0, 2, i]), node_offset, node_x,
                       node_y, wx, wy, box)
            else:
                _place(r, i, cs[i, 0], cs[i, 1], node_offset, node_x, node_y, wx, wy, box)


@njit(cache=True, inline="always")
def _place(r, i, c, s, node_offset, node_x, node_y, wx, wy, box):
    """World corners and bounding box of particle i at orientation ``(cos θ, sin θ) = (c, s)``."""
    x = r[0, 0, i]
    y = r[0, 1, i]
    x0 = np.inf
    x1 = -np.inf
    y0 = np.inf
    y1 = -np.inf
    for k in range(node_offset[i], node_offset[i + 1]):
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
def _separated_along_centres(wx, wy, a0, a1, b0, b1, xi, yi, xj, yj):
    """Separating-axis test on the line of centres (cheap rejection before clipping)."""
    dx = xj - xi
    dy = yj - yi
    amax = -np.inf
    for k in range(a0, a1):
        amax = max(amax, (wx[k] - xi) * dx + (wy[k] - yi) * dy)
    for k in range(b0, b1):
        if (wx[k] - xi) * dx + (wy[k] - yi) * dy < amax:
            return False
    return True


@njit(cache=True, inline="always")
def _contact_force(row, spring, vrx, vry, l, inv_mi, inv_mj, ri, rj, inv_ii, inv_ij,
                   youngs_modulus, damping, friction, dt, damped, tangential):
    """Force on i of one contact whose narrow phase is in ``row`` (Appendix).

    ``vrx, vry`` is the relative velocity at the force point (read only when
    ``damped`` or ``tangential``); without ``damped`` the normal force is the
    elastic one, without ``tangential`` there is no tangential force and the
    spring is returned unchanged.

    Returns
    -------
    (float, float, float)
        Force on i (x, y) and the updated spring.
    """
    nx = row[7]
    ny = row[8]
    if damped:
        f_el, f_n = normal_force(row[0], row[9] * (vrx * nx + vry * ny), l,
                                 reduced_mass(inv_mi, inv_mj), youngs_modulus, damping)
    else:
        f_el = elastic_force(row[0], l, youngs_modulus)
        f_n = f_el
    fx = -f_n * nx
    fy = -f_n * ny
    if tangential:
        tx = -ny
        ty = nx
        t_force, spring = tangential_force(
            spring, vrx * tx + vry * ty, f_el,
            tangential_mass(inv_mi, inv_mj, ri, rj, inv_ii, inv_ij), youngs_modulus,
            friction, dt)
        fx -= t_force * tx
        fy -= t_force * ty
    return fx, fy, spring


def pair_forces(pi, pj, spring, pout, r, dt, node_offset, wx, wy, box, inv_mass,
                inv_inertia, area, youngs_modulus, damping, friction, eps, scratch,
                damped, tangential):
    """Narrow phase and contact law for every candidate pair.

    Writes row p of ``pout`` and, when ``tangential``, updates ``spring[p]``
    (reset to zero when the pair does not overlap, so a new contact starts
    with an unloaded spring).
    """
    for p in prange(pi.shape[0]):
        i = pi[p]
        j = pj[p]
        row = pout[p]
        row[15] = 0.0
        if (box[i, 1] < box[j, 0] or box[j, 1] < box[i, 0] or
                box[i, 3] < box[j, 2] or box[j, 3] < box[i, 2]):
            if tangential:
                spring[p] = 0.0
            continue
        a0 = node_offset[i]
        a1 = node_offset[i + 1]
        b0 = node_offset[j]
        b1 = node_offset[j + 1]
        xi = r[0, 0, i]
        yi = r[0, 1, i]
        xj = r[0, 0, j]
        yj = r[0, 1, j]
        if _separated_along_centres(wx, wy, a0, a1, b0, b1, xi, yi, xj, yj) or \
                not polygon_overlap_range(wx, wy, a0, a1, wx, wy, b0, b1, xi, yi, xj, yj, eps,
                                     row, scratch[numba.get_thread_id()]):
            if tangential:
                spring[p] = 0.0
            continue
        sx = row[5]
        sy = row[6]
        rix = sx - xi
        riy = sy - yi
        rjx = sx - xj
        rjy = sy - yj
        ri = math.sqrt(rix * rix + riy * riy)
        rj = math.sqrt(rjx * rjx + rjy * rjy)
        l = max(characteristic_length(ri, rj), eps)
        vrx = 0.0
        vry = 0.0
        if damped or tangential:
            wi = r[1, 2, i] / dt
            wj = r[1, 2, j] / dt
            vrx = (r[1, 0, i] / dt - wi * riy) - (r[1, 0, j] / dt - wj * rjy)
            vry = (r[1, 1, i] / dt + wi * rix) - (r[1, 1, j] / dt + wj * rjx)
        fx, fy, s = _contact_force(row, spring[p] if tangential else 0.0, vrx, vry, l,
                                   inv_mass[i], inv_mass[j], ri, rj, inv_inertia[i],
                                   inv_inertia[j], youngs_modulus, damping, friction, dt,
                                   damped, tangential)
        if tangential:
            spring[p] = s
        row[10] = fx
        row[11] = fy
        row[12] = rix * fy - riy * fx
        row[13] = -(rjx * fy - rjy * fx)
        row[14] = row[0] / min(area[i], area[j])
        row[15] = 1.0


def gather_and_correct(r, n, coeffs, dt, pi, pout, pair_offset, pair_index, body_p,
                       body_m, body_friction, bspring, bout, node_offset, wx, wy, box,
                       mass, inv_mass, inv_inertia, area, gravity_x, gravity_y,
                       youngs_modulus, damping, rotate, drag, eps, scratch, damped,
                       body_tangential):
    """Total force and torque on each particle, then the corrector (Eq. 1).

    ``drag`` (1/s) adds the background damping ``−drag·m·v`` and ``−drag·I·ω``
    used only while relaxing (see :mod:`sim.protocols`); it is 0 otherwise.
    Bodies are half-planes ``{q : (q − p)·m < 0}`` (point ``body_p[b]``, unit
    outward normal ``body_m[b]``) of infinite mass, e.g. the support ``y < 0``.
    With ``rotate`` false the angular degree of freedom is not integrated;
    ``damped`` and ``body_tangential`` are the flags of :func:`_contact_force`
    for the contacts with bodies.
    """
    nv = r.shape[0]
    half_dt2 = 0.5 * dt * dt
    for i in prange(n):
        fx = mass[i] * gravity_x
        fy = mass[i] * gravity_y
        tq = 0.0
        for q in range(pair_offset[i], pair_offset[i + 1]):
            p = pair_index[q]
            if pout[p, 15] == 0.0:
                continue
            if pi[p] == i:
                fx += pout[p, 10]
                fy += pout[p, 11]
                tq += pout[p, 12]
            else:
                fx -= pout[p, 10]
                fy -= pout[p, 11]
                tq += pout[p, 13]
        a0 = node_offset[i]
        a1 = node_offset[i + 1]
        xi = r[0, 0, i]
        yi = r[0, 1, i]
        vxi = r[1, 0, i] / dt
        vyi = r[1, 1, i] / dt
        wi = r[1, 2, i] / dt
        for b in range(body_p.shape[0]):
            row = bout[b, i]
            row[15] = 0.0
            # the box corner deepest into the body decides whether to clip at all
            deep = ((box[i, 0] if body_m[b, 0] > 0.0 else box[i, 1]) - body_p[b, 0]) * \
                body_m[b, 0] + ((box[i, 2] if body_m[b, 1] > 0.0 else box[i, 3]) -
                                body_p[b, 1]) * body_m[b, 1]
            if deep >= 0.0 or not halfplane_overlap_range(
                    wx, wy, a0, a1, body_p[b, 0], body_p[b, 1], body_m[b, 0], body_m[b, 1],
                    eps, row, scratch[numba.get_thread_id()]):
                if body_tangential:
                    bspring[b, i] = 0.0
                continue
            rix = row[5] - xi
            riy = row[6] - yi
            ri = math.sqrt(rix * rix + riy * riy)
            l = max(characteristic_length(ri, np.inf), eps)
            bfx, bfy, s = _contact_force(
                row, bspring[b, i] if body_tangential else 0.0, vxi - wi * riy, vyi + wi * rix,
                l, inv_mass[i], 0.0, ri, 0.0, inv_inertia[i], 0.0, youngs_modulus, damping,
                body_friction[b], dt, damped, body_tangential)
            if body_tangential:
                bspring[b, i] = s
            row[10] = bfx
            row[11] = bfy
            row[12] = rix * bfy - riy * bfx
            row[13] = 0.0
            row[14] = row[0] / area[i]
            row[15] = 1.0
            fx += bfx
            fy += bfy
            tq += row[12]
        acc0 = fx * inv_mass[i] - drag * vxi
        acc1 = fy * inv_mass[i] - drag * vyi
        acc2 = tq * inv_inertia[i] - drag * wi
        for d in range(3 if rotate else 2):
            a = acc0 if d == 0 else (acc1 if d == 1 else acc2)
            delta = half_dt2 * a - r[2, d, i]
            for k in range(nv):
                r[k, d, i] += coeffs[k] * delta


# kernels are passed to advance() as first-class functions
warnings.filterwarnings("ignore", category=numba.NumbaExperimentalFeatureWarning)

# each kernel in a parallel and a serial build: below a few hundred particles
# the cost of starting a parallel region exceeds the work
KERNELS_PARALLEL = tuple(njit(cache=True, parallel=True)(f) for f in
                         (predict_and_place, pair_forces, gather_and_correct))
KERNELS_SERIAL = tuple(njit(cache=True)(f) for f in
                       (predict_and_place, pair_forces, gather_and_correct))


# Not cached: its signature holds the types of the kernel dispatchers passed in,
# which differ in every new process, so each process missed the cache, compiled
# anyway and appended an entry to the cache index; after a few dozen processes
# loading the index failed ("underlying object has vanished").  Compiling this
# small loop costs well under a second; the kernels themselves stay cached.
@njit(cache=False)
def advance(kernels, n_steps, n, r, coeffs, dt, node_offset, node_x, node_y, wx, wy, box,
            pi, pj, spring, pout, pair_offset, pair_index, body_p, body_m,
            body_friction, bspring, bout, mass, inv_mass, inv_inertia, area,
            gravity_x, gravity_y, youngs_modulus, damping, friction, rotate, drag, eps,
            x_ref, y_ref, rebuild_sq, scratch, cs, damped, tangential, body_tangential):
    """Run up to ``n_steps`` steps; stop early when the pair list needs a rebuild.

    ``kernels`` is :data:`KERNELS_PARALLEL` or :data:`KERNELS_SERIAL`; ``rotate``,
    ``cs``, ``damped``, ``tangential`` (pairs) and ``body_tangential`` select the
    work done (module docstring).

    Returns
    -------
    int
        Steps done.  Fewer than ``n_steps`` means some particle moved more than
        ``sqrt(rebuild_sq)`` since the last pair-list build.
    """
    predict, pairs, gather = kernels
    for s in range(n_steps):
        predict(r, n, node_offset, node_x, node_y, wx, wy, box, rotate, cs)
        pairs(pi, pj, spring, pout, r, dt, node_offset, wx, wy, box, inv_mass,
              inv_inertia, area, youngs_modulus, damping, friction, eps, scratch, damped,
              tangential)
        gather(r, n, coeffs, dt, pi, pout, pair_offset, pair_index, body_p,
               body_m, body_friction, bspring, bout, node_offset, wx, wy, box,
               mass, inv_mass, inv_inertia, area, gravity_x, gravity_y,
               youngs_modulus, damping, rotate, drag, eps, scratch, damped,
               body_tangential)
        m = 0.0
        for i in range(n):
            dx = r[0, 0, i] - x_ref[i]
            dy = r[0, 1, i] - y_ref[i]
            m = max(m, dx * dx + dy * dy)
        if m > rebuild_sq:
            return s + 1
    return n_steps
