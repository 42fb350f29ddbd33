"""Warm-started narrow phase: what a pair's geometry was last step, tried first.

In a pile a contact lives for thousands of steps and a neighbour that does not
touch stays apart for as long, so each candidate pair keeps a *witness* of its
last narrow phase and tests it before doing the general work of
:func:`sim.geometry.polygon_overlap_range` (clipping, 200–300 ns a pair):

* a **separating edge** for a pair that did not overlap: while every corner of
  one polygon lies strictly outside that edge's line of the other polygon, the
  convex polygons do not overlap (:func:`edge_separates`);
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

Edges are numbered from 0 within each polygon (edge k runs from corner k to
corner k + 1); a separating edge is stored as ``2 k`` (edge k of ``b``) or
``2 k + 1`` (edge k of ``a``), the crossings as ``(a_in, b_in, a_out,
b_out)``; -1 means no witness.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .geometry import write_contact



@njit(cache=True, inline="always")
def edge_separates(x, y, e0, e1, k, v0, v1):
    """Whether edge k of the polygon ``[e0, e1)`` has every corner of ``[v0, v1)``
    strictly outside its line (then the two convex polygons do not overlap).

    Uses the clipping's sign convention: a cross product ``>= 0`` is inside the
    edge's closed half-plane.
    """
    a = e0 + k
    b = a + 1 if a + 1 < e1 else e0
    px = x[a]
    py = y[a]
    ex = x[b] - px
    ey = y[b] - py
    for q in range(v0, v1):
        if ex * (y[q] - py) - ey * (x[q] - px) >= 0.0:
            return False
    return True


@njit(cache=True, inline="always")
def axis_separates(x, y, a0, a1, b0, b1, axis):
    """Whether the separating edge ``axis`` (module docstring) still separates ``a`` and ``b``."""
    k = axis >> 1
    if axis & 1:
        return edge_separates(x, y, a0, a1, k, b0, b1)
    return edge_separates(x, y, b0, b1, k, a0, a1)


@njit(cache=True, inline="always")
def find_axis(x, y, a0, a1, b0, b1):
    """A separating edge of two polygons that do not overlap, or -1 (touching)."""
    for k in range(b1 - b0):
        if edge_separates(x, y, b0, b1, k, a0, a1):
            return 2 * k
    for k in range(a1 - a0):
        if edge_separates(x, y, a0, a1, k, b0, b1):
            return 2 * k + 1
    return -1


@njit(cache=True, inline="always")
def _crossing(x, y, a0, a1, ka, b0, b1, kb, entering):
    """Where edge ka of ``a`` crosses edge kb of ``b``, with ``a`` entering ``b`` or leaving it.

    Returns ``(found, t, un, den)``: ``found`` when the two edges (closed
    segments) cross with ``a``'s boundary running into ``b`` (``entering``)
    or out of it; the crossing is ``a_ka + t (a_ka+1 − a_ka) = b_kb + u
    (b_kb+1 − b_kb)`` with ``u = un / (d_a × d_b)``, returned as the numerator
    ``un`` and ``den = |d_a × d_b|`` (u is rarely needed; no division).  The
    cross product ``d_a × d_b`` is negative where ``a`` enters ``b`` (CCW
    polygons), positive where it leaves.
    """
    i = a0 + ka
    i1 = i + 1 if i + 1 < a1 else a0
    j = b0 + kb
    j1 = j + 1 if j + 1 < b1 else b0
    dx = x[i1] - x[i]
    dy = y[i1] - y[i]
    ex = x[j1] - x[j]
    ey = y[j1] - y[j]
    wx = x[j] - x[i]
    wy = y[j] - y[i]
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
def _inside(x, y, p0, p1, vx, vy):
    """Whether the world point ``v`` lies in the closed CCW polygon ``[p0, p1)``."""
    px = x[p1 - 1]
    py = y[p1 - 1]
    for k in range(p0, p1):
        qx = x[k]
        qy = y[k]
        if (qx - px) * (vy - py) - (qy - py) * (vx - px) < 0.0:
            return False
        px = qx
        py = qy
    return True


@njit(cache=True, inline="always")
def _arc(x, y, p0, n, k_from, k_to, q0, q1, ox, oy, x1, y1, a2, qx, qy):
    """Walk the corners ``k_from + 1 .. k_to`` of polygon ``p`` (``n`` corners from
    ``p0``), each of which must lie in polygon ``[q0, q1)``, adding their
    shoelace terms to ``a2`` (coordinates relative to the local point ``(x1,
    y1)`` of the frame at the world point ``o``; ``(qx, qy)`` the previous
    corner).

    Returns
    -------
    (bool, float, float, float)
        Whether every corner lies inside, the sum, the last corner.
    """
    k = k_from
    while k != k_to:
        k = k + 1 if k + 1 < n else 0
        vx = x[p0 + k]
        vy = y[p0 + k]
        if not _inside(x, y, q0, q1, vx, vy):
            return False, a2, qx, qy
        vx = (vx - ox) - x1
        vy = (vy - oy) - y1
        a2 += qx * vy - vx * qy
        qx = vx
        qy = vy
    return True, a2, qx, qy


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
    ka_in = cross[p, 0]
    if ka_in < 0:
        return False
    kb_in = cross[p, 1]
    ka_out = cross[p, 2]
    kb_out = cross[p, 3]
    na = a1 - a0
    nb = b1 - b0
    if ka_in >= na or ka_out >= na or kb_in >= nb or kb_out >= nb:
        return False
    found, t1, un1, den1 = _crossing(x, y, a0, a1, ka_in, b0, b1, kb_in, True)
    if not found:
        return False
    found, t2, un2, den2 = _crossing(x, y, a0, a1, ka_out, b0, b1, kb_out, False)
    if not found:
        return False
    # within one edge the entry must come before the exit (else the arc wraps
    # around); along b's edge the exit comes first: u2 < u1, u = un / den
    if (ka_in == ka_out and not t1 < t2) or \
            (kb_in == kb_out and not un2 / den2 < -un1 / den1):
        return False
    # crossing points relative to a's first corner, as in the general kernel
    ox = x[a0]
    oy = y[a0]
    i = a0 + ka_in
    i1 = i + 1 if i + 1 < a1 else a0
    x1 = (x[i] - ox) + t1 * (x[i1] - x[i])
    y1 = (y[i] - oy) + t1 * (y[i1] - y[i])
    i = a0 + ka_out
    i1 = i + 1 if i + 1 < a1 else a0
    x2 = (x[i] - ox) + t2 * (x[i1] - x[i])
    y2 = (y[i] - oy) + t2 * (y[i1] - y[i])
    # shoelace over X1, a's corners inside b, X2, b's corners inside a (relative to X1)
    ok, a2, qx, qy = _arc(x, y, a0, na, ka_in, ka_out, b0, b1, ox, oy, x1, y1, 0.0, 0.0,
                          0.0)
    if not ok:
        return False
    tx = x2 - x1
    ty = y2 - y1
    a2 += qx * ty - tx * qy
    ok, a2, qx, qy = _arc(x, y, b0, nb, kb_out, kb_in, a0, a1, ox, oy, x1, y1, a2, tx, ty)
    if not ok:
        return False
    d2 = tx * tx + ty * ty
    if not (0.5 * a2 > eps * eps and d2 > eps * eps):
        return False
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
        return False
    write_contact(out, 0.5 * a2, x1, y1, x2, y2, nx, ny, ox, oy)
    return True


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
    if _crossing(x, y, a0, a1, ka1, b0, b1, kb1, True)[0]:
        cross[p, 0] = ka1
        cross[p, 1] = kb1
        cross[p, 2] = ka2
        cross[p, 3] = kb2
    else:
        cross[p, 0] = ka2
        cross[p, 1] = kb2
        cross[p, 2] = ka1
        cross[p, 3] = kb1
