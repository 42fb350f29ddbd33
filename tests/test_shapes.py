"""Tests of particle shape generation and mass properties (sim/polygon.py, sim/shapes.py).

Reference values are analytic formulas or shapely; nothing is copied from
the output of the code under test.
"""

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from sim.polygon import polygon_mass_properties, random_polygon, validate_polygon
from sim.shapes import Shapes, make_shapes, shapes_from_nodes


def regular_polygon(n, R, phase=0.0, center=(0.0, 0.0)):
    phi = phase + 2 * np.pi * np.arange(n) / n
    return center[0] + R * np.cos(phi), center[1] + R * np.sin(phi)


def triangle_polar_moment(p):
    """Polar moment of a triangle about its centroid: A (a^2 + b^2 + c^2) / 36."""
    a2 = np.sum((p[1] - p[0]) ** 2)
    b2 = np.sum((p[2] - p[1]) ** 2)
    c2 = np.sum((p[0] - p[2]) ** 2)
    u, v = p[1] - p[0], p[2] - p[0]
    area = 0.5 * abs(u[0] * v[1] - u[1] * v[0])
    return area, area * (a2 + b2 + c2) / 36.0


def polar_moment_by_triangles(x, y):
    """Independent J0: fan triangulation + per-triangle formula + parallel axes."""
    pts = np.column_stack([x, y])
    A_tot = 0.0
    S = np.zeros(2)
    J_origin = 0.0
    for k in range(1, len(pts) - 1):
        tri = pts[[0, k, k + 1]]
        area, j_c = triangle_polar_moment(tri)
        g = tri.mean(axis=0)
        A_tot += area
        S += area * g
        J_origin += j_c + area * g @ g
    c = S / A_tot
    return A_tot, c, J_origin - A_tot * c @ c


def conic_semi_axes(x, y):
    """Fit A x^2 + B xy + C y^2 + D x + E y = 1 and return (semi-axes, residual, axis angle)."""
    M = np.column_stack([x * x, x * y, y * y, x, y])
    coef, *_ = np.linalg.lstsq(M, np.ones_like(x), rcond=None)
    resid = np.abs(M @ coef - 1.0).max()
    A, B, C, D, E = coef
    Q = np.array([[A, B / 2], [B / 2, C]])
    c = -0.5 * np.linalg.solve(Q, [D, E])
    k = 1.0 + c @ Q @ c
    lam, vec = np.linalg.eigh(Q)
    axes = np.sqrt(k / lam)  # axes[i] along eigenvector vec[:, i]
    return axes, resid, vec


# ---------------------------------------------------------------------------
# mass properties
# ---------------------------------------------------------------------------
def test_square():
    s = 2.0
    x = np.array([1.0, 1 + s, 1 + s, 1.0])
    y = np.array([-1.0, -1.0, -1 + s, -1 + s])
    area, cx, cy, j0 = polygon_mass_properties(x, y)
    assert area == pytest.approx(s * s, rel=1e-14)
    assert (cx, cy) == pytest.approx((2.0, 0.0), abs=1e-14)
    assert j0 == pytest.approx(s**4 / 6.0, rel=1e-13)


def test_rectangle_far_from_origin():
    w, h = 3.0, 0.5
    x0, y0 = 1e4, -2e4
    x = np.array([x0, x0 + w, x0 + w, x0])
    y = np.array([y0, y0, y0 + h, y0 + h])
    area, cx, cy, j0 = polygon_mass_properties(x, y)
    assert area == pytest.approx(w * h, rel=1e-12)
    assert (cx, cy) == pytest.approx((x0 + w / 2, y0 + h / 2), rel=1e-15)
    assert j0 == pytest.approx(w * h * (w * w + h * h) / 12.0, rel=1e-10)


@pytest.mark.parametrize("n", [3, 5, 6, 7, 8, 12, 32])
def test_regular_polygon(n):
    R = 1.7
    x, y = regular_polygon(n, R, phase=0.3, center=(0.4, -0.2))
    area, cx, cy, j0 = polygon_mass_properties(x, y)
    area_ref = 0.5 * n * R * R * np.sin(2 * np.pi / n)
    # polar moment of a regular n-gon about its centre (sum of n isosceles
    # sector triangles): J = A R^2 (2 + cos(2 pi / n)) / 6
    j_ref = area_ref * R * R * (2 + np.cos(2 * np.pi / n)) / 6.0
    assert area == pytest.approx(area_ref, rel=1e-13)
    assert (cx, cy) == pytest.approx((0.4, -0.2), abs=1e-14)
    assert j0 == pytest.approx(j_ref, rel=1e-12)


def test_regular_polygon_tends_to_disc():
    R = 1.0
    x, y = regular_polygon(2000, R)
    _, _, _, j0 = polygon_mass_properties(x, y)
    assert j0 == pytest.approx(np.pi * R**4 / 2, rel=1e-5)


def test_triangle():
    p = np.array([[0.2, 0.1], [2.0, 0.5], [0.7, 1.9]])
    area, cx, cy, j0 = polygon_mass_properties(p[:, 0], p[:, 1])
    area_ref, j_ref = triangle_polar_moment(p)
    assert area == pytest.approx(area_ref, rel=1e-14)
    assert (cx, cy) == pytest.approx(tuple(p.mean(axis=0)), rel=1e-14)
    assert j0 == pytest.approx(j_ref, rel=1e-13)


def test_clockwise_gives_negative_area():
    x, y = regular_polygon(6, 1.0)
    area, _, _, j0 = polygon_mass_properties(x[::-1], y[::-1])
    assert area < 0 and j0 < 0


def test_random_polygons_against_shapely():
    rng = np.random.default_rng(1)
    for _ in range(100):
        n = rng.integers(3, 12)
        x, y = random_polygon(rng, n, rng.uniform(0.5, 2), rng.uniform(0.5, 2), min_angle_deg=2.0)
        x = x + rng.uniform(-5, 5)
        y = y + rng.uniform(-5, 5)
        P = Polygon(np.column_stack([x, y]))
        area, cx, cy, j0 = polygon_mass_properties(x, y)
        assert area == pytest.approx(P.area, rel=1e-12)
        assert (cx, cy) == pytest.approx(P.centroid.coords[0], abs=1e-12)
        a_t, c_t, j_t = polar_moment_by_triangles(x, y)
        assert j0 == pytest.approx(j_t, rel=1e-10)


def test_mass_properties_rejects_degenerate_input():
    with pytest.raises(ValueError, match="at least 3"):
        polygon_mass_properties([0, 1], [0, 1])
    with pytest.raises(ValueError, match="zero area"):
        polygon_mass_properties([0, 1, 2], [0, 1, 2])
    with pytest.raises(ValueError, match="equal length"):
        polygon_mass_properties([0, 1, 2], [0, 1])


# ---------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------
def test_validate_accepts_polygons_up_to_its_limits_and_refuses_just_beyond():
    """The right isosceles triangle has edges 1, sqrt 2, 1 and angles 90, 45, 45 deg:
    it passes with the limits at exactly those values and fails just beyond each."""
    x, y = [0, 1, 0], [0, 0, 1]
    validate_polygon(x, y, min_edge=1.0 - 1e-12, min_angle_deg=45.0 - 1e-9)
    with pytest.raises(ValueError, match="edge 0 is too short"):
        validate_polygon(x, y, min_edge=1.001, min_angle_deg=15.0)
    with pytest.raises(ValueError, match="too sharp: interior angle 45"):
        validate_polygon(x, y, min_edge=0.5, min_angle_deg=45.01)
    # the regular heptagon: interior angles 128.57 deg, so flat beyond min_angle 51.43
    hx, hy = regular_polygon(7, 1.0)
    validate_polygon(hx, hy, min_edge=0.1, min_angle_deg=51.4)
    with pytest.raises(ValueError, match="too flat"):
        validate_polygon(hx, hy, min_edge=0.1, min_angle_deg=51.5)


@pytest.mark.parametrize(
    "x, y, pattern",
    [
        ([0, 1], [0, 0], "at least 3 corners"),
        ([0, 1, np.nan], [0, 0, 1], "finite"),
        # arrow head: corner 3 is reflex
        ([0, 2, 1, 1.2, 0.5], [0, 0, 0.5, 1.5, 1.0], "non-convex at corner"),
        # bow tie
        ([0, 1, 0, 1], [0, 1, 1, 0], "self-intersecting"),
        # pentagram
        (np.cos(np.pi / 2 + 4 * np.pi * np.arange(5) / 5), np.sin(np.pi / 2 + 4 * np.pi * np.arange(5) / 5),
         "self-intersecting"),
        # clockwise square
        ([0, 0, 1, 1], [0, 1, 1, 0], "not counter-clockwise"),
        # repeated corner
        ([0, 1, 1, 1, 0], [0, 0, 1, 1, 1], "coincide"),
        # short edge (0.05 < 0.1)
        ([0, 1, 1, 0.95, 0], [0, 0, 1, 1, 1], "too short"),
        # nearly straight corner (179 deg)
        ([0, 1, 2, 1], [0, -np.tan(np.radians(0.5)), 0, 1], "too flat"),
        # needle triangle (angle ~ 5.7 deg at the tip)
        ([0, 1, 0], [0, 0.05, 0.1], "too sharp"),
    ],
)
def test_validate_rejects(x, y, pattern):
    with pytest.raises(ValueError, match=pattern) as err:
        validate_polygon(np.asarray(x, float), np.asarray(y, float), min_edge=0.1,
                         min_angle_deg=15.0, name="particle 42")
    assert "particle 42" in str(err.value)


def test_validate_messages_name_values_and_limits():
    with pytest.raises(ValueError, match=r"length 0\.05 < minimum allowed 0\.1"):
        validate_polygon(np.array([0, 1, 1, 0.95, 0.0]), np.array([0, 0, 1, 1, 1.0]), 0.1, 15.0)
    with pytest.raises(ValueError, match=r"interior angle 179 deg > maximum allowed 165 deg"):
        validate_polygon(np.array([0, 1, 2, 1.0]), np.array([0, -np.tan(np.radians(0.5)), 0, 1]),
                         0.1, 15.0)


def test_validate_rejects_bad_limits():
    x, y = regular_polygon(5, 1.0)
    with pytest.raises(ValueError, match="min_angle_deg"):
        validate_polygon(x, y, 0.1, 70.0)
    with pytest.raises(ValueError, match="min_edge"):
        validate_polygon(x, y, -1.0, 10.0)


# ---------------------------------------------------------------------------
# generation
# ---------------------------------------------------------------------------
def test_random_polygon_lies_on_the_ellipse_unrotated():
    rng = np.random.default_rng(3)
    a, b = 2.0e-3, 3.5e-3
    for n in (6, 7, 8):
        x, y = random_polygon(rng, n, a, b, rotation=0.0)
        s = 1e-3  # scale to order one for a well-conditioned fit
        axes, resid, vec = conic_semi_axes(x / s, y / s)
        assert resid < 1e-10
        # with zero rotation the principal axes are x and y: a along x
        ix = int(np.argmax(np.abs(vec[0])))
        assert axes[ix] * s == pytest.approx(a, rel=1e-8)
        assert axes[1 - ix] * s == pytest.approx(b, rel=1e-8)
        assert abs(vec[1, ix]) < 1e-6
        _, cx, cy, _ = polygon_mass_properties(x, y)
        assert abs(cx) < 1e-18 and abs(cy) < 1e-18


def test_random_polygon_jitter_zero_is_equiangular_on_the_ellipse():
    rng = np.random.default_rng(4)
    x, y = random_polygon(rng, 6, 1.0, 1.0, jitter=0.0, rotation=0.0)
    # a circle with equal angles: regular hexagon of circumradius 1
    r = np.hypot(x, y)
    np.testing.assert_allclose(r, 1.0, rtol=1e-12)


def test_random_polygon_impossible_constraints():
    rng = np.random.default_rng(5)
    with pytest.raises(ValueError, match="no valid 64-gon"):
        random_polygon(rng, 64, 1.0, 1.0, min_edge_fraction=0.4, max_tries=20)
    with pytest.raises(ValueError, match="n_corners"):
        random_polygon(rng, 2, 1.0, 1.0)
    with pytest.raises(ValueError, match="jitter"):
        random_polygon(rng, 6, 1.0, 1.0, jitter=1.5)


@pytest.fixture(scope="module")
def shapes():
    return make_shapes(np.random.default_rng(11), 400)


def test_make_shapes_layout(shapes):
    sh = shapes
    assert isinstance(sh, Shapes)
    assert sh.n == 400
    assert sh.node_count.dtype == np.int64 and sh.node_offset.dtype == np.int64
    assert sh.node_offset[0] == 0
    np.testing.assert_array_equal(np.diff(sh.node_offset), sh.node_count)
    assert sh.node_x.shape == (sh.node_offset[-1],) == sh.node_y.shape
    for arr in (sh.node_x, sh.node_y, sh.area, sh.mass, sh.inertia, sh.radius, sh.inradius):
        assert arr.dtype == np.float64 and arr.flags.c_contiguous


def test_make_shapes_follows_the_paper_recipe(shapes):
    sh = shapes
    # corner numbers uniform in 6..8
    assert sh.node_count.min() == 6 and sh.node_count.max() == 8
    counts = np.bincount(sh.node_count)[6:]
    assert np.all(counts > 100)
    # semi-axes within +-30 % of 3.4 mm, independently uniform
    for ax in (sh.semi_a, sh.semi_b):
        assert ax.min() >= 0.7 * 3.4e-3 and ax.max() <= 1.3 * 3.4e-3
        assert ax.mean() == pytest.approx(3.4e-3, rel=0.03)
        assert ax.min() < 0.75 * 3.4e-3 and ax.max() > 1.25 * 3.4e-3
    assert abs(np.corrcoef(sh.semi_a, sh.semi_b)[0, 1]) < 0.15


def test_make_shapes_corners_lie_on_their_ellipse(shapes):
    sh = shapes
    s = 3.4e-3
    for i in range(0, sh.n, 5):
        x, y = sh.corners(i)
        axes, resid, _ = conic_semi_axes(x / s, y / s)
        assert resid < 1e-9
        np.testing.assert_allclose(np.sort(axes * s), np.sort([sh.semi_a[i], sh.semi_b[i]]),
                                   rtol=1e-7)


def test_make_shapes_polygons_are_valid(shapes):
    sh = shapes
    for i in range(sh.n):
        x, y = sh.corners(i)
        P = Polygon(np.column_stack([x, y]))
        assert P.is_valid and P.exterior.is_ccw
        assert P.convex_hull.area == pytest.approx(P.area, rel=1e-12)
        validate_polygon(x, y, 0.1 * 2 * min(sh.semi_a[i], sh.semi_b[i]), 15.0)
        # body frame: centroid at the origin
        assert np.hypot(*P.centroid.coords[0]) < 1e-12 * sh.radius[i]
        assert sh.area[i] == pytest.approx(P.area, rel=1e-12)
        assert sh.radius[i] == pytest.approx(np.hypot(x, y).max(), rel=1e-14)
        assert sh.inradius[i] == pytest.approx(P.exterior.distance(Point(0, 0)), rel=1e-9)
        assert 0 < sh.inradius[i] < sh.radius[i]


def test_make_shapes_mass_and_inertia(shapes):
    sh = shapes
    rho = 2500.0
    np.testing.assert_allclose(sh.mass, rho * sh.area, rtol=1e-15)
    for i in range(0, sh.n, 10):
        _, _, j_t = polar_moment_by_triangles(*sh.corners(i))
        assert sh.inertia[i] == pytest.approx(rho * j_t, rel=1e-10)


def test_make_shapes_is_reproducible():
    a = make_shapes(np.random.default_rng(5), 20)
    b = make_shapes(5, 20)
    np.testing.assert_array_equal(a.node_x, b.node_x)
    np.testing.assert_array_equal(a.node_count, b.node_count)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(corners_min=2), "corners_min"),
        (dict(corners_min=7, corners_max=6), "corners_max"),
        (dict(corners_max=100), "corners_max"),
        (dict(semi_axis_spread=1.0), "semi_axis_spread"),
        (dict(semi_axis_spread=-0.1), "semi_axis_spread"),
        (dict(density=0.0), "density"),
        (dict(density=-5.0), "density"),
        (dict(semi_axis_mean=0.0), "semi_axis_mean"),
        (dict(semi_axis_mean=np.inf), "semi_axis_mean"),
        (dict(min_edge_fraction=0.5), "min_edge_fraction"),
        (dict(min_angle_deg=60.0), "min_angle_deg"),
        (dict(n=-1), "n ="),
        (dict(n=2.5), "n must be an integer"),
    ],
)
def test_make_shapes_rejects_bad_arguments(kwargs, name):
    kw = dict(n=3)
    kw.update(kwargs)
    with pytest.raises(ValueError, match=name) as err:
        make_shapes(np.random.default_rng(0), **kw)
    if "range" in str(err.value):
        assert "allowed range" in str(err.value)


def test_make_shapes_regular_hexagon_inertia():
    # a single regular polygon through shapes_from_nodes
    R = 2e-3
    x, y = regular_polygon(6, R, phase=0.1)
    sh = shapes_from_nodes(np.array([6]), x, y, density=1000.0)
    area_ref = 0.5 * 6 * R * R * np.sin(np.pi / 3)
    j_ref = area_ref * R * R * (2 + np.cos(np.pi / 3)) / 6.0
    assert sh.inertia[0] == pytest.approx(1000.0 * j_ref, rel=1e-12)
    assert sh.radius[0] == pytest.approx(R, rel=1e-14)
    assert sh.inradius[0] == pytest.approx(R * np.cos(np.pi / 6), rel=1e-12)


# ---------------------------------------------------------------------------
# loading from corner arrays
# ---------------------------------------------------------------------------
def test_shapes_from_nodes_round_trip(shapes):
    sh = shapes
    re = shapes_from_nodes(sh.node_count, sh.node_x, sh.node_y, density=2500.0)
    np.testing.assert_array_equal(re.node_offset, sh.node_offset)
    np.testing.assert_allclose(re.area, sh.area, rtol=1e-14)
    np.testing.assert_allclose(re.inertia, sh.inertia, rtol=1e-13)
    np.testing.assert_allclose(re.radius, sh.radius, rtol=1e-15)
    np.testing.assert_allclose(re.inradius, sh.inradius, rtol=1e-13)
    assert re.semi_a is None


def _centred(x, y):
    _, cx, cy, _ = polygon_mass_properties(np.asarray(x, float), np.asarray(y, float))
    return np.asarray(x, float) - cx, np.asarray(y, float) - cy


def test_shapes_from_nodes_rejects_bad_polygons():
    good_x, good_y = regular_polygon(5, 1.0)
    arrow_x, arrow_y = _centred([0, 2, 1, 1.2, 0.5], [0, 0, 0.5, 1.5, 1.0])
    with pytest.raises(ValueError, match="particle 1: non-convex"):
        shapes_from_nodes(np.array([5, 5]), np.r_[good_x, arrow_x], np.r_[good_y, arrow_y], 1.0)
    bow_x = np.array([-0.5, 0.5, -0.5, 0.5])
    bow_y = np.array([-0.5, 0.5, 0.5, -0.5])
    with pytest.raises(ValueError, match="particle 2: self-intersecting"):
        shapes_from_nodes(np.array([5, 5, 4]), np.r_[good_x, good_x, bow_x],
                          np.r_[good_y, good_y, bow_y], 1.0)
    with pytest.raises(ValueError, match="particle 0: corners are not counter-clockwise"):
        shapes_from_nodes(np.array([5]), good_x[::-1], good_y[::-1], 1.0)
    with pytest.raises(ValueError, match="particle 0: corners are not relative to the centroid"):
        shapes_from_nodes(np.array([5]), good_x + 0.1, good_y, 1.0)
    with pytest.raises(ValueError, match="sum\\(node_count\\)"):
        shapes_from_nodes(np.array([5, 5]), good_x, good_y, 1.0)
    with pytest.raises(ValueError, match="particle 0: node_count = 2"):
        shapes_from_nodes(np.array([2]), good_x[:2], good_y[:2], 1.0)
    with pytest.raises(ValueError, match="density"):
        shapes_from_nodes(np.array([5]), good_x, good_y, 0.0)
