"""Warm-started narrow phase: what a pair's geometry was last step, tried first.

In a pile a contact lives for thousands of steps and a neighbour that does not
touch stays apart for as long, so each candidate pair keeps a *witness* of its
last narrow phase and tests it before doing the general work of
:func:`sim.geometry.polygon_overlap_range` (clipping, 200–300 ns a pair):

* a **separating edge** for a pair that did not overlap: while every corner of
  one polygon lies strictly outside that edge's line of the other polygon, the
  convex polygons do not overlap (:func:`axis_separates`);
* the **crossing edges** of a pair that overlapped: the edge of ``a`` and the
  edge of ``b`` that cross where ``a``'s boundary enters ``b`` (the contact
  point ``c1`` or ``c2``), and the two that cross where it leaves.  From them
  :func:`overlap_from_crossings` builds the overlap polygon directly: the two
  crossing points, the corners of ``a`` between them (which must lie inside
  ``b``) and the corners of ``b`` between them (which must lie inside ``a``).

Both tests are exact, not heuristics.  The crossing test accepts only when the
closed curve made of ``a``'s boundary from the entry to the exit point and
``b``'s boundary from the exit back to the entry has every corner of its
``a`` part inside ``b`` and of its ``b`` part inside ``a``; such a curve lies
on the boundary of the convex set ``a ∩ b`` and is closed, so it *is* that
boundary, and the overlap, its area, the crossings ``c1, c2`` and the normal
follow as in the general kernel (same conventions, same ``eps`` rules, see
:mod:`sim.geometry`).  Anything else (a new contact, a crossing that moved
past a corner, more than two crossings, a contact line shorter than ``eps``)
is left to the general kernel, after which the witness is found anew.

The serial kernels that call these are compiled without Numba's reference
counting (:data:`sim.step.KERNELS_SERIAL`); with it, every array handed to an
inlined helper is counted at every call (an atomic increment and decrement
per array).  :func:`overlap_from_crossings` has a single exit with every value defined
on every path (a value defined on some paths only gave wrong results in the
parallel pass).

Edges are numbered from 0 within each polygon (edge k runs from corner k to
corner k + 1); a separating edge is stored as ``2 k`` (edge k of ``b``) or
``2 k + 1`` (edge k of ``a``), the crossings as ``(a_in, b_in, a_out,
b_out)``; -1 means no witness.
"""

from __future__ import annotations

import numpy as np

from .geometry import contact_geometry
from .kernel_cache import njit

#: Integer type of the witnesses (``axis``, ``cross``) kept per pair.  An edge
#: number is below 64 (at most 32 corners, ``particles.corners_max``), and the
#: pair pass streams these arrays at every step: one byte instead of eight
#: took 5 % off the pair pass on the bench heaps of 3000 and 10 000
#: particles (docs/performance.md).
WITNESS_DTYPE = np.int8


@njit(cache=True, inline="always")
def axis_separates(x, y, a0, a1, b0, b1, axis):
    """Whether the separating edge ``axis`` (module docstring) still separates ``a`` and ``b``.

    It does while every corner of the one polygon lies strictly outside the
    line of that edge of the other (then the two convex polygons do not
    overlap).  Uses the clipping's sign convention: a cross product ``>= 0``
    is inside the edge's closed half-plane.
    """
    if axis & 1:  # edge of a, corners of b
        e0, e1, v0, v1 = a0, a1, b0, b1
    else:
        e0, e1, v0, v1 = b0, b1, a0, a1
    k = e0 + (axis >> 1)
    # unsigned corner indices here and below: Numba then indexes without its
    # test for negative indices (three integer operations per access, in a
    # pair's every corner access; the pair pass took 12 % longer with them)
    e = np.uint64(k)
    f = np.uint64(k + 1 if k + 1 < e1 else e0)
    px = x[e]
    py = y[e]
    ex = x[f] - px
    ey = y[f] - py
    for q in range(np.uint64(v0), np.uint64(v1)):
        if ex * (y[q] - py) - ey * (x[q] - px) >= 0.0:
            return False
    return True


@njit(cache=True, inline="always")
def find_axis(x, y, a0, a1, b0, b1):
    """A separating edge of two polygons that do not overlap, or -1 (touching)."""
    for k in range(b1 - b0):
        if axis_separates(x, y, a0, a1, b0, b1, 2 * k):
            return 2 * k
    for k in range(a1 - a0):
        if axis_separates(x, y, a0, a1, b0, b1, 2 * k + 1):
            return 2 * k + 1
    return -1


@njit(cache=True, inline="always")
def _crossing(ax0, ay0, ax1, ay1, bx0, by0, bx1, by1, entering):
    """Where the edge ``a0 → a1`` crosses the edge ``b0 → b1``, with ``a``
    entering ``b`` or leaving it.

    Returns ``(found, t, un, den)``: ``found`` when the two edges (closed
    segments) cross with ``a``'s boundary running into ``b`` (``entering``)
    or out of it; the crossing is ``a0 + t (a1 − a0) = b0 + u (b1 − b0)``
    with ``u = un / (d_a × d_b)``, returned as the numerator ``un`` and
    ``den = |d_a × d_b|`` (u is rarely needed; no division).  The cross
    product ``d_a × d_b`` is negative where ``a`` enters ``b`` (CCW
    polygons), positive where it leaves.
    """
    dx = ax1 - ax0
    dy = ay1 - ay0
    ex = bx1 - bx0
    ey = by1 - by0
    wx = bx0 - ax0
    wy = by0 - ay0
    den = dx * ey - dy * ex
    tn = wx * ey - wy * ex
    un = wx * dy - wy * dx
    if entering:
        found = den < 0.0 and den <= tn <= 0.0 and den <= un <= 0.0
    else:
        found = den > 0.0 and 0.0 <= tn <= den and 0.0 <= un <= den
    if not found:
        return False, 0.0, 0.0, 1.0
    return True, tn / den, un, abs(den)


@njit(cache=True, inline="always")
def _edge_crossing(x, y, a0, a1, ka, b0, b1, kb, entering, ox, oy):
    """:func:`_crossing` of edge ka of ``a = [a0, a1)`` and edge kb of ``b = [b0, b1)``.

    Returns
    -------
    (bool, float, float, float, float, float)
        ``found, t, un, den`` as from :func:`_crossing`, then the crossing
        point relative to ``(ox, oy)`` (as in the general kernel; 0 when not
        found).
    """
    ia = a0 + ka
    jb = b0 + kb
    # unsigned (see axis_separates)
    i = np.uint64(ia)
    i1 = np.uint64(ia + 1 if ia + 1 < a1 else a0)
    j = np.uint64(jb)
    j1 = np.uint64(jb + 1 if jb + 1 < b1 else b0)
    found, t, un, den = _crossing(x[i], y[i], x[i1], y[i1], x[j], y[j], x[j1], y[j1],
                                  entering)
    if not found:
        return False, t, un, den, 0.0, 0.0
    return True, t, un, den, (x[i] - ox) + t * (x[i1] - x[i]), (y[i] - oy) + t * (y[i1] - y[i])


@njit(cache=True, inline="always")
def _arcs_area(x, y, a0, a1, b0, b1, ka_in, kb_in, ka_out, kb_out, ox, oy, x1, y1, tx, ty):
    """Test the corners between the crossings and sum the overlap's shoelace area.

    The corners of ``a`` from edge ``ka_in`` to ``ka_out`` must lie inside
    ``b``, those of ``b`` from edge ``kb_out`` to ``kb_in`` inside ``a``
    (module docstring).  ``(x1, y1)`` is the entry point relative to
    ``(ox, oy)``, ``(tx, ty)`` the exit point relative to the entry.

    Returns
    -------
    (bool, float)
        Whether every corner passed, and twice the overlap's area (partial
        when a corner failed).  One exit, like :func:`overlap_from_crossings`.
    """
    na = a1 - a0
    nb = b1 - b0
    ok = True
    # shoelace over X1, a's corners inside b, X2, b's corners inside a
    # (relative to X1): the two arcs in turn, each corner tested against
    # the other polygon
    a2 = 0.0
    qx = 0.0
    qy = 0.0
    for side in range(2):
        if side == 0:
            p0, n, k, k_to, q0, q1 = a0, na, ka_in, ka_out, b0, b1
        else:
            p0, n, k, k_to, q0, q1 = b0, nb, kb_out, kb_in, a0, a1
        while ok and k != k_to:
            k = k + 1 if k + 1 < n else 0
            vx = x[np.uint64(p0 + k)]
            vy = y[np.uint64(p0 + k)]
            ex = x[np.uint64(q1 - 1)]
            ey = y[np.uint64(q1 - 1)]
            for m in range(np.uint64(q0), np.uint64(q1)):
                if (x[m] - ex) * (vy - ey) - (y[m] - ey) * (vx - ex) < 0.0:
                    ok = False
                    break
                ex = x[m]
                ey = y[m]
            vx = (vx - ox) - x1
            vy = (vy - oy) - y1
            a2 += qx * vy - vx * qy
            qx = vx
            qy = vy
        if side == 0:
            a2 += qx * ty - tx * qy
            qx = tx
            qy = ty
    return ok, a2


@njit(cache=True, inline="always")
def overlap_from_crossings(x, y, a0, a1, b0, b1, cax, cay, cbx, cby, eps, out, cross, p):
    """Overlap geometry of ``a = [a0, a1)`` and ``b = [b0, b1)`` from the crossing
    edges ``cross[p]`` of the last step, if they still describe it.

    Parameters
    ----------
    x, y : numpy.ndarray
        World corners of both polygons (CCW, convex).
    a0, a1, b0, b1 : int
        Corner ranges.
    cax, cay, cbx, cby : float
        Centres of mass (orient the normal).
    eps : float
        Length tolerance (:mod:`sim.geometry`).
    out : numpy.ndarray, shape (>= 10,)
        Receives the contact geometry, as from
        :func:`sim.geometry.polygon_overlap_range`.
    cross : numpy.ndarray of int64, shape (n_pairs, 4)
        Crossing edges per pair (module docstring).
    p : int
        Row of ``cross``.

    Returns
    -------
    bool
        True when ``out`` holds the overlap; False when the witness does not
        apply, or when the normal's orientation needs the general kernel's
        tie-break (``|n · (cb − ca)| <= eps``).  ``out`` is then untouched.
    """
    # one exit (module docstring)
    ka_in = cross[p, 0]
    kb_in = cross[p, 1]
    ka_out = cross[p, 2]
    kb_out = cross[p, 3]
    na = a1 - a0
    nb = b1 - b0
    ok = 0 <= ka_in < na and ka_out < na and kb_in < nb and kb_out < nb
    # every value defined on every path (the parallel pass needs it)
    t1 = un1 = t2 = un2 = x1 = y1 = x2 = y2 = tx = ty = a2 = d2 = nx = ny = 0.0
    den1 = den2 = 1.0
    ox = x[np.uint64(a0)]
    oy = y[np.uint64(a0)]
    if ok:
        ok, t1, un1, den1, x1, y1 = _edge_crossing(x, y, a0, a1, ka_in, b0, b1, kb_in, True,
                                                   ox, oy)
    if ok:
        ok, t2, un2, den2, x2, y2 = _edge_crossing(x, y, a0, a1, ka_out, b0, b1, kb_out,
                                                   False, ox, oy)
    # within one edge the entry must come before the exit (else the arc wraps
    # around); along b's edge the exit comes first: u2 < u1, u = un / den
    if ok and ((ka_in == ka_out and not t1 < t2) or
               (kb_in == kb_out and not un2 / den2 < -un1 / den1)):
        ok = False
    if ok:
        tx = x2 - x1
        ty = y2 - y1
        ok, a2 = _arcs_area(x, y, a0, a1, b0, b1, ka_in, kb_in, ka_out, kb_out, ox, oy,
                            x1, y1, tx, ty)
        d2 = tx * tx + ty * ty
        ok = ok and 0.5 * a2 > eps * eps and d2 > eps * eps
    if ok:
        ln = np.sqrt(d2)
        inv_ln = 1.0 / ln
        nx = ty * inv_ln
        ny = -tx * inv_ln
        # orient along cb − ca; the near-perpendicular case takes the general tie-break
        dot = nx * (cbx - cax) + ny * (cby - cay)
        if dot < -eps:
            nx = -nx
            ny = -ny
        elif not dot > eps:
            ok = False
    if ok:
        (out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8],
         out[9]) = contact_geometry(0.5 * a2, x1, y1, x2, y2, nx, ny, ox, oy)
    return ok


@njit(cache=True, inline="always")
def _edge_through(x, y, p0, p1, px, py):
    """The edge of polygon ``[p0, p1)`` nearest to the world point ``(px, py)``."""
    best = np.inf
    kbest = 0
    for k in range(p0, p1):
        k1 = k + 1 if k + 1 < p1 else p0
        ex = x[k1] - x[k]
        ey = y[k1] - y[k]
        wx = px - x[k]
        wy = py - y[k]
        le2 = ex * ex + ey * ey
        t = min(max((wx * ex + wy * ey) / le2, 0.0), 1.0) if le2 > 0.0 else 0.0
        dx = wx - t * ex
        dy = wy - t * ey
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
            kbest = k - p0
    return kbest


@njit(cache=True, inline="always")
def find_crossings(x, y, a0, a1, b0, b1, out, cross, p):
    """Store in ``cross[p]`` the crossing edges of the contact whose geometry is in ``out``.

    ``out`` holds the general kernel's result: the edges nearest to ``c1`` and
    ``c2`` are taken, ordered by where ``a`` enters and leaves ``b``.  A
    contact line shorter than ``eps`` (nested fall-back) stores no witness;
    a wrong guess only fails the next step's test.
    """
    cross[p, 0] = -1
    if not out[9] > 0.0:
        return
    ka1 = _edge_through(x, y, a0, a1, out[1], out[2])
    kb1 = _edge_through(x, y, b0, b1, out[1], out[2])
    ka2 = _edge_through(x, y, a0, a1, out[3], out[4])
    kb2 = _edge_through(x, y, b0, b1, out[3], out[4])
    if _edge_crossing(x, y, a0, a1, ka1, b0, b1, kb1, True, 0.0, 0.0)[0]:
        cross[p, 0] = ka1
        cross[p, 1] = kb1
        cross[p, 2] = ka2
        cross[p, 3] = kb2
    else:
        cross[p, 0] = ka2
        cross[p, 1] = kb2
        cross[p, 2] = ka1
        cross[p, 3] = kb1
