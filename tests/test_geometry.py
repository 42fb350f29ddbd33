"""Tests of the narrow-phase contact geometry (sim/geometry.py).

References are independent of the code under test: shapely (GEOS) for areas
and boundary intersections, exact rational arithmetic (fractions) for tiny
overlaps, and hand-derived values for constructed degenerate configurations.
"""

from fractions import Fraction

import numpy as np
import pytest
from shapely.geometry import LineString, MultiPoint, Point, Polygon, box

from sim.geometry import (
    OUT_SIZE,
    halfplane_overlap,
    halfplane_overlap_range,
    make_scratch,
    polygon_overlap,
    polygon_overlap_range,
    world_corners,
)
from sim.shapes import make_shapes

REL_EPS = 1e-9  # length tolerance relative to the particle size
SCRATCH = make_scratch(32)


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def _arr(pts):
    pts = np.asarray(pts, dtype=np.float64)
    return np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])


def size_of(*polys):
    """Largest bounding-box extent of the polygons (a particle-size scale)."""
    return max(max(np.ptp(p[:, 0]), np.ptp(p[:, 1])) for p in polys)


def overlap(a, b, eps=None, ca=None, cb=None, scratch=SCRATCH):
    """Call polygon_overlap on (n, 2) corner arrays; centroids from shapely."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if ca is None:
        ca = Polygon(a).centroid.coords[0]
    if cb is None:
        cb = Polygon(b).centroid.coords[0]
    if eps is None:
        eps = REL_EPS * size_of(a, b)
    out = np.full(OUT_SIZE, np.nan)
    ax, ay = _arr(a)
    bx, by = _arr(b)
    hit = polygon_overlap(ax, ay, bx, by, ca[0], ca[1], cb[0], cb[1], eps, out, scratch)
    return hit, out


def farthest_pair(pts):
    pts = np.asarray(pts, dtype=np.float64)
    d2 = ((pts[:, None, :] - pts[None, :, :]) ** 2).sum(-1)
    i, j = np.unravel_index(np.argmax(d2), d2.shape)
    return pts[[i, j]]


def boundary_points(geom):
    """All coordinates of a (multi)point/line intersection geometry."""
    if geom.is_empty:
        return np.zeros((0, 2))
    parts = getattr(geom, "geoms", [geom])
    return np.array([c for g in parts for c in g.coords])


def assert_same_pair(c, ref, tol):
    c = np.asarray(c).reshape(2, 2)
    ref = np.asarray(ref).reshape(2, 2)
    err = min(np.abs(c - ref).max(), np.abs(c[::-1] - ref).max())
    assert err <= tol, f"contact points {c.tolist()} differ from {ref.tolist()} by {err}"


def assert_contact_invariants(out, ca, cb, eps):
    """Layout invariants that hold for every positive result."""
    assert np.all(np.isfinite(out[:10]))
    assert out[0] > 0.0
    c1, c2, s, n, ln = out[1:3], out[3:5], out[5:7], out[7:9], out[9]
    assert np.hypot(*n) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(s, 0.5 * (c1 + c2), rtol=0, atol=1e-15 * (1 + np.abs(s).max()))
    assert ln == pytest.approx(np.hypot(*(c2 - c1)), rel=1e-12, abs=1e-300)
    if ln > 0:
        t = np.array([-n[1], n[0]])
        # c2 - c1 = ln * t
        np.testing.assert_allclose(c2 - c1, ln * t, atol=1e-9 * ln + 1e-15 * np.abs(c1).max())
    g = np.asarray(cb, dtype=float) - np.asarray(ca, dtype=float)
    assert n @ g >= -eps


# exact (rational) Sutherland-Hodgman clipping as an independent reference
def exact_overlap_area(a, b):
    def clip(poly, p, q):
        res = []
        ex, ey = q[0] - p[0], q[1] - p[1]
        m = len(poly)
        for k in range(m):
            P, Q = poly[k - 1], poly[k]
            dP = ex * (P[1] - p[1]) - ey * (P[0] - p[0])
            dQ = ex * (Q[1] - p[1]) - ey * (Q[0] - p[0])
            if dQ >= 0:
                if dP < 0:
                    t = dP / (dP - dQ)
                    res.append((P[0] + t * (Q[0] - P[0]), P[1] + t * (Q[1] - P[1])))
                res.append(Q)
            elif dP >= 0:
                t = dP / (dP - dQ)
                res.append((P[0] + t * (Q[0] - P[0]), P[1] + t * (Q[1] - P[1])))
        return res

    poly = [(Fraction(x), Fraction(y)) for x, y in a]
    bb = [(Fraction(x), Fraction(y)) for x, y in b]
    for j in range(len(bb)):
        poly = clip(poly, bb[j], bb[(j + 1) % len(bb)])
        if not poly:
            return Fraction(0)
    s = sum(poly[k - 1][0] * poly[k][1] - poly[k][0] * poly[k - 1][1] for k in range(len(poly)))
    return s / 2


def square(x0, y0, s):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]], dtype=float)


def rect(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def rotate(pts, theta, about=(0.0, 0.0)):
    c, s = np.cos(theta), np.sin(theta)
    p = np.asarray(pts, dtype=float) - about
    return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]]) + about


# ---------------------------------------------------------------------------
# random pairs against shapely
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def particle_shapes():
    return make_shapes(np.random.default_rng(2024), 300)


def _random_pairs(shapes, rng, n_trials, offset=(0.0, 0.0)):
    for _ in range(n_trials):
        i, j = rng.integers(0, shapes.n, 2)
        ca = np.array(offset) + rng.uniform(-1e-3, 1e-3, 2)
        a = np.column_stack(world_corners(*shapes.corners(i), ca[0], ca[1], rng.uniform(0, 2 * np.pi)))
        r = shapes.radius[i] + shapes.radius[j]
        cb = ca + rng.uniform(-r, r, 2)
        b = np.column_stack(world_corners(*shapes.corners(j), cb[0], cb[1], rng.uniform(0, 2 * np.pi)))
        yield i, j, a, b, ca, cb


def test_random_pairs_match_shapely(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(7)
    size = 2 * 3.4e-3
    eps = REL_EPS * size
    n_overlap = n_nested = n_multi = 0
    for i, j, a, b, ca, cb in _random_pairs(sh, rng, 2000):
        A, B = Polygon(a), Polygon(b)
        ref = A.intersection(B).area
        hit, out = overlap(a, b, eps=eps, ca=ca, cb=cb)
        if ref == 0.0:
            assert not hit
            continue
        n_overlap += 1
        assert hit
        assert out[0] == pytest.approx(ref, rel=0, abs=1e-9 * min(sh.area[i], sh.area[j]))
        assert_contact_invariants(out, ca, cb, eps)
        pts = boundary_points(A.boundary.intersection(B.boundary))
        if len(pts) == 0:  # one polygon inside the other: nested fall-back
            n_nested += 1
            assert out[9] == 0.0
            np.testing.assert_allclose(out[5:7], A.intersection(B).centroid.coords[0], atol=eps)
            g = cb - ca
            np.testing.assert_allclose(out[7:9], g / np.hypot(*g), atol=1e-12)
            continue
        if len(pts) > 2:
            n_multi += 1  # deep overlap, 4+ crossings: extreme pair is used
        assert_same_pair(out[1:5], farthest_pair(pts), eps)
    assert n_overlap >= 1000
    assert n_multi > 0


def test_non_overlapping_pairs_are_rejected(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(8)
    n = 0
    for _, _, a, b, ca, cb in _random_pairs(sh, rng, 600):
        if Polygon(a).intersects(Polygon(b)):
            continue
        n += 1
        hit, out = overlap(a, b, ca=ca, cb=cb)
        assert not hit
        assert np.all(np.isnan(out))  # untouched
    assert n > 100


def test_swapping_the_polygons_flips_the_normal(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(9)
    for _, _, a, b, ca, cb in _random_pairs(sh, rng, 300):
        hit_ab, ab = overlap(a, b, ca=ca, cb=cb)
        hit_ba, ba = overlap(b, a, ca=cb, cb=ca)
        assert hit_ab == hit_ba
        if not hit_ab:
            continue
        assert ab[0] == pytest.approx(ba[0], rel=1e-11)
        if ab[9] > 0:
            assert_same_pair(ab[1:5], ba[1:5], 1e-9 * 6.8e-3)
            np.testing.assert_allclose(ab[7:9], -ba[7:9], atol=1e-9)


def test_huge_coordinate_offset_keeps_relative_accuracy(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(10)
    off = 1.0e3
    size = 2 * 3.4e-3
    eps = REL_EPS * size
    n = 0
    for i, j, a, b, ca, cb in _random_pairs(sh, rng, 400, offset=(off, off)):
        # subtracting the offset is exact (Sterbenz), so shapely sees exactly
        # the same geometry near the origin, where it is most accurate
        a0, b0 = a - off, b - off
        A, B = Polygon(a0), Polygon(b0)
        ref = A.intersection(B).area
        hit, out = overlap(a, b, eps=eps, ca=ca, cb=cb)
        if ref == 0.0:
            assert not hit
            continue
        n += 1
        assert hit
        assert out[0] == pytest.approx(ref, rel=0, abs=1e-9 * min(sh.area[i], sh.area[j]))
        pts = boundary_points(A.boundary.intersection(B.boundary))
        if len(pts) >= 2:
            assert_same_pair(out[1:5] - off, farthest_pair(pts), eps)
    assert n > 150


# ---------------------------------------------------------------------------
# degenerate configurations
# ---------------------------------------------------------------------------
def test_edge_on_edge_touching_is_no_contact():
    a = square(0, 0, 1)
    b = square(1, 0, 1)  # shares the edge x = 1 exactly
    hit, out = overlap(a, b)
    assert not hit
    b = rect(1, 0.25, 2, 0.75)  # partial collinear contact
    assert not overlap(a, b)[0]


def test_edge_on_edge_touching_rotated_has_negligible_area():
    # round-off in rotated coordinates may leave a sliver of round-off size
    for theta in np.linspace(0.1, 3.0, 13):
        a = rotate(square(0, 0, 1), theta)
        b = rotate(square(1, 0, 1), theta)
        hit, out = overlap(a, b)
        if hit:
            assert out[0] < 1e-14
            assert np.all(np.isfinite(out))


def test_parallel_edges_slightly_overlapping():
    a = square(0, 0, 1)
    delta = 1e-3
    x0 = 1.0 - delta
    depth = 1.0 - x0  # exact
    b = rect(x0, 0.2, x0 + 1.0, 0.8)
    hit, out = overlap(a, b)
    assert hit
    assert out[0] == pytest.approx(0.6 * depth, rel=1e-12)
    assert_same_pair(out[1:5], [[1, 0.2], [1, 0.8]], 1e-12)
    np.testing.assert_allclose(out[7:9], [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(out[5:7], [1.0, 0.5], atol=1e-15)
    assert out[9] == pytest.approx(0.6)


def test_parallel_edges_with_collinear_sides():
    # b's top and bottom edges are collinear with a's: the crossing points
    # are ambiguous; the result must still be a valid contact whose normal is
    # (nearly) perpendicular to the contact face
    a = square(0, 0, 1)
    x0 = 1.0 - 1e-3
    b = rect(x0, 0.0, x0 + 1.0, 1.0)
    hit, out = overlap(a, b)
    assert hit
    assert out[0] == pytest.approx(1.0 - x0, rel=1e-12)
    assert_contact_invariants(out, (0.5, 0.5), (x0 + 0.5, 0.5), 1e-9)
    assert out[7] > 0.99
    # the contact points lie on both boundaries
    A, B = Polygon(a), Polygon(b)
    for p in out[1:5].reshape(2, 2):
        assert A.boundary.distance(Point(p)) < 1e-12
        assert B.boundary.distance(Point(p)) < 1e-12


def test_vertex_on_vertex():
    a = square(0, 0, 1)
    # corners touching only: zero area
    assert not overlap(a, square(1, 1, 1))[0]
    assert not overlap(a, square(-1, -1, 1))[0]
    # diamond sharing the corner (0, 0) with a and overlapping it
    b = np.array([[0, 0], [0.6, 0.6], [0, 1.2], [-0.6, 0.6]], dtype=float)
    hit, out = overlap(a, b)
    assert hit
    A, B = Polygon(a), Polygon(b)
    assert out[0] == pytest.approx(A.intersection(B).area, rel=1e-12)
    assert out[0] == pytest.approx(0.34, rel=1e-12)  # hand-computed
    pts = boundary_points(A.boundary.intersection(B.boundary))
    assert_same_pair(out[1:5], farthest_pair(pts), 1e-12)
    assert_same_pair(out[1:5], [[0, 0], [0.2, 1.0]], 1e-12)
    assert_contact_invariants(out, A.centroid.coords[0], B.centroid.coords[0], 1e-9)


@pytest.mark.parametrize("swap", [False, True])
def test_vertex_exactly_on_edge(swap):
    a = square(0, 0, 1)
    # b's corner (0.5, 1) lies on a's top edge; one of its edges enters a
    b = np.array([[0.5, 1.0], [0.8, 0.5], [1.5, 1.5]])
    if swap:
        a, b = b, a
    hit, out = overlap(a, b)
    assert hit
    A, B = Polygon(a), Polygon(b)
    assert out[0] == pytest.approx(A.intersection(B).area, rel=1e-12)
    pts = boundary_points(A.boundary.intersection(B.boundary))
    assert len(pts) == 2
    assert_same_pair(out[1:5], pts, 1e-12)
    assert_same_pair(out[1:5], [[0.5, 1.0], [1.0, 0.5 + 0.2 / 0.7]], 1e-12)
    assert_contact_invariants(out, A.centroid.coords[0], B.centroid.coords[0], 1e-9)


def test_vertex_on_edge_from_inside_is_nested():
    # triangle inside the square touching its top edge with one corner
    a = square(0, 0, 1)
    b = np.array([[0.5, 1.0], [0.3, 0.4], [0.7, 0.4]])
    b = b[::-1] if not Polygon(b).exterior.is_ccw else b
    hit, out = overlap(a, b)
    assert hit
    assert out[0] == pytest.approx(Polygon(b).area, rel=1e-12)
    assert out[9] == 0.0  # no crossing: nested fall-back
    np.testing.assert_allclose(out[5:7], Polygon(b).centroid.coords[0], atol=1e-12)


def test_nested_polygon_fallback():
    a = square(0, 0, 1)
    b = square(0.3, 0.2, 0.3)
    ca, cb = (0.5, 0.5), (0.45, 0.35)
    for p, q, cp, cq in [(a, b, ca, cb), (b, a, cb, ca)]:
        hit, out = overlap(p, q, ca=cp, cb=cq)
        assert hit
        assert out[0] == pytest.approx(0.09, rel=1e-12)
        assert out[9] == 0.0
        np.testing.assert_array_equal(out[1:3], out[3:5])
        np.testing.assert_allclose(out[5:7], cb, atol=1e-12)  # centroid of the inner square
        g = np.subtract(cq, cp)
        np.testing.assert_allclose(out[7:9], g / np.hypot(*g), atol=1e-14)


def test_concentric_nested_polygons_give_a_unit_normal():
    a = square(-1, -1, 2)
    b = square(-0.5, -0.5, 1)
    hit, out = overlap(a, b, ca=(0, 0), cb=(0, 0))
    assert hit
    assert out[0] == pytest.approx(1.0)
    assert np.hypot(*out[7:9]) == pytest.approx(1.0)
    assert np.all(np.isfinite(out))


def test_nested_touching_along_an_edge_uses_the_shared_edge():
    a = square(0, 0, 1)
    b = rect(0.2, 0.5, 0.7, 1.0)  # inside a, top edge on a's top edge
    hit, out = overlap(a, b)
    assert hit
    assert out[0] == pytest.approx(0.25, rel=1e-12)
    assert_same_pair(out[1:5], [[0.2, 1.0], [0.7, 1.0]], 1e-12)
    np.testing.assert_allclose(out[7:9], [0.0, 1.0], atol=1e-15)


def test_almost_nested_with_tiny_sliver_outside():
    a = square(0, 0, 1)
    # small square rotated by 45 degrees whose right corner pokes out of a
    # through the edge x = 1 by 1e-7 (crossings 2e-7 apart, >> eps)
    h = 0.2
    poke = 1e-7
    cx = 1.0 + poke - h
    b = np.array([[cx, 0.5 - h], [cx + h, 0.5], [cx, 0.5 + h], [cx - h, 0.5]])
    hit, out = overlap(a, b)
    assert hit
    A, B = Polygon(a), Polygon(b)
    exact = float(exact_overlap_area(a, b))
    assert out[0] == pytest.approx(exact, rel=1e-12)
    assert out[0] == pytest.approx(A.intersection(B).area, rel=1e-12)
    pts = boundary_points(A.boundary.intersection(B.boundary))
    assert_same_pair(out[1:5], farthest_pair(pts), 1e-12)
    np.testing.assert_allclose(out[7:9], [1.0, 0.0], atol=1e-7)
    assert out[9] == pytest.approx(2 * (b[1, 0] - 1.0), rel=1e-6)


def test_identical_polygons_on_top_of_each_other(particle_shapes):
    x, y = world_corners(*particle_shapes.corners(3), 0.01, 0.02, 0.7)
    a = np.column_stack([x, y])
    hit, out = overlap(a, a.copy(), ca=(0.01, 0.02), cb=(0.01, 0.02))
    assert hit
    assert out[0] == pytest.approx(Polygon(a).area, rel=1e-12)
    assert np.all(np.isfinite(out))
    assert np.hypot(*out[7:9]) == pytest.approx(1.0)


@pytest.mark.parametrize("theta", [0.0, 0.3, 1.1, 2.5])
def test_tiny_corner_overlap_is_accurate(theta):
    # a diamond's corner pokes 1e-6 into a unit square: area ~ 1e-12
    a = square(0, 0, 1)
    d = 1e-6
    b = np.array([[0.5, 1 - d], [1.0, 1.5 - d], [0.5, 2 - d], [0.0, 1.5 - d]])
    a = rotate(a, theta, about=(0.5, 0.5))
    b = rotate(b, theta, about=(0.5, 0.5))
    hit, out = overlap(a, b)
    assert hit
    exact = float(exact_overlap_area(a, b))
    assert exact == pytest.approx(d * d, rel=1e-6)
    assert out[0] == pytest.approx(exact, rel=1e-8)
    # crossing points: on a's top edge, d either side of the corner
    top = rotate(np.array([[0.5 - d, 1.0], [0.5 + d, 1.0]]), theta, about=(0.5, 0.5))
    assert_same_pair(out[1:5], top, 1e-14)
    n_expected = rotate(np.array([[0.0, 1.0]]), theta)[0]
    np.testing.assert_allclose(out[7:9], n_expected, atol=1e-8)


def test_tiny_parallel_sliver_is_accurate():
    a = square(0, 0, 1)
    x0 = 1.0 - 1e-12
    b = rect(x0, 0.25, x0 + 1, 0.75)
    hit, out = overlap(a, b)
    assert hit
    exact = float(exact_overlap_area(a, b))
    assert exact == pytest.approx(0.5 * (1.0 - x0), rel=1e-15)
    assert out[0] == pytest.approx(exact, rel=1e-9)
    np.testing.assert_allclose(out[7:9], [1.0, 0.0], atol=1e-15)


def test_overlap_below_area_tolerance_is_ignored():
    a = square(0, 0, 1)
    d = 1e-10
    b = np.array([[0.5, 1 - d], [1.0, 1.5 - d], [0.5, 2 - d], [0.0, 1.5 - d]])
    assert overlap(a, b, eps=1e-9)[0] is False  # area 1e-20 < eps**2 = 1e-18
    assert overlap(a, b, eps=1e-12)[0] is True


def test_normal_tie_break_uses_the_boundary_chains():
    # contact line vertical at x = 1, but cb - ca is vertical too: the
    # normal must point from a (left) into b (right)
    a = square(0, 0, 1)
    b = rect(0.9, 0.2, 1.9, 0.8)
    hit, out = overlap(a, b, ca=(0.5, 0.5), cb=(0.5, 0.9))
    assert hit
    np.testing.assert_allclose(out[7:9], [1.0, 0.0], atol=1e-15)
    hit, out = overlap(b, a, ca=(0.5, 0.9), cb=(0.5, 0.5))
    np.testing.assert_allclose(out[7:9], [-1.0, 0.0], atol=1e-15)


def _lattice_polygon(rng, g=5):
    while True:
        pts = rng.integers(0, g, size=(rng.integers(3, 9), 2)).astype(float)
        h = MultiPoint(pts).convex_hull
        if h.geom_type == "Polygon" and h.area > 0:
            c = np.array(h.exterior.coords)[:-1]
            return c if Polygon(c).exterior.is_ccw else c[::-1]


def test_lattice_polygons_full_of_degeneracies():
    """Integer corners: collinear edges, shared vertices, vertices on edges."""
    rng = np.random.default_rng(5)
    n_two = 0
    for _ in range(1000):
        a = _lattice_polygon(rng)
        b = _lattice_polygon(rng) + rng.integers(-2, 3, 2)
        A, B = Polygon(a), Polygon(b)
        ref = A.intersection(B).area
        hit, out = overlap(a, b)
        if ref == 0.0:
            assert not hit
            continue
        assert hit
        assert out[0] == pytest.approx(ref, rel=0, abs=1e-12)
        assert_contact_invariants(out, A.centroid.coords[0], B.centroid.coords[0], 1e-9)
        if out[9] == 0.0:
            continue
        for p in out[1:5].reshape(2, 2):  # on both boundaries
            assert A.boundary.distance(Point(p)) < 1e-12
            assert B.boundary.distance(Point(p)) < 1e-12
        g = A.boundary.intersection(B.boundary)
        if g.geom_type == "MultiPoint" and len(g.geoms) == 2:
            n_two += 1
            assert_same_pair(out[1:5], boundary_points(g), 1e-12)
    assert n_two > 200


# ---------------------------------------------------------------------------
# API details
# ---------------------------------------------------------------------------
def _all_world_corners(sh, x, y, th):
    """World corners of every particle, concatenated like the body-frame arrays."""
    parts = [world_corners(*sh.corners(i), x[i], y[i], th[i]) for i in range(sh.n)]
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))


def test_range_variant_and_default_scratch_agree(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(11)
    x = rng.uniform(0, 0.02, sh.n)
    y = rng.uniform(0, 0.02, sh.n)
    th = rng.uniform(0, 2 * np.pi, sh.n)
    wx, wy = _all_world_corners(sh, x, y, th)
    off = sh.node_offset
    eps = REL_EPS * 6.8e-3
    n_hit = 0
    for _ in range(400):
        i, j = rng.integers(0, sh.n, 2)
        if i == j:
            continue
        out1 = np.full(OUT_SIZE, np.nan)
        out2 = np.full(OUT_SIZE, np.nan)
        out3 = np.full(OUT_SIZE, np.nan)
        sl_i = slice(off[i], off[i + 1])
        sl_j = slice(off[j], off[j + 1])
        h1 = polygon_overlap_range(wx, wy, off[i], off[i + 1], wx, wy, off[j], off[j + 1],
                                   x[i], y[i], x[j], y[j], eps, out1, SCRATCH)
        h2 = polygon_overlap(wx[sl_i], wy[sl_i], wx[sl_j], wy[sl_j], x[i], y[i], x[j], y[j],
                             eps, out2)
        h3 = polygon_overlap(wx[sl_i], wy[sl_i], wx[sl_j], wy[sl_j], x[i], y[i], x[j], y[j],
                             eps, out3, SCRATCH)
        assert h1 == h2 == h3
        np.testing.assert_array_equal(out1, out2)
        np.testing.assert_array_equal(out1, out3)
        n_hit += h1
    assert n_hit > 10


def test_bad_buffers_raise():
    a = square(0, 0, 1)
    b = square(0.5, 0.5, 1)
    ax, ay = _arr(a)
    bx, by = _arr(b)
    with pytest.raises(ValueError, match="out"):
        polygon_overlap(ax, ay, bx, by, 0.5, 0.5, 1.0, 1.0, 1e-9, np.zeros(5), SCRATCH)
    with pytest.raises(ValueError, match="scratch"):
        polygon_overlap(ax, ay, bx, by, 0.5, 0.5, 1.0, 1.0, 1e-9, np.zeros(10),
                        np.zeros((7, 10)))
    with pytest.raises(ValueError, match="3 corners"):
        polygon_overlap(ax[:2], ay[:2], bx, by, 0.5, 0.5, 1.0, 1.0, 1e-9, np.zeros(10), SCRATCH)
    with pytest.raises(ValueError, match="out"):
        halfplane_overlap(ax, ay, 0.0, 0.5, 0.0, 1.0, 1e-9, np.zeros(3), SCRATCH)
    with pytest.raises(ValueError):
        make_scratch(2)


def test_world_corners_rotation_convention():
    wx, wy = world_corners([1.0, 0.0], [0.0, 1.0], 2.0, 3.0, np.pi / 2)
    np.testing.assert_allclose(wx, [2.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(wy, [4.0, 3.0], atol=1e-15)


# ---------------------------------------------------------------------------
# half-plane
# ---------------------------------------------------------------------------
def hp(a, p, m, eps=1e-9, scratch=SCRATCH):
    ax, ay = _arr(a)
    out = np.full(OUT_SIZE, np.nan)
    hit = halfplane_overlap(ax, ay, p[0], p[1], m[0], m[1], eps, out, scratch)
    return hit, out


def body_polygon(p, m, big):
    """A large box standing for the body {(q - p) . m < 0}."""
    p = np.asarray(p, float)
    m = np.asarray(m, float)
    t = np.array([-m[1], m[0]])
    return Polygon([p - big * t, p - big * t - big * m, p + big * t - big * m, p + big * t])


def test_halfplane_random_polygons_match_shapely(particle_shapes):
    sh = particle_shapes
    rng = np.random.default_rng(13)
    size = 2 * 3.4e-3
    eps = REL_EPS * size
    n = 0
    for k in range(400):
        i = rng.integers(0, sh.n)
        c = rng.uniform(-0.01, 0.01, 2)
        a = np.column_stack(world_corners(*sh.corners(i), c[0], c[1], rng.uniform(0, 2 * np.pi)))
        if k < 100:
            m = np.array([0.0, 1.0])  # the support
        else:
            phi = rng.uniform(0, 2 * np.pi)
            m = np.array([np.cos(phi), np.sin(phi)])
        p = c + rng.uniform(-1.2, 1.2) * sh.radius[i] * m + rng.uniform(-1, 1, 2) * 1e-3
        A = Polygon(a)
        ref = A.intersection(body_polygon(p, m, 1.0)).area
        hit, out = hp(a, p, m, eps)
        if ref == 0.0:
            assert not hit
            continue
        assert hit
        n += 1
        assert out[0] == pytest.approx(ref, rel=0, abs=1e-9 * sh.area[i])
        np.testing.assert_array_equal(out[7:9], -m)
        assert_contact_invariants(out, (0, 0), (0, 0), np.inf)
        t = np.array([-m[1], m[0]])
        line = LineString([p - t, p + t])
        pts = boundary_points(A.boundary.intersection(line))
        if len(pts) >= 2:
            assert_same_pair(out[1:5], farthest_pair(pts), eps)
            # contact points on the line
            assert abs((out[1:3] - p) @ m) < eps
            assert abs((out[3:5] - p) @ m) < eps
        else:  # polygon entirely inside the body
            assert out[0] == pytest.approx(A.area, rel=1e-12)
    assert n > 150


def test_halfplane_support_and_offset():
    a = rect(1000.0, -0.25, 1000.5, 0.75) + np.array([0.0, 0.0])
    hit, out = hp(a, (0.0, 0.0), (0.0, 1.0))
    assert hit
    assert out[0] == pytest.approx(0.125, rel=1e-12)
    assert_same_pair(out[1:5], [[1000.0, 0.0], [1000.5, 0.0]], 1e-12)
    np.testing.assert_array_equal(out[7:9], [0.0, -1.0])
    np.testing.assert_allclose(out[5:7], [1000.25, 0.0], atol=1e-12)


def test_halfplane_edge_exactly_on_the_line():
    a = square(0.0, 0.0, 1.0)  # bottom edge on y = 0
    # body y < 0: the square only touches it
    hit, out = hp(a, (0.0, 0.0), (0.0, 1.0))
    assert not hit
    # body y > 0 contains the square; the edge on the line is the contact line
    hit, out = hp(a, (0.0, 0.0), (0.0, -1.0))
    assert hit
    assert out[0] == pytest.approx(1.0)
    assert_same_pair(out[1:5], [[0.0, 0.0], [1.0, 0.0]], 1e-15)
    np.testing.assert_array_equal(out[7:9], [0.0, 1.0])
    # rotated square with an edge on a tilted line
    theta = 0.37
    r = rotate(a, theta)
    m = np.array([np.sin(theta), -np.cos(theta)])  # outward normal of the body above the edge
    hit, out = hp(r, (0.0, 0.0), -m)
    assert not hit or out[0] < 1e-15
    hit, out = hp(r, (0.0, 0.0), m)
    assert hit
    assert out[0] == pytest.approx(1.0, rel=1e-12)
    assert_same_pair(out[1:5], r[:2], 1e-12)


def test_halfplane_deeply_immersed_polygon_uses_nested_fallback():
    a = square(0.0, -3.0, 1.0)
    hit, out = hp(a, (0.0, 0.0), (0.0, 1.0))
    assert hit
    assert out[0] == pytest.approx(1.0)
    assert out[9] == 0.0
    np.testing.assert_allclose(out[5:7], [0.5, -2.5], atol=1e-14)


def test_halfplane_range_variant(particle_shapes):
    sh = particle_shapes
    x = np.zeros(sh.n)
    y = np.full(sh.n, 1e-3)
    th = np.linspace(0, 6, sh.n)
    wx, wy = _all_world_corners(sh, x, y, th)
    for i in range(0, sh.n, 7):
        a0, a1 = sh.node_offset[i], sh.node_offset[i + 1]
        o1 = np.full(OUT_SIZE, np.nan)
        o2 = np.full(OUT_SIZE, np.nan)
        h1 = halfplane_overlap_range(wx, wy, a0, a1, 0.0, 0.0, 0.0, 1.0, 1e-12, o1, SCRATCH)
        h2 = halfplane_overlap(wx[a0:a1], wy[a0:a1], 0.0, 0.0, 0.0, 1.0, 1e-12, o2)
        assert h1 == h2
        np.testing.assert_array_equal(o1, o2)
