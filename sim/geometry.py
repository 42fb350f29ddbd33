"""Narrow-phase contact geometry of convex polygons (Numba kernels).

Implements the geometric part of the contact model of Roul, Schinner &
Kassner (2010), Appendix: for two overlapping convex polygons the overlap
area ``A`` (surveyor's / shoelace formula of the overlap polygon), the two
points ``c1``, ``c2`` where the two boundaries intersect, the force point
``s`` (midpoint of the contact line ``c1 c2``) and the contact normal
perpendicular to the contact line.

Output layout
-------------
Both :func:`polygon_overlap` and :func:`halfplane_overlap` fill a float64
array ``out`` of length ``>= OUT_SIZE`` (10):

====== =========================================================
index  meaning
====== =========================================================
0      overlap area ``A`` (> ``eps**2``)
1, 2   ``c1`` (x, y)
3, 4   ``c2`` (x, y)
5, 6   force point ``s = (c1 + c2) / 2``
7, 8   unit normal ``n``, pointing from body ``a`` into body ``b``
9      contact-line length ``|c2 - c1|`` (may be 0, see below)
====== =========================================================

The points are ordered so that ``c2 - c1 = out[9] * t`` with the tangent
``t = (-n_y, n_x)`` (``n`` turned counter-clockwise by 90 degrees).

When the functions return ``False`` (no overlap of positive area) ``out`` is
left untouched.

Tolerances
----------
Every kernel takes ``eps``, a *length* tolerance (e.g. ``1e-9`` times the
particle size).  It is used as follows:

* an overlap counts only if its area exceeds ``eps**2``;
* a contact line shorter than ``eps`` is not trusted for a direction;
* in the degenerate fall-backs a point is "on a boundary" when it is within
  ``eps`` of it;
* the orientation test ``n . (cb - ca)`` is "zero" when ``|.| <= eps``.

Nothing else depends on absolute numbers: all arithmetic is done in
coordinates relative to a corner of polygon ``a``, so polygons far from the
origin (e.g. at ``x = 1e3`` m) keep the relative accuracy they have near it.

Degenerate configurations
-------------------------
The overlap polygon is obtained by Sutherland-Hodgman clipping of ``a`` by
the edge lines of ``b`` (closed half-planes), tracking for every edge of the
clipped polygon whether it is a piece of ``a``'s or of ``b``'s boundary.
A vertex where the label changes is a boundary crossing.  A small overlap
of two convex polygons has exactly two (the paper's ``c1``, ``c2``); a deep
overlap can have four or more (e.g. two thin rectangles crossing), and
collinear edges, vertices on edges or round-off can add crossings that all
lie on both boundaries.  The pair farthest apart is taken as ``c1, c2``.  If fewer than two crossings at least
``eps`` apart exist (one polygon inside the other, possibly touching its
boundary from inside), the overlap-polygon vertices lying within ``eps`` of
both boundaries are used instead (farthest pair).  If there are still not
two such points at least ``eps`` apart, the *nested fall-back* is used:
``s`` = centroid of the overlap polygon, ``c1 = c2 = s``, contact-line length
``0`` and ``n`` along ``cb - ca`` (``(1, 0)`` if the centres coincide within
``eps``).  Callers must cope with ``out[9] == 0``.

The normal is oriented so that ``n . (cb - ca) > 0``.  If
``|n . (cb - ca)| <= eps`` it is oriented towards the side of the contact
line on which ``a``'s part of the overlap boundary lies (``a`` protrudes
into ``b`` there), i.e. away from ``b``'s part.

Corner ranges and use from Numba loops
--------------------------------------
:func:`polygon_overlap_range` and :func:`halfplane_overlap_range` take the
corners as index ranges ``[a0, a1)`` of (possibly shared) coordinate
arrays, e.g. the simulator's world-corner arrays with ``a0 =
node_offset[i]``, ``a1 = node_offset[i + 1]``.  They are declared
``inline="always"``: called from a Numba loop they are inlined, so no array
views are created and no reference counts are touched per pair.  This is
the fastest way to call the narrow phase; :func:`polygon_overlap` is a thin
wrapper around it.  They contain no ``raise`` statement of their own (errors
go through a non-inlined helper), so a surrounding ``prange`` loop stays
parallel; each thread needs its own ``scratch`` and ``out``.  (An error
raised inside a ``prange`` region surfaces as a ``SystemError`` chained to
the ``ValueError``, a Numba limitation.)  Numba's on-disk cache of a caller
is not invalidated when this module changes; clear it after editing here.

Scratch memory
--------------
The kernels need small work arrays.  Pass a preallocated
``scratch = make_scratch(max_corners)`` (float64, shape ``(7, cap)``, one per
thread) to avoid any heap allocation per call; when ``scratch`` is omitted a
work array is allocated on each call (slower).  The capacity must satisfy
``cap >= scratch_capacity(na, nb) = 3 * (na + nb) + 8``.
"""

from __future__ import annotations

import numpy as np

from .kernel_cache import njit
from .rotation import cos_sin

__all__ = [
    "OUT_SIZE",
    "SCRATCH_ROWS",
    "scratch_capacity",
    "make_scratch",
    "polygon_overlap",
    "polygon_overlap_range",
    "halfplane_overlap",
    "halfplane_overlap_range",
    "world_corners",
]

#: Required length of the ``out`` array.
OUT_SIZE = 10
#: Number of rows of a scratch array.
SCRATCH_ROWS = 7

# Scratch rows: 0-2 and 3-5 hold two labelled polygons (x, y, label) used as
# source and destination while clipping; row 6 holds signed distances.


@njit(cache=True)
def scratch_capacity(na, nb):
    """Scratch columns needed to clip an ``na``-gon by an ``nb``-gon.

    Parameters
    ----------
    na, nb : int
        Corner counts (``nb = 1`` for a half-plane).

    Returns
    -------
    int
        ``3 * (na + nb) + 8``.
    """
    return 3 * (na + nb) + 8


def make_scratch(max_corners=32):
    """Allocate a scratch array for polygons with up to ``max_corners`` corners.

    Parameters
    ----------
    max_corners : int, optional
        Largest corner count of either polygon, ``>= 3``.

    Returns
    -------
    numpy.ndarray of float64, shape (SCRATCH_ROWS, 6 * max_corners + 8)
        Reusable work array (one per thread; contents are overwritten).

    Raises
    ------
    ValueError
        If ``max_corners < 3``.
    """
    max_corners = int(max_corners)
    if max_corners < 3:
        raise ValueError(f"max_corners = {max_corners} is outside the allowed range [3, inf)")
    return np.empty((SCRATCH_ROWS, scratch_capacity(max_corners, max_corners)), dtype=np.float64)


# Error reporting.  The range kernels are inlined into the caller's loop;
# a ``raise`` statement inside them would give that loop a second exit and
# stop Numba from parallelising a surrounding ``prange``.  They therefore
# call this (not inlined) function, which raises.


@njit(cache=True)
def _fail(code):
    """Raise the ``ValueError`` identified by ``code``.

    Codes: 1 ``out`` too short, 2 fewer than 3 corners, 3 scratch too small,
    4 scratch capacity exceeded while clipping.
    """
    if code == 1:
        raise ValueError("overlap kernel: out must have length >= 10")
    if code == 2:
        raise ValueError("overlap kernel: polygons need at least 3 corners")
    if code == 3:
        raise ValueError("overlap kernel: scratch too small, need shape "
                         "(7, 3*(na+nb)+8), nb = 1 for a half-plane")
    raise ValueError("overlap kernel: scratch capacity exceeded while clipping")


# ---------------------------------------------------------------------------
# helpers on labelled polygons stored in scratch rows (no array views: views
# cost reference-count updates in the hot loop)
# ---------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _area_and_crossings(S, r, n, r_idx):
    """Shoelace area of the labelled polygon in rows ``r..r+2`` of ``S`` and its crossings.

    A vertex whose incoming and outgoing edges carry different labels is a
    boundary crossing.  Returns ``(area, m, k1, k2)``: ``m`` crossings, the
    first two at vertex indices ``k1``, ``k2``; all ``m`` indices are also
    written to row ``r_idx`` of ``S`` (as floats).  The area is accumulated
    relative to vertex 0 to limit cancellation.
    """
    x0 = S[r, 0]
    y0 = S[r + 1, 0]
    a2 = 0.0
    m = 0
    k1 = -1
    k2 = -1
    kp = n - 1
    px = S[r, kp] - x0
    py = S[r + 1, kp] - y0
    lp = S[r + 2, kp]
    for k in range(n):
        qx = S[r, k] - x0
        qy = S[r + 1, k] - y0
        a2 += px * qy - qx * py
        lk = S[r + 2, k]
        if lk != lp:
            if m == 0:
                k1 = k
            elif m == 1:
                k2 = k
            S[r_idx, m] = k
            m += 1
        px = qx
        py = qy
        lp = lk
    return 0.5 * a2, m, k1, k2


@njit(cache=True, inline="always")
def _centroid(S, r, n):
    """Centroid of the polygon in rows ``r, r+1`` of ``S`` (vertex mean if area is 0)."""
    x0 = S[r, 0]
    y0 = S[r + 1, 0]
    a2 = 0.0
    sx = 0.0
    sy = 0.0
    px = 0.0
    py = 0.0
    for k in range(1, n):
        qx = S[r, k] - x0
        qy = S[r + 1, k] - y0
        w = px * qy - qx * py
        a2 += w
        sx += (px + qx) * w
        sy += (py + qy) * w
        px = qx
        py = qy
    if a2 != 0.0:
        return x0 + sx / (3.0 * a2), y0 + sy / (3.0 * a2)
    mx = 0.0
    my = 0.0
    for k in range(n):
        mx += S[r, k]
        my += S[r + 1, k]
    return mx / n, my / n


@njit(cache=True, inline="always")
def _farthest_pair(S, r, r_idx, m):
    """The two of the ``m`` vertices listed in row ``r_idx`` farthest apart.

    Returns ``(i, j, d2)``: vertex indices and squared distance (``-1`` if
    ``m < 2``).
    """
    bi = -1
    bj = -1
    best = -1.0
    for p in range(m):
        i = int(S[r_idx, p])
        for q in range(p + 1, m):
            j = int(S[r_idx, q])
            dx = S[r, j] - S[r, i]
            dy = S[r + 1, j] - S[r + 1, i]
            d2 = dx * dx + dy * dy
            if d2 > best:
                best = d2
                bi = i
                bj = j
    return bi, bj, best


@njit(cache=True, inline="always")
def _min_edge_distance(vx, vy, px, py, p0, p1, ox, oy):
    """Smallest signed distance of local point ``v`` to the edge lines of a CCW polygon.

    The polygon is ``px[p0:p1], py[p0:p1]`` in world coordinates, ``(ox, oy)``
    the local origin.  Positive inside; for a point inside a convex polygon
    it is the distance to the boundary.
    """
    best = np.inf
    for i in range(p0, p1):
        i1 = i + 1 if i + 1 < p1 else p0
        x0 = px[i] - ox
        y0 = py[i] - oy
        ex = (px[i1] - ox) - x0
        ey = (py[i1] - oy) - y0
        le = np.sqrt(ex * ex + ey * ey)
        if le == 0.0:
            continue
        d = (ex * (vy - y0) - ey * (vx - x0)) / le
        if d < best:
            best = d
    return best


@njit(cache=True, inline="always")
def contact_geometry(area, c1x, c1y, c2x, c2y, nx, ny, ox, oy):
    """The contact geometry (the first 10 entries of an output row) from
    local-frame contact points and a unit normal.

    Orders ``c1, c2`` so that ``c2 - c1`` points along ``t = (-n_y, n_x)``.

    Returns
    -------
    tuple of 10 float
        area, c1 (x, y), c2 (x, y), force point s (x, y), n (x, y) and the
        contact-line length, in world coordinates (``o`` is the frame's origin).
    """
    if (c2x - c1x) * (-ny) + (c2y - c1y) * nx < 0.0:
        c1x, c2x = c2x, c1x
        c1y, c2y = c2y, c1y
    dx = c2x - c1x
    dy = c2y - c1y
    return (area, c1x + ox, c1y + oy, c2x + ox, c2y + oy, 0.5 * (c1x + c2x) + ox,
            0.5 * (c1y + c2y) + oy, nx, ny, np.sqrt(dx * dx + dy * dy))


@njit(cache=True, inline="always")
def write_contact(out, area, c1x, c1y, c2x, c2y, nx, ny, ox, oy):
    """Fill ``out[:10]`` with :func:`contact_geometry`."""
    (out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8],
     out[9]) = contact_geometry(area, c1x, c1y, c2x, c2y, nx, ny, ox, oy)


# ---------------------------------------------------------------------------
# polygon - polygon
# ---------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _clip_step(S, src, dst, n):
    """Cut the labelled polygon in rows ``src..src+2`` of ``S`` at one edge line of ``b``.

    Row 6 of ``S`` holds the vertices' signed distances to the line (``>= 0``
    inside).  The part inside is written to rows ``dst..dst+2``; a vertex
    where the boundary leaves the half-plane starts an edge along ``b``'s
    line (label 1.0).

    Returns
    -------
    tuple of (int, float, float, float, float)
        ``m``, the number of vertices written, and their bounding box
        ``x0, x1, y0, y1``.
    """
    m = 0
    kp = n - 1
    dp = S[6, kp]
    x0 = np.inf
    x1 = -np.inf
    y0 = np.inf
    y1 = -np.inf
    for k in range(n):
        dq = S[6, k]
        if dq >= 0.0:
            if dp < 0.0:  # entering: crossing on the edge kp -> k
                t = dp / (dp - dq)
                u = S[src, kp] + t * (S[src, k] - S[src, kp])
                v = S[src + 1, kp] + t * (S[src + 1, k] - S[src + 1, kp])
                S[dst, m] = u
                S[dst + 1, m] = v
                S[dst + 2, m] = S[src + 2, kp]
                x0 = min(x0, u)
                x1 = max(x1, u)
                y0 = min(y0, v)
                y1 = max(y1, v)
                m += 1
            u = S[src, k]
            v = S[src + 1, k]
            S[dst, m] = u
            S[dst + 1, m] = v
            S[dst + 2, m] = S[src + 2, k]
            x0 = min(x0, u)
            x1 = max(x1, u)
            y0 = min(y0, v)
            y1 = max(y1, v)
            m += 1
        elif dp >= 0.0:  # leaving: continue along b's edge line
            t = dp / (dp - dq)
            u = S[src, kp] + t * (S[src, k] - S[src, kp])
            v = S[src + 1, kp] + t * (S[src + 1, k] - S[src + 1, kp])
            S[dst, m] = u
            S[dst + 1, m] = v
            S[dst + 2, m] = 1.0
            x0 = min(x0, u)
            x1 = max(x1, u)
            y0 = min(y0, v)
            y1 = max(y1, v)
            m += 1
        kp = k
        dp = dq
    return m, x0, x1, y0, y1


@njit(cache=True, inline="always")
def _clip(ax, ay, a0, a1, bx, by, b0, b1, ox, oy, gx, gy, S):
    """Clip polygon ``a`` by the closed half-planes of ``b``'s edges.

    Works in local coordinates (world minus ``(ox, oy)``).  Returns
    ``(n, r)``: the clipped polygon has ``n`` vertices stored in rows
    ``r, r+1, r+2`` (x, y, label) of ``S`` (``r`` is 0 or 3).  The label of
    vertex ``k`` names the boundary carrying the edge from vertex ``k`` to
    ``k+1``: 0.0 for ``a``, 1.0 for ``b``.

    Clipping starts with ``b``'s edge whose outward normal points most along
    ``g`` (``g = ca - cb``, towards ``a``): for a small overlap that edge cuts
    ``a`` down to the overlap region at once, after which the remaining edge
    lines are rejected by a bounding-box test.  The box test only skips an
    edge when every vertex would have been classified inside anyway (the
    rounded signed distance is monotone in each coordinate), so it does not
    change the result.
    """
    na = a1 - a0
    nb = b1 - b0
    cap = S.shape[1]
    x0 = np.inf
    x1 = -np.inf
    y0 = np.inf
    y1 = -np.inf
    for k in range(na):
        u = ax[a0 + k] - ox
        v = ay[a0 + k] - oy
        S[0, k] = u
        S[1, k] = v
        S[2, k] = 0.0
        x0 = min(x0, u)
        x1 = max(x1, u)
        y0 = min(y0, v)
        y1 = max(y1, v)
    n = na
    src = 0
    # b's edge facing a: outward normal (e_y, -e_x) most along g
    best = -np.inf
    j0 = b0
    for j in range(b0, b1):
        j1 = j + 1 if j + 1 < b1 else b0
        v = (by[j1] - by[j]) * gx - (bx[j1] - bx[j]) * gy
        if v > best:
            best = v
            j0 = j
    bx0 = bx[j0] - ox
    by0 = by[j0] - oy
    qx = bx0
    qy = by0
    j = j0
    for jj in range(nb):
        px = qx
        py = qy
        j += 1
        if j == b1:
            j = b0
        if jj + 1 < nb:
            qx = bx[j] - ox
            qy = by[j] - oy
        else:
            qx = bx0
            qy = by0
        ex = qx - px
        ey = qy - py
        # most outside corner of the current bounding box
        cy = y0 if ex > 0.0 else y1
        cx = x1 if ey > 0.0 else x0
        if ex * (cy - py) - ey * (cx - px) >= 0.0:
            continue
        # signed distances (times |e|); >= 0 is inside b's closed half-plane
        n_in = 0
        for k in range(n):
            d = ex * (S[src + 1, k] - py) - ey * (S[src, k] - px)
            S[6, k] = d
            n_in += d >= 0.0
        if n_in == n:
            continue
        if n_in == 0:
            return 0, src
        if 2 * n > cap:
            _fail(4)
            return 0, src
        dst = 3 - src
        n, x0, x1, y0, y1 = _clip_step(S, src, dst, n)
        src = dst
        if n < 3:
            return 0, src
    return n, src


@njit(cache=True, inline="always")
def orient_normal(nx, ny, gx, gy, S, r, n, smx, smy, eps):
    """Sign of the contact normal: along ``g = cb - ca``, else by boundary chains.

    Returns ``(nx, ny)`` possibly flipped.  Rows ``r..r+2`` of ``S`` hold the
    labelled overlap polygon and ``(smx, smy)`` is the midpoint of the contact
    line (local coordinates).
    """
    dot = nx * gx + ny * gy
    if dot > eps:
        return nx, ny
    if dot < -eps:
        return -nx, -ny
    # a's chain (vertices whose incoming and outgoing edges both belong to a)
    # lies on b's side of the contact line, b's chain on a's side.
    sig = 0.0
    kp = n - 1
    for k in range(n):
        proj = (S[r, k] - smx) * nx + (S[r + 1, k] - smy) * ny
        if S[r + 2, kp] == 0.0 and S[r + 2, k] == 0.0:
            sig += proj
        elif S[r + 2, kp] == 1.0 and S[r + 2, k] == 1.0:
            sig -= proj
        kp = k
    if sig < 0.0:
        return -nx, -ny
    if sig > 0.0:
        return nx, ny
    if dot < 0.0:
        return -nx, -ny
    return nx, ny


@njit(cache=True, inline="always")
def _near_both(ax, ay, a0, a1, bx, by, b0, b1, ox, oy, eps, S, r, n, r_idx):
    """List the vertices of the overlap polygon within ``eps`` of both boundaries.

    The overlap has ``n`` vertices in rows ``r, r+1`` of ``S`` (local
    coordinates, origin ``(ox, oy)``); ``a`` and ``b`` are as for
    :func:`polygon_overlap_range`.  The indices of the vertices found are
    written to row ``r_idx`` of ``S`` (as floats); returns their number.
    """
    m = 0
    for k in range(n):
        vx = S[r, k]
        vy = S[r + 1, k]
        if (_min_edge_distance(vx, vy, ax, ay, a0, a1, ox, oy) <= eps
                and _min_edge_distance(vx, vy, bx, by, b0, b1, ox, oy) <= eps):
            S[r_idx, m] = k
            m += 1
    return m


@njit(cache=True, inline="always")
def polygon_overlap_range(ax, ay, a0, a1, bx, by, b0, b1, cax, cay, cbx, cby, eps, out,
                          scratch):
    """Overlap geometry of the convex polygons ``a = ax[a0:a1]`` and ``b = bx[b0:b1]``.

    Same as :func:`polygon_overlap` but the corners are given as index
    ranges into coordinate arrays (which may be the same arrays for ``a`` and
    ``b``), and ``scratch`` is required.  This is the variant to call from a
    Numba loop over contact pairs.

    Parameters
    ----------
    ax, ay : numpy.ndarray of float64
        World corner coordinates containing polygon ``a`` at ``[a0, a1)``.
    a0, a1 : int
        Corner range of ``a``, ``a1 - a0 >= 3``.
    bx, by : numpy.ndarray of float64
        World corner coordinates containing polygon ``b`` at ``[b0, b1)``.
    b0, b1 : int
        Corner range of ``b``, ``b1 - b0 >= 3``.
    cax, cay, cbx, cby : float
        Centres of mass of ``a`` and ``b``.
    eps : float
        Length tolerance (see module docstring).
    out : numpy.ndarray of float64, shape (>= 10,)
        Receives the contact geometry; untouched on ``False``.
    scratch : numpy.ndarray of float64, shape (7, cap)
        Work array, ``cap >= 3 * (na + nb) + 8`` (see :func:`make_scratch`).

    Returns
    -------
    bool
        ``True`` if the overlap area exceeds ``eps**2``.

    Raises
    ------
    ValueError
        If ``out`` or ``scratch`` is too small or a polygon has < 3 corners.
    """
    na = a1 - a0
    nb = b1 - b0
    if out.shape[0] < 10:
        _fail(1)
        return False
    if na < 3 or nb < 3:
        _fail(2)
        return False
    if scratch.shape[0] < 7 or scratch.shape[1] < 3 * (na + nb) + 8:
        _fail(3)
        return False
    ox = ax[a0]
    oy = ay[a0]
    n, r = _clip(ax, ay, a0, a1, bx, by, b0, b1, ox, oy, cax - cbx, cay - cby, scratch)
    if n < 3:
        return False
    r_idx = 3 - r  # free row for indices of crossings / candidates
    area, m, i, j = _area_and_crossings(scratch, r, n, r_idx)
    if not (area > eps * eps):
        return False
    d2 = -1.0
    if m == 2:
        dx = scratch[r, j] - scratch[r, i]
        dy = scratch[r + 1, j] - scratch[r + 1, i]
        d2 = dx * dx + dy * dy
    elif m > 2:
        i, j, d2 = _farthest_pair(scratch, r, r_idx, m)
    if not (d2 > eps * eps):
        # fall-back: overlap vertices within eps of both boundaries
        m = _near_both(ax, ay, a0, a1, bx, by, b0, b1, ox, oy, eps, scratch, r, n, r_idx)
        i, j, d2 = _farthest_pair(scratch, r, r_idx, m)
    gx = cbx - cax
    gy = cby - cay
    if d2 > eps * eps:
        c1x = scratch[r, i]
        c1y = scratch[r + 1, i]
        c2x = scratch[r, j]
        c2y = scratch[r + 1, j]
        tx = c2x - c1x
        ty = c2y - c1y
        ln = np.sqrt(tx * tx + ty * ty)
        nx = ty / ln
        ny = -tx / ln
        nx, ny = orient_normal(nx, ny, gx, gy, scratch, r, n, 0.5 * (c1x + c2x),
                                0.5 * (c1y + c2y), eps)
        write_contact(out, area, c1x, c1y, c2x, c2y, nx, ny, ox, oy)
        return True
    # nested fall-back
    sx, sy = _centroid(scratch, r, n)
    lg = np.sqrt(gx * gx + gy * gy)
    if lg > eps:
        nx = gx / lg
        ny = gy / lg
    else:
        nx = 1.0
        ny = 0.0
    write_contact(out, area, sx, sy, sx, sy, nx, ny, ox, oy)
    return True


@njit(cache=True)
def polygon_overlap(ax, ay, bx, by, cax, cay, cbx, cby, eps, out, scratch=None):
    """Overlap area and contact geometry of two convex polygons.

    Parameters
    ----------
    ax, ay : numpy.ndarray of float64, shape (na,)
        World corners of polygon ``a``, counter-clockwise, convex, ``na >= 3``.
    bx, by : numpy.ndarray of float64, shape (nb,)
        World corners of polygon ``b``, likewise.
    cax, cay, cbx, cby : float
        Centres of mass of ``a`` and ``b`` (orient the normal).
    eps : float
        Length tolerance, e.g. ``1e-9 * particle size`` (see module docstring).
    out : numpy.ndarray of float64, shape (>= 10,)
        Receives the contact geometry (layout in the module docstring:
        area, c1, c2, s, n, contact-line length).  Untouched on ``False``.
    scratch : numpy.ndarray of float64, shape (7, cap), optional
        Work array from :func:`make_scratch` with
        ``cap >= 3 * (na + nb) + 8``; allocated per call if omitted.

    Returns
    -------
    bool
        ``True`` if the overlap area exceeds ``eps**2``.

    Raises
    ------
    ValueError
        If ``out`` or ``scratch`` is too small, a polygon has < 3 corners or
        its x and y arrays differ in length.
    """
    na = ax.shape[0]
    nb = bx.shape[0]
    if ay.shape[0] != na or by.shape[0] != nb:
        raise ValueError("polygon_overlap: x and y corner arrays differ in length")
    if scratch is None:
        buf = np.empty((7, 3 * (na + nb) + 8))
        return polygon_overlap_range(ax, ay, 0, na, bx, by, 0, nb, cax, cay, cbx, cby, eps,
                                     out, buf)
    return polygon_overlap_range(ax, ay, 0, na, bx, by, 0, nb, cax, cay, cbx, cby, eps, out,
                                 scratch)


# ---------------------------------------------------------------------------
# polygon - half-plane
# ---------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _cut_at_line(ax, ay, a0, na, ox, oy, S):
    """Write the part of the polygon ``ax[a0:a0+na]`` inside the half-plane body to ``S``.

    Row 6 of ``S`` holds the corners' depths below the line (``>= 0``
    inside).  The part inside goes to rows 0, 1, 2 (x, y, label) in local
    coordinates (origin ``(ox, oy)``); label 0.0 for an edge of the
    polygon, 1.0 for the edge along the line.  Returns the number of its
    vertices.
    """
    m = 0
    kp = na - 1
    dp = S[6, kp]
    for k in range(na):
        dq = S[6, k]
        qx = ax[a0 + k] - ox
        qy = ay[a0 + k] - oy
        if dq >= 0.0:
            if dp < 0.0:
                t = dp / (dp - dq)
                rx = ax[a0 + kp] - ox
                ry = ay[a0 + kp] - oy
                S[0, m] = rx + t * (qx - rx)
                S[1, m] = ry + t * (qy - ry)
                S[2, m] = 0.0
                m += 1
            S[0, m] = qx
            S[1, m] = qy
            S[2, m] = 0.0
            m += 1
        elif dp >= 0.0:
            t = dp / (dp - dq)
            rx = ax[a0 + kp] - ox
            ry = ay[a0 + kp] - oy
            S[0, m] = rx + t * (qx - rx)
            S[1, m] = ry + t * (qy - ry)
            S[2, m] = 1.0
            m += 1
        kp = k
        dp = dq
    return m


@njit(cache=True, inline="always")
def halfplane_overlap_range(ax, ay, a0, a1, px, py, mx, my, eps, out, scratch):
    """Overlap of the convex polygon ``ax[a0:a1]`` with a solid half-plane body.

    Same as :func:`halfplane_overlap` but with the corners given as an index
    range and ``scratch`` required.

    Parameters
    ----------
    ax, ay : numpy.ndarray of float64
        World corner coordinates containing the polygon at ``[a0, a1)``.
    a0, a1 : int
        Corner range, ``a1 - a0 >= 3``.
    px, py, mx, my, eps, out
        As for :func:`halfplane_overlap`.
    scratch : numpy.ndarray of float64, shape (7, cap)
        Work array, ``cap >= 3 * (na + 1) + 8``.

    Returns
    -------
    bool
        ``True`` if the overlap area exceeds ``eps**2``.

    Raises
    ------
    ValueError
        If ``out`` or ``scratch`` is too small or the polygon has < 3 corners.
    """
    na = a1 - a0
    if out.shape[0] < 10:
        _fail(1)
        return False
    if na < 3:
        _fail(2)
        return False
    if scratch.shape[0] < 7 or scratch.shape[1] < 3 * (na + 1) + 8:
        _fail(3)
        return False
    S = scratch
    ox = ax[a0]
    oy = ay[a0]
    # depth below the line (>= 0 inside the body); the line is located once,
    # relative to corner a0, so all corners see exactly the same line
    d0 = -((ox - px) * mx + (oy - py) * my)
    n_in = 0
    for k in range(na):
        d = d0 - ((ax[a0 + k] - ox) * mx + (ay[a0 + k] - oy) * my)
        S[6, k] = d
        n_in += d >= 0.0
    if n_in == 0:
        return False
    n = _cut_at_line(ax, ay, a0, na, ox, oy, S)
    if n < 3:
        return False
    area, m, i, j = _area_and_crossings(S, 0, n, 3)
    if not (area > eps * eps):
        return False
    nx = -mx
    ny = -my
    d2 = -1.0
    if m == 2:
        dx = S[0, j] - S[0, i]
        dy = S[1, j] - S[1, i]
        d2 = dx * dx + dy * dy
    elif m > 2:
        i, j, d2 = _farthest_pair(S, 0, 3, m)
    if not (d2 > eps * eps):
        # polygon inside the body: corners within eps of the line
        m = 0
        for k in range(n):
            if d0 - (S[0, k] * mx + S[1, k] * my) <= eps:
                S[3, m] = k
                m += 1
        i, j, d2 = _farthest_pair(S, 0, 3, m)
    if d2 > eps * eps:
        write_contact(out, area, S[0, i], S[1, i], S[0, j], S[1, j], nx, ny, ox, oy)
        return True
    sx, sy = _centroid(S, 0, n)
    write_contact(out, area, sx, sy, sx, sy, nx, ny, ox, oy)
    return True


@njit(cache=True)
def halfplane_overlap(ax, ay, px, py, mx, my, eps, out, scratch=None):
    """Overlap of a convex polygon with a solid half-plane body (support, wall).

    The body is ``{q : (q - p) . m < 0}``: ``p`` is a point of its boundary
    line and ``m`` its unit *outward* normal.  The contact normal is
    ``n = -m`` (from the polygon into the body); ``c1``, ``c2`` are where the
    polygon boundary crosses the line.  If the polygon lies entirely in the
    body, ``c1, c2`` are its farthest-apart corners within ``eps`` of the line
    or, failing that, the nested fall-back of :func:`polygon_overlap` applies
    (``s`` = overlap centroid, length 0).

    Parameters
    ----------
    ax, ay : numpy.ndarray of float64, shape (na,)
        World corners of the polygon, counter-clockwise, convex.
    px, py : float
        A point on the boundary line of the body.
    mx, my : float
        Unit outward normal of the body (e.g. ``(0, 1)`` for the support
        ``y < 0``).
    eps : float
        Length tolerance (see module docstring).
    out : numpy.ndarray of float64, shape (>= 10,)
        Same layout as for :func:`polygon_overlap`; untouched on ``False``.
    scratch : numpy.ndarray of float64, shape (7, cap), optional
        Work array with ``cap >= 3 * (na + 1) + 8``; allocated if omitted.

    Returns
    -------
    bool
        ``True`` if the overlap area exceeds ``eps**2``.

    Raises
    ------
    ValueError
        As :func:`polygon_overlap`, for the one polygon.
    """
    na = ax.shape[0]
    if ay.shape[0] != na:
        raise ValueError("halfplane_overlap: x and y corner arrays differ in length")
    if scratch is None:
        buf = np.empty((7, 3 * (na + 1) + 8))
        return halfplane_overlap_range(ax, ay, 0, na, px, py, mx, my, eps, out, buf)
    return halfplane_overlap_range(ax, ay, 0, na, px, py, mx, my, eps, out, scratch)


# ---------------------------------------------------------------------------
# body frame -> world frame
# ---------------------------------------------------------------------------
def world_corners(node_x, node_y, x, y, theta):
    """World coordinates of one particle's corners (numpy, for tests and tools).

    The cosine and sine are the kernels' (:func:`sim.rotation.cos_sin`).

    Parameters
    ----------
    node_x, node_y : array_like of float
        Body-frame corners (relative to the centre of mass).
    x, y : float
        Position of the centre of mass.
    theta : float
        Orientation angle [rad], counter-clockwise.

    Returns
    -------
    wx, wy : numpy.ndarray of float64
        ``(x + X cos(theta) - Y sin(theta), y + X sin(theta) + Y cos(theta))``.
    """
    node_x = np.asarray(node_x, dtype=np.float64)
    node_y = np.asarray(node_y, dtype=np.float64)
    c, s = cos_sin(float(theta))
    return x + (c * node_x - s * node_y), y + (s * node_x + c * node_y)
