"""The shapes of a pile: body-frame corners and mass properties of N particles.

:class:`Shapes` holds the polygons of all particles as ragged (CSR) arrays
with their mass properties; :func:`make_shapes` draws them by the recipe of
Roul, Schinner & Kassner (2010), Section 3.1 (corner number and semi-axes
per particle, each polygon by :func:`sim.polygon.random_polygon`), or as
elongated polygons of a set aspect ratio (``particles.aspect_ratio``), and
:func:`shapes_from_nodes` rebuilds them from stored corners.  The maths and
validation of one polygon are in :mod:`sim.polygon`.

All corner coordinates are stored in the *body frame*: counter-clockwise,
relative to the particle's centre of mass, at orientation ``theta = 0``.
A body-frame corner ``(X, Y)`` of a particle at position ``(x, y)`` and
orientation ``theta`` is at ``(x + X cos(theta) - Y sin(theta),
y + X sin(theta) + Y cos(theta))`` in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import ModelParams, ParticleParams, setting_bounds, setting_schema
from .polygon import (
    as_corner_arrays,
    check_int,
    check_range,
    polygon_mass_properties,
    polygon_radii,
    random_polygon,
    validate_polygon,
)

__all__ = [
    "Shapes",
    "make_shapes",
    "shapes_by_settings",
    "shapes_from_nodes",
]


def _setting_range(section, name):
    """``lo, hi, lo_open, hi_open`` of the setting ``section.name`` (from the schema)."""
    b = setting_bounds(setting_schema(section, name))
    return b["lo"], b["hi"], b["lo_open"], b["hi_open"]


def _int_range(section, name):
    """Closed ``lo, hi`` of the integer setting ``section.name`` (from the schema)."""
    lo, hi, lo_open, hi_open = _setting_range(section, name)
    return (None if lo is None else lo + lo_open), (None if hi is None else hi - hi_open)


# ---------------------------------------------------------------------------
# structure of arrays
# ---------------------------------------------------------------------------
@dataclass
class Shapes:
    """Shapes and mass properties of ``N`` polygonal particles (structure of arrays).

    The corners of particle ``i`` are
    ``node_x[node_offset[i]:node_offset[i + 1]]`` (and ``node_y``), in the body
    frame: counter-clockwise, relative to the centre of mass, at orientation
    ``theta = 0``.

    Attributes
    ----------
    node_count : numpy.ndarray of int64, shape (N,)
        Number of corners of each particle.
    node_offset : numpy.ndarray of int64, shape (N + 1,)
        CSR offsets into the corner arrays; ``node_offset[0] == 0``.
    node_x, node_y : numpy.ndarray of float64, shape (node_offset[-1],)
        Body-frame corner coordinates [m].
    area : numpy.ndarray of float64, shape (N,)
        Polygon area [m^2].
    mass : numpy.ndarray of float64, shape (N,)
        ``density * area`` [kg per m of depth for a 2D areal density].
    inertia : numpy.ndarray of float64, shape (N,)
        Moment of inertia about the centre of mass, ``density * j0``.
    radius : numpy.ndarray of float64, shape (N,)
        Circumradius about the centre of mass: the largest corner distance.
    inradius : numpy.ndarray of float64, shape (N,)
        Smallest distance from the centre of mass to an edge line.
    semi_a, semi_b : numpy.ndarray of float64, shape (N,), or None
        Semi-axes of the generating ellipse (``None`` when the shapes were
        loaded from corner coordinates).
    """

    node_count: np.ndarray
    node_offset: np.ndarray
    node_x: np.ndarray
    node_y: np.ndarray
    area: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    radius: np.ndarray
    inradius: np.ndarray
    semi_a: np.ndarray | None = None
    semi_b: np.ndarray | None = None

    @property
    def n(self):
        """int: Number of particles."""
        return int(self.node_count.shape[0])

    def corners(self, i):
        """Body-frame corners of particle ``i``.

        Parameters
        ----------
        i : int
            Particle index.

        Returns
        -------
        x, y : numpy.ndarray
            Views into :attr:`node_x`, :attr:`node_y`.
        """
        s = slice(int(self.node_offset[i]), int(self.node_offset[i + 1]))
        return self.node_x[s], self.node_y[s]


def _build(counts, xs, ys, density):
    """Assemble a :class:`Shapes` from per-particle corner arrays (centred)."""
    n = len(counts)
    node_count = np.asarray(counts, dtype=np.int64).reshape(n)
    node_offset = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(node_count, out=node_offset[1:])
    area = np.empty(n)
    inertia = np.empty(n)
    radius = np.empty(n)
    inradius = np.empty(n)
    for i in range(n):
        A, _, _, j0 = polygon_mass_properties(xs[i], ys[i])
        area[i] = A
        inertia[i] = density * j0
        radius[i], inradius[i] = polygon_radii(xs[i], ys[i])
    node_x = np.concatenate(xs) if n else np.empty(0)
    node_y = np.concatenate(ys) if n else np.empty(0)
    return Shapes(
        node_count=node_count,
        node_offset=node_offset,
        node_x=np.ascontiguousarray(node_x, dtype=np.float64),
        node_y=np.ascontiguousarray(node_y, dtype=np.float64),
        area=area,
        mass=density * area,
        inertia=inertia,
        radius=radius,
        inradius=inradius,
    )


def make_shapes(
    rng,
    n,
    corners_min=ParticleParams.corners_min,
    corners_max=ParticleParams.corners_max,
    semi_axis_mean=ParticleParams.semi_axis_mean,
    semi_axis_spread=ParticleParams.semi_axis_spread,
    density=ModelParams.density,
    min_edge_fraction=ParticleParams.min_edge_fraction,
    min_angle_deg=ParticleParams.min_angle_deg,
    aspect_ratio=ParticleParams.aspect_ratio,
    jitter=0.5,
):
    """Generate ``n`` random particles following the paper's recipe (Section 3.1).

    For each particle the corner number is a uniform integer in
    ``[corners_min, corners_max]`` and both semi-axes are drawn independently
    and uniformly from ``semi_axis_mean * (1 +- semi_axis_spread)``; the
    polygon is then drawn by :func:`random_polygon`.

    With ``aspect_ratio = r`` the particles are elongated instead: one size
    ``s`` per particle, uniform in ``semi_axis_mean * (1 +- semi_axis_spread)``,
    gives the major semi-axis ``a = s sqrt(r)`` and the minor one
    ``b = s / sqrt(r)``, so that the ellipse has the aspect ``r`` and the
    area ``pi s^2`` of the circle of radius ``s``.

    The random stream, in this order: the ``n`` corner numbers, then ``n``
    uniforms for the first semi-axes (``aspect_ratio`` set: the sizes ``s``),
    then, only when ``aspect_ratio`` is None, ``n`` uniforms for the second
    semi-axes, then the polygons one after the other.  The default draw thus
    takes the same numbers as before the setting existed, and a draw with
    ``aspect_ratio`` set has the same corner numbers and, as sizes, the same
    first semi-axes as the default draw from the same generator state.

    The arguments named like settings of the configuration take their
    defaults and allowed ranges from ``sim/config.schema.yaml``
    (``particles.*`` and ``model.density``, see :mod:`sim.config`).

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Random source (an int is used as a seed for
        :func:`numpy.random.default_rng`).
    n : int
        Number of particles, ``>= 0``.
    corners_min, corners_max : int, optional
        Corner-number range, ``corners_min <= corners_max``, each within the
        bounds of ``particles.corners_min`` / ``corners_max``.
    semi_axis_mean : float, optional
        Mean semi-axis [m] (``particles.semi_axis_mean``).
    semi_axis_spread : float, optional
        Relative half-width of the semi-axis distribution
        (``particles.semi_axis_spread``).
    density : float, optional
        Areal mass density [kg/m^2] (``model.density``).
    min_edge_fraction, min_angle_deg : float, optional
        ``particles.min_edge_fraction`` / ``min_angle_deg``, passed to
        :func:`random_polygon`.
    aspect_ratio : float or None, optional
        Ratio of the major to the minor semi-axis of every particle's ellipse
        (``particles.aspect_ratio``); None (the default): both semi-axes drawn
        independently, as in the paper.
    jitter : float, optional
        Passed to :func:`random_polygon`.

    Returns
    -------
    Shapes
        With :attr:`Shapes.semi_a`, :attr:`Shapes.semi_b` set (with
        ``aspect_ratio``: the major and the minor semi-axis).

    Raises
    ------
    ValueError
        Naming the argument, its value and the allowed range.
    """
    n = check_int("n", n, 0)
    corners_min = check_int("corners_min", corners_min, *_int_range("particles", "corners_min"))
    lo, hi = _int_range("particles", "corners_max")
    corners_max = check_int("corners_max", corners_max, max(lo, corners_min), hi)
    semi_axis_mean = check_range("semi_axis_mean", semi_axis_mean,
                                  *_setting_range("particles", "semi_axis_mean"))
    semi_axis_spread = check_range("semi_axis_spread", semi_axis_spread,
                                    *_setting_range("particles", "semi_axis_spread"))
    density = check_range("density", density, *_setting_range("model", "density"))
    min_edge_fraction = check_range("min_edge_fraction", min_edge_fraction,
                                     *_setting_range("particles", "min_edge_fraction"))
    min_angle_deg = check_range("min_angle_deg", min_angle_deg,
                                 *_setting_range("particles", "min_angle_deg"))
    if aspect_ratio is not None:
        aspect_ratio = check_range("aspect_ratio", aspect_ratio,
                                   *_setting_range("particles", "aspect_ratio"))
    jitter = check_range("jitter", jitter, 0.0, 1.0)
    rng = np.random.default_rng(rng)

    counts = rng.integers(corners_min, corners_max + 1, size=n)
    lo = semi_axis_mean * (1.0 - semi_axis_spread)
    hi = semi_axis_mean * (1.0 + semi_axis_spread)
    semi_a = rng.uniform(lo, hi, size=n)
    if aspect_ratio is None:
        semi_b = rng.uniform(lo, hi, size=n)
    else:
        stretch = np.sqrt(aspect_ratio)
        semi_a, semi_b = semi_a * stretch, semi_a / stretch
    xs, ys = [], []
    for i in range(n):
        x, y = random_polygon(
            rng,
            int(counts[i]),
            semi_a[i],
            semi_b[i],
            jitter=jitter,
            min_edge_fraction=min_edge_fraction,
            min_angle_deg=min_angle_deg,
        )
        xs.append(x)
        ys.append(y)
    shapes = _build(counts, xs, ys, density)
    shapes.semi_a = semi_a
    shapes.semi_b = semi_b
    return shapes


def shapes_by_settings(rng, n, particles: ParticleParams, density):
    """``n`` polygons drawn from ``rng`` by :func:`make_shapes` with every setting of
    ``particles`` (a pile's ``particles`` section) at the given ``density``: the one
    place that turns the settings into arguments, for the pour and the bench alike."""
    return make_shapes(rng, n, particles.corners_min, particles.corners_max, particles.semi_axis_mean,
                       particles.semi_axis_spread, density, particles.min_edge_fraction,
                       particles.min_angle_deg, particles.aspect_ratio)


def shapes_from_nodes(
    node_count,
    node_x,
    node_y,
    density,
    min_edge_fraction=1e-3,
    min_angle_deg=1.0,
    centroid_tol=1e-9,
):
    """Rebuild :class:`Shapes` from stored body-frame corners (e.g. a state file).

    Every polygon is validated with :func:`validate_polygon` (using
    ``min_edge = min_edge_fraction * 2 * circumradius``; the defaults are
    lenient because they only guard against corrupt input) and its mass
    properties are recomputed.  The corners must already be relative to the
    centroid: shifting them silently would move the particle, so a polygon
    whose centroid is farther than ``centroid_tol * circumradius`` from the
    origin is rejected.

    Parameters
    ----------
    node_count : array_like of int, shape (N,)
        Corners per particle (each ``>= 3``).
    node_x, node_y : array_like of float, shape (sum(node_count),)
        Body-frame corners, particle after particle.
    density : float
        Areal mass density, ``> 0``.
    min_edge_fraction : float, optional
        In ``[0, 0.5)``.
    min_angle_deg : float, optional
        In ``[0, 60)``.
    centroid_tol : float, optional
        Allowed centroid offset relative to the circumradius, ``>= 0``.

    Returns
    -------
    Shapes
        With ``semi_a = semi_b = None``.

    Raises
    ------
    ValueError
        For inconsistent array sizes, bad arguments, or an invalid polygon
        (the message names the particle index).
    """
    density = check_range("density", density, 0.0, None, lo_open=True)
    min_edge_fraction = check_range("min_edge_fraction", min_edge_fraction, 0.0, 0.5, hi_open=True)
    min_angle_deg = check_range("min_angle_deg", min_angle_deg, 0.0, 60.0, hi_open=True)
    centroid_tol = check_range("centroid_tol", centroid_tol, 0.0, None)
    counts = np.asarray(node_count)
    if counts.ndim != 1 or (counts.size and not np.issubdtype(counts.dtype, np.integer)):
        raise ValueError(f"node_count must be a 1-D integer array, got {counts.dtype} {counts.shape}")
    if np.any(counts < 3):
        i = int(np.argmax(counts < 3))
        raise ValueError(f"particle {i}: node_count = {int(counts[i])} < 3 corners")
    node_x, node_y = as_corner_arrays(node_x, node_y, "node_x/node_y")
    total = int(counts.sum())
    if node_x.shape[0] != total:
        raise ValueError(
            f"node_x has {node_x.shape[0]} entries but sum(node_count) = {total}"
        )
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    xs, ys = [], []
    for i in range(counts.shape[0]):
        x = node_x[offsets[i]:offsets[i + 1]].copy()
        y = node_y[offsets[i]:offsets[i + 1]].copy()
        name = f"particle {i}"
        r = float(np.max(np.hypot(x, y))) if np.all(np.isfinite(x) & np.isfinite(y)) else np.nan
        validate_polygon(x, y, min_edge_fraction * 2.0 * r if np.isfinite(r) else 0.0,
                         min_angle_deg, name=name)
        _, cx, cy, _ = polygon_mass_properties(x, y)
        off = float(np.hypot(cx, cy))
        if off > centroid_tol * r:
            raise ValueError(
                f"{name}: corners are not relative to the centroid: centroid at "
                f"({cx:.6g}, {cy:.6g}), offset {off:.6g} > allowed {centroid_tol * r:.6g}"
            )
        xs.append(x)
        ys.append(y)
    return _build(counts, xs, ys, density)
