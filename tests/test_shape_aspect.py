"""Elongated particles (``particles.aspect_ratio``, issue 44 item 4).

With ``aspect_ratio = r`` every polygon is inscribed in an ellipse of
semi-axes ``a = s sqrt(r)`` and ``b = s / sqrt(r)``, ``s`` drawn as the
paper's semi-axis.  The geometry proved here:

* the corners of each polygon lie on such an ellipse, found by fitting a conic
  through them (five unknowns, six to eight corners);
* such a polygon is the affine image ``diag(a, b)`` of the polygon inscribed
  in the unit circle at the same eccentric angles ``phi_k``; an affine map
  multiplies the area by ``det = a b = s^2`` and turns the second-moment
  tensor ``M0`` into ``a b A M0 A``.  So the area is ``s^2`` times the
  circle polygon's ``(1/2) sum sin(dphi)``, independent of ``r`` (the mean
  size is kept), and the measured aspect ``sqrt(lambda_max / lambda_min)``
  lies within ``[r / alpha0, r alpha0]``, ``alpha0`` the aspect of the
  circle polygon (which is 1 for equal angles: then the aspect is ``r``
  exactly, for any corner count);
* with the default null the draw is the one of the code before the setting:
  a committed draw (tests/data/default_shapes.json, written by
  tests/default_shapes.py at the commit before) and the settings digest of a
  default pour.
"""

import copy
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from sim.config import ConfigError, ParticleParams, SimConfig
from sim.io import pour_digest
from sim.shapes import make_shapes

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from workflow.validation import ConfigurationError, validate_config  # noqa: E402

FIXTURE = REPO / "tests" / "data" / "default_shapes.json"

#: Particles per statistic: the standard error of a mean aspect is then about
#: 0.1 % of r, of a mean area about 0.8 % (the sizes spread by +-30 %).
N = 2000


def second_moments(x, y):
    """Second-moment tensor of area about the centroid of a CCW polygon.

    The standard polygon formulas (triangles from the origin), written here
    apart from sim.polygon: ``int x^2``, ``int y^2``, ``int x y`` over the area.

    Returns
    -------
    ndarray, shape (2, 2)
        ``[[int x^2, int x y], [int x y, int y^2]]`` about the centroid.
    """
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    w = x * yn - xn * y
    area = w.sum() / 2
    cx = ((x + xn) * w).sum() / (6 * area)
    cy = ((y + yn) * w).sum() / (6 * area)
    ixx = (w * (x * x + x * xn + xn * xn)).sum() / 12 - area * cx * cx
    iyy = (w * (y * y + y * yn + yn * yn)).sum() / 12 - area * cy * cy
    ixy = (w * (x * yn + 2 * x * y + 2 * xn * yn + xn * y)).sum() / 24 - area * cx * cy
    return np.array([[ixx, ixy], [ixy, iyy]])


def aspect(x, y):
    """``sqrt(lambda_max / lambda_min)`` of the polygon's second-moment tensor:
    ``a / b`` for an ellipse of semi-axes ``a >= b``."""
    lam = np.linalg.eigvalsh(second_moments(x, y))
    return math.sqrt(lam[1] / lam[0])


def fit_ellipse(x, y):
    """The conic ``q_xx x^2 + q_xy x y + q_yy y^2 + l_x x + l_y y = 1`` through
    the corners, by least squares.

    Returns
    -------
    semi : ndarray, shape (2,)
        Its semi-axes, major first.
    centre : ndarray, shape (2,)
    axes : ndarray, shape (2, 2)
        Unit vectors of the major and the minor axis as columns (a rotation).
    misfit : float
        Largest ``|(p - c)^T Q (p - c) / k - 1|`` over the corners: 0 when
        they all lie on the ellipse.
    """
    scale = float(np.max(np.hypot(x, y)))
    u, v = x / scale, y / scale
    terms = np.column_stack([u * u, u * v, v * v, u, v])
    p = np.linalg.lstsq(terms, np.ones_like(u), rcond=None)[0]
    q = np.array([[p[0], p[1] / 2], [p[1] / 2, p[2]]])
    centre = -np.linalg.solve(q, p[3:]) / 2
    k = 1 + centre @ q @ centre
    d = np.column_stack([u, v]) - centre
    misfit = float(np.max(np.abs(np.einsum("ni,ij,nj->n", d, q, d) / k - 1)))
    lam, axes = np.linalg.eigh(q / k)          # ascending: the major axis first
    axes[:, 1] *= np.sign(np.linalg.det(axes))  # a rotation: the corners stay counter-clockwise
    return scale / np.sqrt(lam), scale * centre, axes, misfit


def circle_polygon(x, y):
    """The polygon inscribed in the unit circle at the eccentric angles of the
    corners on their fitted ellipse (the ellipse mapped onto the unit circle)."""
    semi, centre, axes, _ = fit_ellipse(x, y)
    local = (np.column_stack([x, y]) - centre) @ axes / semi
    phi = np.arctan2(local[:, 1], local[:, 0])
    return np.cos(phi), np.sin(phi), phi


def polygons(shapes):
    """The corner arrays of every particle."""
    return [shapes.corners(i) for i in range(shapes.n)]


def draw(aspect_ratio, n=N, seed=44, **kwargs):
    """``n`` shapes of the given aspect ratio, the other settings at their defaults."""
    return make_shapes(np.random.default_rng(seed), n, aspect_ratio=aspect_ratio, **kwargs)


# --- the default: the draw of the code before the setting ----------------------------

def test_the_default_draw_is_the_draw_before_the_setting():
    """Corner counts, semi-axes and the stream after the draw equal the committed
    draw bit for bit (integers and uniforms are exact arithmetic on the
    generator's bits, on any host); the corners, which pass through sin and cos,
    within 1e-12 of a semi-axis (another libm may round a last bit otherwise,
    while a draw that took one more or one less random number moves them by
    their whole size).  And an explicit null is the default, bit for bit."""
    fixture = json.loads(FIXTURE.read_text())
    rng = np.random.default_rng(fixture["seed"])
    shapes = make_shapes(rng, fixture["n"])
    assert shapes.node_count.tolist() == fixture["node_count"]
    assert shapes.semi_a.tolist() == fixture["semi_a"]
    assert shapes.semi_b.tolist() == fixture["semi_b"]
    assert int(rng.integers(2**62)) == fixture["next_integer"]
    size = ParticleParams().semi_axis_mean
    for coordinate in ("node_x", "node_y"):
        np.testing.assert_allclose(getattr(shapes, coordinate), fixture[coordinate], rtol=0,
                                   atol=1e-12 * size)

    explicit = make_shapes(np.random.default_rng(fixture["seed"]), fixture["n"], aspect_ratio=None)
    for name in ("node_count", "node_x", "node_y", "semi_a", "semi_b", "area", "inertia"):
        assert np.array_equal(getattr(explicit, name), getattr(shapes, name)), name


def test_the_default_keeps_the_settings_digest_of_the_piles():
    """A pour's settings before the setting existed had no aspect_ratio key: at
    its default it leaves the digest as it was, and set it makes another pile."""
    settings = SimConfig().to_dict()
    assert settings["particles"]["aspect_ratio"] is None
    before = copy.deepcopy(settings)
    del before["particles"]["aspect_ratio"]
    assert pour_digest(settings) == pour_digest(before)
    for r in (1.0, 2.0):
        elongated = SimConfig.from_dict({"particles": {"aspect_ratio": r}}).to_dict()
        assert pour_digest(elongated) != pour_digest(settings), r


# --- geometry of the elongated polygons -------------------------------------------------

@pytest.mark.parametrize("r", [1.0, 1.5, 2.5, 3.0])
def test_every_corner_lies_on_the_ellipse_of_its_aspect(r):
    """A conic through the body-frame corners of each polygon passes through all
    of them and is the ellipse of semi-axes s sqrt(r) and s / sqrt(r), with s
    within the paper's semi_axis_mean * (1 +- semi_axis_spread)."""
    p = ParticleParams()
    shapes = draw(r, n=300)
    s_lo = p.semi_axis_mean * (1 - p.semi_axis_spread)
    s_hi = p.semi_axis_mean * (1 + p.semi_axis_spread)
    for i, (x, y) in enumerate(polygons(shapes)):
        semi, _, _, misfit = fit_ellipse(x, y)
        assert misfit < 1e-9, (i, misfit)
        assert semi[0] / semi[1] == pytest.approx(r, rel=1e-7), i
        s = math.sqrt(semi[0] * semi[1])
        assert s_lo * (1 - 1e-9) <= s <= s_hi * (1 + 1e-9), i
        np.testing.assert_allclose(semi, [shapes.semi_a[i], shapes.semi_b[i]], rtol=1e-7)


def test_the_sizes_are_the_default_draws_first_semi_axes():
    """The random stream: with the setting the corner counts and the sizes s are
    those the default draw takes from the same generator (its first semi-axes),
    so the size distribution is the paper's."""
    default = draw(None, n=200)
    elongated = draw(2.0, n=200)
    assert np.array_equal(elongated.node_count, default.node_count)
    sizes = np.sqrt(elongated.semi_a * elongated.semi_b)
    np.testing.assert_allclose(sizes, default.semi_a, rtol=1e-15)


@pytest.mark.parametrize("r", [1.0, 1.5, 2.0, 2.5, 3.0])
def test_at_equal_angles_the_aspect_is_that_of_the_ellipse(r):
    """Without jitter each polygon is the affine image of a regular polygon, whose
    second-moment tensor is isotropic: its aspect is r exactly, for 6, 7 or 8
    corners alike."""
    shapes = draw(r, n=100, jitter=0.0)
    measured = np.array([aspect(x, y) for x, y in polygons(shapes)])
    np.testing.assert_allclose(measured, r, rtol=1e-9)


@pytest.mark.parametrize("r", [1.5, 2.0, 2.5])
def test_the_mean_aspect_is_the_set_one(r):
    """With the jitter of the corner angles a particle's circle polygon has a
    second-moment tensor mu (1 + D), D traceless with eigenvalues +-d and
    aspect alpha0 = sqrt((1 + d) / (1 - d)) >= 1.  Its own aspect then lies in
    [r / alpha0, r alpha0] (the singular values of diag(a, b) (1 + D)^(1/2)),
    and, D pointing in no preferred direction of the ellipse (the angle grid
    of 6 to 8 corners and the jitter are symmetric), it is on average
    r (1 + <d^2> r^2 / (2 (r^2 - 1))): the first order and the anisotropic
    part of the second average out, the third is of order d^3 ~ 1e-4
    (d ~ 0.05).  Tolerance: four standard errors of the
    mean aspect (about 0.35 % of r), while the second-order excess is 0.2 to
    0.3 %."""
    shapes = draw(r)
    measured, alpha0 = [], []
    for x, y in polygons(shapes):
        measured.append(aspect(x, y))
        alpha0.append(aspect(*circle_polygon(x, y)[:2]))
    measured, alpha0 = np.array(measured), np.array(alpha0)
    assert np.all(measured >= r / alpha0 * (1 - 1e-9))
    assert np.all(measured <= r * alpha0 * (1 + 1e-9))
    d = (alpha0**2 - 1) / (alpha0**2 + 1)
    expected = r * (1 + np.mean(d**2) * r**2 / (2 * (r**2 - 1)))
    error = measured.std() / math.sqrt(shapes.n)
    assert abs(measured.mean() - expected) <= 4 * error, (measured.mean(), expected, error)


def area_fraction(n):
    """Mean area of a polygon of ``n`` corners drawn in the unit circle over pi:
    the corners at ``2 pi k / n + c u_k``, ``u_k`` uniform in [-1, 1] and
    ``c = pi / (2 n)`` (half a sector of jitter), make the gaps
    ``2 pi / n + c (u_(k+1) - u_k)``, and ``E cos(c (u - u')) = (sin c / c)^2``."""
    c = np.pi / (2 * n)
    return n * np.sin(2 * np.pi / n) / (2 * np.pi) * (np.sin(c) / c) ** 2


@pytest.mark.parametrize("r", [1.0, 1.5, 2.0, 2.5, 3.0])
def test_the_area_is_that_of_the_size_whatever_the_aspect(r):
    """Each polygon's area is pi s^2 f, f = (1/2) sum sin(dphi) / pi the area
    fraction of its circle polygon (the affine map has determinant
    a b = s^2), whatever r.  Over many particles f averages to
    :func:`area_fraction` of their corner numbers, and with s uniform in
    m (1 +- w) the mean area is pi m^2 (1 + w^2 / 3) <f>: the same for every
    aspect, the mean size is kept.  Tolerance: four standard errors of each
    mean (up to r = 2.5; at 3 more than half the 8-gons are redrawn for flat
    corners, and the survivors have up to 0.08 % more area)."""
    p = ParticleParams()
    shapes = draw(r)
    s2 = shapes.semi_a * shapes.semi_b
    fraction = []
    for x, y in polygons(shapes):
        phi = np.sort(circle_polygon(x, y)[2])
        gaps = np.diff(np.append(phi, phi[0] + 2 * np.pi))
        fraction.append(np.sin(gaps).sum() / (2 * np.pi))
    np.testing.assert_allclose(shapes.area, np.pi * s2 * np.array(fraction), rtol=1e-9)
    if r > 2.5:
        return

    residual = shapes.area - np.pi * s2 * area_fraction(shapes.node_count)
    assert abs(residual.mean()) <= 4 * residual.std() / math.sqrt(shapes.n)
    n = np.arange(p.corners_min, p.corners_max + 1)
    mean_s2 = p.semi_axis_mean**2 * (1 + p.semi_axis_spread**2 / 3)
    expected = np.pi * mean_s2 * np.mean(area_fraction(n))
    error = shapes.area.std() / math.sqrt(shapes.n)
    assert abs(shapes.area.mean() - expected) <= 4 * error, (shapes.area.mean(), expected, error)


# --- refusals ------------------------------------------------------------------------------

@pytest.mark.parametrize("value", [0.5, 6, 3.5, "long"])
def test_a_bad_aspect_ratio_is_refused_in_one_line(value):
    """The simulator's settings, the workflow's validator and make_shapes each
    name the setting, the value and (for a number) the allowed range [1, 3]."""
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"particles": {"aspect_ratio": value}})
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"particles.aspect_ratio = {value!r}: must be")
    assert (">= 1 and <= 3" in text) if not isinstance(value, str) else "a number" in text

    config = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
    config.setdefault("particles", {})["aspect_ratio"] = value
    with pytest.raises(ConfigurationError) as err:
        validate_config(config)
    line = next(line for line in str(err.value).splitlines() if "particles.aspect_ratio" in line)
    bound = ">= 1 and <= 3" if isinstance(value, str) else \
        "minimum of 1" if value < 1 else "maximum of 3"
    assert str(value) in line and bound in line, line

    with pytest.raises(ValueError) as err:
        make_shapes(0, 1, aspect_ratio=value)
    assert str(err.value).startswith(f"aspect_ratio = {value!r} ")
    assert str(err.value).endswith("allowed range [1, 3]") and "\n" not in str(err.value)


def test_a_pile_and_the_bench_draw_with_the_setting():
    """The pour's and the bench's shapes (sim.shapes.shapes_by_settings) take
    particles.aspect_ratio: a pile poured at r = 2 is made of polygons of aspect 2."""
    from sim.numerics.bench import _shapes
    from sim.pour import pile_shapes

    cfg = SimConfig.from_dict({"particles": {"aspect_ratio": 2.0}, "pour": {"n_particles": 400}})
    for shapes in (pile_shapes(cfg, 7), _shapes(np.random.default_rng(7), 400, cfg.model, cfg.particles)):
        measured = np.array([aspect(x, y) for x, y in polygons(shapes)])
        # the corners' jitter spreads each polygon's aspect by a few per cent (the test above):
        # 400 polygons put their mean within 1 % of r
        assert measured.mean() == pytest.approx(2.0, rel=0.01)
    default = SimConfig.from_dict({"pour": {"n_particles": 400}})
    assert np.array_equal(pile_shapes(default, 7).node_x, make_shapes(np.random.default_rng([7, 0]), 400).node_x)
