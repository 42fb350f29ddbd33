"""One polygon: mass properties, validation, and a random polygon in an ellipse.

The particles of Roul, Schinner & Kassner (2010), Section 3.1, are convex
polygons inscribed into an ellipse, with a corner number drawn uniformly
from 6 to 8 and both semi-axes drawn independently and uniformly within
+-30 % of a mean of 3.4 mm.  This module draws one such polygon, checks that
a polygon is usable by the contact geometry (convex, counter-clockwise, not
nearly degenerate) and computes its area, centroid, polar moment of inertia
and radii.  The container of a pile's shapes, which draws the corner numbers
and semi-axes of many particles, is :mod:`sim.shapes`; the corners are in
the body frame described there.
"""

from __future__ import annotations

import numpy as np

from .config import ParticleParams

__all__ = [
    "MAX_CORNERS",
    "as_corner_arrays",
    "polygon_mass_properties",
    "polygon_radii",
    "validate_polygon",
    "random_polygon",
    "check_range",
    "check_int",
]

#: Largest corner count :func:`random_polygon` accepts.  The configuration
#: (and so :func:`sim.shapes.make_shapes`, which takes its settings) allows
#: fewer: the bounds of ``particles.corners_min`` / ``corners_max`` in
#: ``sim/config.schema.yaml``, up to the largest count that the
#: stability suite checks.
MAX_CORNERS = 64


# ---------------------------------------------------------------------------
# mass properties and radii
# ---------------------------------------------------------------------------
def as_corner_arrays(x, y, name="polygon"):
    """Return ``x, y`` as 1-D float64 arrays of equal length (no other checks)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.ndim != 1 or y.ndim != 1 or x.shape != y.shape:
        raise ValueError(
            f"{name}: corner coordinates must be two 1-D arrays of equal length, "
            f"got shapes {x.shape} and {y.shape}"
        )
    return x, y


def polygon_mass_properties(x, y):
    """Area, centroid and centroidal polar moment of area of a simple polygon.

    With the corners ``(x_k, y_k)``, ``k = 0..n-1`` (closed cyclically), and
    ``w_k = x_k y_{k+1} - x_{k+1} y_k``, the formulas are

    * area (shoelace / surveyor's formula): ``A = 1/2 sum_k w_k``;
    * centroid: ``c_x = 1/(6A) sum_k (x_k + x_{k+1}) w_k``,
      ``c_y = 1/(6A) sum_k (y_k + y_{k+1}) w_k``;
    * polar moment of area about the origin:
      ``J_O = 1/12 sum_k w_k (x_k^2 + x_k x_{k+1} + x_{k+1}^2
      + y_k^2 + y_k y_{k+1} + y_{k+1}^2)``,
      shifted to the centroid by the parallel-axis theorem,
      ``J_0 = J_O - A (c_x^2 + c_y^2)``.

    To limit round-off the sums are evaluated relative to the mean corner
    position.  For a homogeneous body of areal density ``rho`` the mass is
    ``rho * A`` and the moment of inertia about the centre of mass is
    ``rho * J_0``.

    Parameters
    ----------
    x, y : array_like of float, shape (n,)
        Corner coordinates, counter-clockwise, ``n >= 3``.  For a clockwise
        polygon the area (and ``j0``) come out negative.

    Returns
    -------
    area : float
        Signed area ``A`` (positive for counter-clockwise corners).
    cx, cy : float
        Centroid (centre of mass of a homogeneous lamina).
    j0 : float
        Second polar moment of area about the centroid, ``int (r - c)^2 dA``.

    Raises
    ------
    ValueError
        If the input is not two equal-length 1-D arrays with at least three
        corners, or the area is zero (no centroid).
    """
    x, y = as_corner_arrays(x, y)
    if x.shape[0] < 3:
        raise ValueError(f"polygon needs at least 3 corners, got {x.shape[0]}")
    x0 = x.mean()
    y0 = y.mean()
    xs = x - x0
    ys = y - y0
    xn = np.roll(xs, -1)
    yn = np.roll(ys, -1)
    w = xs * yn - xn * ys
    a2 = w.sum()
    if a2 == 0.0:
        raise ValueError("polygon has zero area; its centroid is undefined")
    area = 0.5 * a2
    cx_rel = ((xs + xn) * w).sum() / (3.0 * a2)
    cy_rel = ((ys + yn) * w).sum() / (3.0 * a2)
    j_ref = (w * (xs * xs + xs * xn + xn * xn + ys * ys + ys * yn + yn * yn)).sum() / 12.0
    j0 = j_ref - area * (cx_rel * cx_rel + cy_rel * cy_rel)
    return float(area), float(cx_rel + x0), float(cy_rel + y0), float(j0)


def polygon_radii(x, y):
    """Circumradius and inradius about the origin of a convex CCW polygon."""
    radius = float(np.max(np.hypot(x, y)))
    ex = np.roll(x, -1) - x
    ey = np.roll(y, -1) - y
    # distance of the origin to each edge line; positive inside a CCW polygon
    dist = (ex * (0.0 - y) - ey * (0.0 - x)) / np.hypot(ex, ey)
    return radius, float(np.min(dist))


# ---------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------
def _segments_intersect(p1, p2, q1, q2):
    """Whether closed segments ``p1p2`` and ``q1q2`` share a point (float predicates)."""

    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    def on_segment(a, b, c):  # c collinear with ab: is it within the bounding box?
        return (
            min(a[0], b[0]) <= c[0] <= max(a[0], b[0])
            and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])
        )

    d1 = orient(q1, q2, p1)
    d2 = orient(q1, q2, p2)
    d3 = orient(p1, p2, q1)
    d4 = orient(p1, p2, q2)
    if ((d1 > 0 and d2 < 0) or (d1 < 0 and d2 > 0)) and (
        (d3 > 0 and d4 < 0) or (d3 < 0 and d4 > 0)
    ):
        return True
    if d1 == 0 and on_segment(q1, q2, p1):
        return True
    if d2 == 0 and on_segment(q1, q2, p2):
        return True
    if d3 == 0 and on_segment(p1, p2, q1):
        return True
    if d4 == 0 and on_segment(p1, p2, q2):
        return True
    return False


def validate_polygon(x, y, min_edge, min_angle_deg, name="polygon"):
    """Check that a polygon is a usable, well-conditioned convex particle shape.

    The checks run in this order and the first failure raises:

    1. at least 3 corners, all coordinates finite;
    2. every edge at least ``min_edge`` long (and never of zero length);
    3. not self-intersecting: no two non-adjacent edges share a point and no
       two adjacent edges fold back onto each other;
    4. counter-clockwise (positive signed area);
    5. convex: every corner turns left (interior angle below 180 degrees);
    6. not nearly degenerate: every interior angle lies within
       ``[min_angle_deg, 180 - min_angle_deg]`` degrees (no needle-sharp
       corners and no almost-straight corners).

    Parameters
    ----------
    x, y : array_like of float, shape (n,)
        Corner coordinates in order.
    min_edge : float
        Shortest allowed edge length (same unit as ``x``, ``y``); ``>= 0``.
    min_angle_deg : float
        Smallest allowed interior angle in degrees, ``0 <= min_angle_deg < 60``.
        Interior angles above ``180 - min_angle_deg`` are rejected too.
    name : str, optional
        How the polygon is called in error messages, e.g. ``"particle 17"``.

    Returns
    -------
    None

    Raises
    ------
    ValueError
        Naming the polygon, the offending corner/edge, its value and what is
        allowed.
    """
    x, y = as_corner_arrays(x, y, name)
    n = x.shape[0]
    if not (np.isfinite(min_edge) and min_edge >= 0.0):
        raise ValueError(f"min_edge must be finite and >= 0, got {min_edge!r}")
    if not (np.isfinite(min_angle_deg) and 0.0 <= min_angle_deg < 60.0):
        raise ValueError(f"min_angle_deg must lie in [0, 60), got {min_angle_deg!r}")
    if n < 3:
        raise ValueError(f"{name}: a polygon needs at least 3 corners, got {n}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError(f"{name}: corner coordinates must be finite (found NaN or inf)")
    ex, ey = _checked_edges(x, y, min_edge, name)
    _check_simple(x, y, ex, ey, name)
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if area2 <= 0.0:
        raise ValueError(
            f"{name}: corners are not counter-clockwise (signed area "
            f"{0.5 * area2:.6g} <= 0); list them counter-clockwise"
        )
    _check_corner_angles(ex, ey, min_angle_deg, name)


def _checked_edges(x, y, min_edge, name):
    """The edge vectors of a polygon, none shorter than `min_edge` or of zero length.

    Parameters
    ----------
    x, y : ndarray of float, shape (n,)
        Finite corner coordinates in order.
    min_edge : float
        Shortest allowed edge length.
    name : str
        How the polygon is called in error messages.

    Returns
    -------
    ex, ey : ndarray of float, shape (n,)
        Edge k runs from corner k to corner k + 1 (the last back to corner 0).

    Raises
    ------
    ValueError
        Naming the shortest edge: two corners coincide, or it is shorter than
        `min_edge`.
    """
    n = x.shape[0]
    ex = np.roll(x, -1) - x
    ey = np.roll(y, -1) - y
    length = np.hypot(ex, ey)
    k = int(np.argmin(length))
    if length[k] == 0.0:
        raise ValueError(
            f"{name}: corners {k} and {(k + 1) % n} coincide (zero-length edge {k})"
        )
    if length[k] < min_edge:
        raise ValueError(
            f"{name}: edge {k} is too short: length {length[k]:.6g} < minimum "
            f"allowed {min_edge:.6g}"
        )
    return ex, ey


def _check_simple(x, y, ex, ey, name):
    """Raise unless the polygon is simple: no two adjacent edges fold back onto
    each other (a 360-degree turn) and no two non-adjacent edges share a point.

    Parameters
    ----------
    x, y : ndarray of float, shape (n,)
        Corner coordinates in order.
    ex, ey : ndarray of float, shape (n,)
        Edge vectors (:func:`_checked_edges`).
    name : str
        How the polygon is called in error messages.

    Raises
    ------
    ValueError
        Naming the two edges.
    """
    n = x.shape[0]
    for i in range(n):
        j = (i + 1) % n
        cross = ex[i] * ey[j] - ey[i] * ex[j]
        dot = ex[i] * ex[j] + ey[i] * ey[j]
        if cross == 0.0 and dot < 0.0:
            raise ValueError(
                f"{name}: self-intersecting: edges {i} and {j} fold back onto each "
                f"other at corner {j}"
            )
    pts = np.column_stack([x, y])
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # adjacent through corner 0
            if _segments_intersect(pts[i], pts[(i + 1) % n], pts[j], pts[(j + 1) % n]):
                raise ValueError(
                    f"{name}: self-intersecting: edges {i} and {j} intersect "
                    f"(a simple polygon is required)"
                )


def _check_corner_angles(ex, ey, min_angle_deg, name):
    """Raise unless every corner turns left (convex) and its interior angle lies
    within ``[min_angle_deg, 180 - min_angle_deg]`` degrees.

    Parameters
    ----------
    ex, ey : ndarray of float, shape (n,)
        Edge vectors of a counter-clockwise polygon (:func:`_checked_edges`).
    min_angle_deg : float
        Smallest allowed interior angle in degrees.
    name : str
        How the polygon is called in error messages.

    Raises
    ------
    ValueError
        Naming the corner and its interior angle: non-convex, too sharp or
        too flat.
    """
    # interior angle at corner j between incoming edge i=j-1 and outgoing edge j
    exp = np.roll(ex, 1)
    eyp = np.roll(ey, 1)
    cross = exp * ey - eyp * ex
    dot = exp * ex + eyp * ey
    turn = np.degrees(np.arctan2(cross, dot))  # exterior (turning) angle, CCW > 0
    interior = 180.0 - turn
    j = int(np.argmin(turn))
    if cross[j] < 0.0:
        raise ValueError(
            f"{name}: non-convex at corner {j}: interior angle {interior[j]:.6g} deg "
            f"> 180 deg (a convex polygon is required)"
        )
    j = int(np.argmin(interior))
    if interior[j] < min_angle_deg:
        raise ValueError(
            f"{name}: corner {j} is too sharp: interior angle {interior[j]:.6g} deg "
            f"< minimum allowed {min_angle_deg:.6g} deg"
        )
    j = int(np.argmax(interior))
    if interior[j] > 180.0 - min_angle_deg:
        raise ValueError(
            f"{name}: corner {j} is too flat (nearly degenerate): interior angle "
            f"{interior[j]:.6g} deg > maximum allowed {180.0 - min_angle_deg:.6g} deg"
        )


# ---------------------------------------------------------------------------
# argument checks (also of sim.shapes)
# ---------------------------------------------------------------------------
def check_range(name, value, lo=None, hi=None, lo_open=False, hi_open=False):
    """Raise ``ValueError`` unless ``lo <(=) value <(=) hi`` (and finite).

    The message names the argument, its value and the allowed range, e.g.
    ``aspect_ratio = 'long' is not a number; allowed range [1, 3]``.
    """
    left = "-inf" if lo is None else f"{lo!r}"
    right = "inf" if hi is None else f"{hi!r}"
    lb = "(" if (lo_open or lo is None) else "["
    rb = ")" if (hi_open or hi is None) else "]"
    allowed = f"{lb}{left}, {right}{rb}"
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is not a number; allowed range {allowed}") from None
    ok = np.isfinite(v)
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v < hi if hi_open else v <= hi
    if not ok:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {allowed}")
    return v


def check_int(name, value, lo, hi=None):
    """Raise ``ValueError`` unless ``value`` is an integer in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if value < lo or (hi is not None and value > hi):
        right = "inf" if hi is None else str(hi)
        raise ValueError(f"{name} = {value!r} is outside the allowed range [{lo}, {right}]")
    return int(value)


# ---------------------------------------------------------------------------
# generation
# ---------------------------------------------------------------------------
def random_polygon(
    rng,
    n_corners,
    a,
    b,
    jitter=0.5,
    min_edge_fraction=ParticleParams.min_edge_fraction,
    min_angle_deg=ParticleParams.min_angle_deg,
    rotation=None,
    max_tries=1000,
):
    """Random convex polygon inscribed in an ellipse (Section 3.1 of the paper).

    Corner ``k`` sits at the ellipse angle
    ``phi_k = 2 pi k / n + jitter * U(-1, 1) * pi / n`` (angles sorted, so the
    corners are counter-clockwise) at ``(a cos phi_k, b sin phi_k)``; the
    polygon is then rotated by ``rotation`` (uniform in ``[0, 2 pi)`` if not
    given) about the ellipse centre and shifted so that its centroid is at the
    origin.  A polygon inscribed in an ellipse is always convex; candidates
    failing :func:`validate_polygon` with
    ``min_edge = min_edge_fraction * 2 * min(a, b)`` and ``min_angle_deg``
    (too short an edge, too sharp or too flat a corner) are redrawn.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    n_corners : int
        Number of corners, ``3 <= n_corners <= 64``.
    a, b : float
        Semi-axes of the ellipse along the x and y axis before rotation (> 0).
    jitter : float, optional
        Angular jitter in units of half the mean angular spacing, in
        ``[0, 1]``; 0 gives corners at equal ellipse angles.
    min_edge_fraction : float, optional
        Shortest allowed edge as a fraction of the minor diameter
        ``2 min(a, b)``, in ``[0, 0.5)``; default: that of the configuration
        (``particles.min_edge_fraction``).
    min_angle_deg : float, optional
        Allowed interior angles are ``[min_angle_deg, 180 - min_angle_deg]``,
        in ``[0, 60)``; default: ``particles.min_angle_deg``.
    rotation : float or None, optional
        Rotation angle in radians; ``None`` draws it uniformly.
    max_tries : int, optional
        Number of candidates drawn before giving up.

    Returns
    -------
    x, y : numpy.ndarray of float64, shape (n_corners,)
        Body-frame corners (counter-clockwise, centroid at the origin).

    Raises
    ------
    ValueError
        For arguments outside their allowed range, or if no valid polygon was
        found within ``max_tries`` candidates (the constraints are too strict
        for this ellipse and corner count).
    """
    n = check_int("n_corners", n_corners, 3, MAX_CORNERS)
    a = check_range("a", a, 0.0, None, lo_open=True)
    b = check_range("b", b, 0.0, None, lo_open=True)
    jitter = check_range("jitter", jitter, 0.0, 1.0)
    min_edge_fraction = check_range("min_edge_fraction", min_edge_fraction, 0.0, 0.5, hi_open=True)
    min_angle_deg = check_range("min_angle_deg", min_angle_deg, 0.0, 60.0, hi_open=True)
    max_tries = check_int("max_tries", max_tries, 1)
    min_edge = min_edge_fraction * 2.0 * min(a, b)
    last_error = None
    for _ in range(max_tries):
        k = np.arange(n)
        phi = 2.0 * np.pi * k / n + jitter * rng.uniform(-1.0, 1.0, n) * np.pi / n
        phi.sort()
        rot = rng.uniform(0.0, 2.0 * np.pi) if rotation is None else float(rotation)
        ex = a * np.cos(phi)
        ey = b * np.sin(phi)
        c, s = np.cos(rot), np.sin(rot)
        x = c * ex - s * ey
        y = s * ex + c * ey
        try:
            validate_polygon(x, y, min_edge, min_angle_deg, name="candidate polygon")
        except ValueError as err:
            last_error = err
            continue
        _, cx, cy, _ = polygon_mass_properties(x, y)
        x = x - cx
        y = y - cy
        return x, y
    raise ValueError(
        f"random_polygon: no valid {n}-gon in ellipse a={a:.6g}, b={b:.6g} after "
        f"{max_tries} tries (min_edge={min_edge:.6g}, min_angle_deg={min_angle_deg}); "
        f"last rejection: {last_error}"
    )
