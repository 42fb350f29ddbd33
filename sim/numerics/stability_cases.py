"""The catalogue of the stability suite: the setups of its cases.

Each case of :mod:`sim.numerics.stability` is a small :class:`Setup`, built
by a function of this module: :func:`packing` (twelve of the paper's
particles in a box; the stiffness cases, the jammed box, the friction and
damping variants), :func:`linear_spring` (a square between two walls, with
its stiffness and theoretical stability limit), and the extreme shapes and
loads of :func:`case_builders` (size ratio 1:20, aspect ratio 1:5, 3 and 32
corners, nearly degenerate shapes, impacts at 10 m/s, a deep overlap, a step
above the limit).  :data:`CASE_NAMES` lists the latter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..config import ModelParams
from ..engine import Simulation
from ..integrators import stability_limit
from ..shapes import make_shapes
from .polygons import centred, ellipse_polygon, rectangle, regular_polygon, shapes_of

#: Mean semi-axis of the paper's particles, m.
SIZE = 3.4e-3


@dataclass
class Setup:
    """Particles, their start states, the law and the bodies, before they are simulated.

    Attributes
    ----------
    shapes : sim.shapes.Shapes
    states : list of tuple
        ``(x, y, theta, vx, vy, omega)`` per particle.
    model : ModelParams
    gravity : tuple
    support : bool
    walls : tuple or None
    rotate : bool
    """

    shapes: object
    states: list
    model: ModelParams
    gravity: tuple = (0.0, -9.81)
    support: bool = True
    walls: tuple | None = None
    rotate: bool = True

    def simulation(self, dt=None):
        """The :class:`Simulation` with the particles placed.

        ``dt`` given: that step is used even above the stability limit (the
        largest-stable-step search needs it; the model's own ``dt`` rule is
        bypassed by setting the step before any particle is placed).
        """
        sim = Simulation(self.shapes, self.model, gravity=self.gravity, support=self.support,
                         walls=self.walls, rotate=self.rotate)
        if dt is not None:
            sim.dt = float(dt)
        for k, state in enumerate(self.states):
            sim.place(k, *state)
        return sim


def _box(polygons, spacing, columns, rng, speed=0.05, **model):
    """Polygons on a square lattice of ``spacing`` in a box on the support.

    Walls half a spacing beyond the outer columns; random orientations and
    velocities up to ``speed`` (m/s).  A spacing below the particles'
    diameters starts them compressed against each other and the walls.
    """
    n = len(polygons)
    width = columns * spacing
    states = []
    for k in range(n):
        row, col = divmod(k, columns)
        states.append((-0.5 * width + (col + 0.5) * spacing, (row + 0.5) * spacing,
                       rng.uniform(0, 2 * np.pi), *rng.uniform(-speed, speed, 2),
                       rng.uniform(-speed, speed) / spacing))
    return Setup(shapes_of(*polygons), states, ModelParams(**model),
                 walls=(-0.5 * width, 0.5 * width))


def _paper_polygons(n, seed):
    """``n`` of the paper's particles (6-8 corners, 3.4 mm ± 30 %)."""
    shapes = make_shapes(np.random.default_rng(seed), n)
    return [tuple(np.array(a) for a in shapes.corners(i)) for i in range(n)]


def packing(youngs_modulus=1.0e7, spacing=0.95, seed=1, **model):
    """Twelve paper particles, 4 columns, lattice ``spacing`` × mean circumdiameter."""
    polygons = _paper_polygons(12, seed)
    d = 2 * np.mean([np.max(np.hypot(*p)) for p in polygons])
    return _box(polygons, spacing * d, 4, np.random.default_rng(seed),
                youngs_modulus=youngs_modulus, **model)


#: Compression of the linear spring's square by each wall, fraction of its half side.
SPRING_COMPRESSION = 1e-3


def linear_spring(youngs_modulus=1.0e7, integrator="gear"):
    """A square of side 2·SIZE squeezed between two walls, oscillating sideways.

    Zero gravity, no support, no rotation, damping or friction: each wall is
    a linear spring (:func:`linear_spring_stiffness`) that never opens, since
    the oscillation's amplitude is a tenth of the static compression (Verlet
    enlarges the amplitude of positions by ``ω dt / sin θ`` with
    ``cos θ = 1 − (ω dt)²/2``, tenfold only at 0.995 of its limit).  The square
    starts at the equilibrium, where the engine's starting acceleration (zero,
    free flight) is exact.
    """
    sq = rectangle(2 * SIZE, 2 * SIZE)
    shapes = shapes_of(sq)
    model = ModelParams(youngs_modulus=youngs_modulus, damping=0.0, friction=0.0,
                        support_friction=0.0, integrator=integrator)
    depth = SPRING_COMPRESSION * SIZE
    omega = math.sqrt(2 * linear_spring_stiffness(youngs_modulus) / shapes.mass[0])
    return Setup(shapes, [(0.0, 0.0, 0.0, 0.1 * depth * omega, 0.0, 0.0)], model,
                 gravity=(0.0, 0.0), support=False, walls=(-SIZE + depth, SIZE - depth),
                 rotate=False)


def linear_spring_stiffness(youngs_modulus):
    """``k = Y L / l`` of an edge ``L = 2 SIZE`` on a wall, ``l = r = SIZE (1 − compression)``."""
    return youngs_modulus * 2 * SIZE / (SIZE * (1 - SPRING_COMPRESSION))


def linear_spring_limit(youngs_modulus, integrator):
    """Theoretical stability limit ``h*(0) / ω`` of :func:`linear_spring`, ``ω² = 2k/m``, s."""
    shapes = shapes_of(rectangle(2 * SIZE, 2 * SIZE))
    omega = math.sqrt(2 * linear_spring_stiffness(youngs_modulus) / shapes.mass[0])
    return stability_limit(integrator, 0.0) / omega


def _nearly_degenerate(edge_fraction, flat_angle_deg):
    """A heptagon with one edge of ``edge_fraction`` of its diameter and one
    corner of interior angle ``flat_angle_deg``."""
    x, y = regular_polygon(6, SIZE)
    # split corner 0 into two corners an edge_fraction of the diameter apart
    half = edge_fraction * SIZE
    pts = [(x[0], y[0] - half), (x[0], y[0] + half)] + list(zip(x[1:], y[1:]))
    # push the midpoint of the edge between corners 3 and 4 out to the given angle
    a, b = np.array(pts[3]), np.array(pts[4])
    mid = 0.5 * (a + b)
    out = mid / np.linalg.norm(mid)
    bulge = 0.5 * np.linalg.norm(b - a) * math.tan(math.radians(90 - flat_angle_deg / 2))
    pts.insert(4, tuple(mid + bulge * out))
    return centred(*np.array(pts).T)


def _size_ratio(ratio=20.0, speed=0.5):
    """A hexagon on the support; two hexagons ``ratio`` times smaller hit its
    top edge and its side corner at ``speed``."""
    big, small = 5e-3, 5e-3 / ratio
    h = big * math.sin(math.pi / 3)
    hs = small * math.sin(math.pi / 3)
    states = [(0.0, h, 0.0, 0.0, 0.0, 0.0),
              (0.2 * big, 2 * h + hs, 0.0, 0.0, -speed, 0.0),
              (-big - small, h, 0.0, speed, 0.0, 0.0)]
    polygons = [regular_polygon(6, big), regular_polygon(6, small), regular_polygon(6, small)]
    return Setup(shapes_of(*polygons), states, ModelParams())


def _stacked_elongated(aspect=5.0, layers=3):
    """Octagons in ``aspect``:1 ellipses lying flat on each other and the support,
    each pressed 2 % of its thickness into the one below."""
    a, b = 5e-3, 5e-3 / aspect
    poly = ellipse_polygon(8, a, b)
    thick = float(np.max(poly[1]))   # half thickness: corners at ±b on the minor axis
    states = [(0.1 * a * k, thick * (1 + 2 * k) * 0.98, 0.0, 0.0, 0.0, 0.0)
              for k in range(layers)]
    return Setup(shapes_of(*[poly] * layers), states, ModelParams())


def _impact(speed, **model):
    """A paper particle hitting the support and one hitting a resting particle, at ``speed``."""
    polygons = _paper_polygons(3, 2)
    r = [np.max(np.hypot(*p)) for p in polygons]
    states = [(0.0, r[0] + 1e-4, 0.3, 0.0, -speed, 0.0),
              (0.03, r[1], 0.0, 0.0, 0.0, 0.0),
              (0.03, 2 * r[1] + r[2] + 1e-4, 1.1, 0.0, -speed, 0.0)]
    return Setup(shapes_of(*polygons), states, ModelParams(**model))


def _deep_overlap(fraction):
    """Two squares overlapping edge-on-edge by ``fraction`` of their area, at rest."""
    sq = rectangle(2 * SIZE, 2 * SIZE)
    gap = 2 * SIZE * (1 - fraction)
    return Setup(shapes_of(sq, sq), [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                                     (gap, 0.1 * SIZE, 0.0, 0.0, 0.0, 0.0)],
                 ModelParams(damping=0.0, friction=0.0), gravity=(0.0, 0.0), support=False)


def _overdamped_spring(damping):
    """:func:`linear_spring` with normal damping γ (its contacts' ζ = γ sqrt(L/l) / 2)."""
    setup = linear_spring()
    setup.model = replace(setup.model, damping=damping)
    return setup


def _critical_damping():
    """γ making the rule's stiffest normal mode critically damped, ζ⊥ = (γ/2) sqrt(L/l) = 1."""
    sim = packing().simulation()
    ratio = (sim.bound.zeta_normal / (0.5 * sim.model.damping)) ** 2
    return 2.0 / math.sqrt(ratio)


def case_builders():
    """Name → (description, function returning a :class:`Setup`) of every suite case
    other than the stiffness ones."""
    rng = np.random.default_rng
    return {
        "size_ratio_20": ("hexagons of circumradius 5 mm and 0.25 mm (1:20), impacts at "
                          "0.5 m/s", _size_ratio),
        "aspect_ratio_5": ("three octagons in 5:1 ellipses stacked flat, long edges in contact",
                           _stacked_elongated),
        "corners_3": ("equilateral triangles", lambda: _box(
            [regular_polygon(3, SIZE)] * 9, 1.9 * SIZE, 3, rng(5))),
        "corners_32": ("32-gons", lambda: _box(
            [regular_polygon(32, SIZE)] * 9, 1.95 * SIZE, 3, rng(6))),
        "nearly_degenerate": ("an edge of 0.2 % of the diameter and a 178° corner", lambda: _box(
            [_nearly_degenerate(2e-3, 178.0)] * 9, 1.95 * SIZE, 3, rng(7))),
        "degenerate_refused": ("a 179.8° corner (beyond the shapes' 179° limit)", lambda: _box(
            [_nearly_degenerate(2e-3, 179.8)] * 4, 2.1 * SIZE, 2, rng(8))),
        "impact_10_m_s": ("10 m/s onto the support and onto a particle", lambda: _impact(10.0)),
        "deep_overlap": ("two squares overlapping by 15 % of their area, undamped",
                         lambda: _deep_overlap(0.15)),
        "jammed_box": ("packing on a lattice 0.8 of the mean diameter between walls",
                       lambda: packing(spacing=0.8)),
        "friction_zero": ("packing with mu = 0", lambda: packing(friction=0.0,
                                                                 support_friction=0.0)),
        "friction_2": ("packing with mu = 2", lambda: packing(friction=2.0,
                                                              support_friction=2.0)),
        "damping_zero": ("packing with gamma = 0", lambda: packing(damping=0.0)),
        "damping_critical": ("packing, stiffest normal mode critically damped",
                             lambda: packing(damping=_critical_damping())),
        "damping_overcritical": ("packing with gamma = 10", lambda: packing(damping=10.0)),
        "spring_overcritical": ("the linear spring (a square between walls) with gamma = 10, "
                                "zeta = 10", lambda: _overdamped_spring(10.0)),
        "dt_above_limit": ("packing with model.dt twice Verlet's (the larger) limit",
                           lambda: packing(dt=2 * packing(integrator="verlet").simulation()
                                           .bound.dt_limit)),
    }


CASE_NAMES = tuple(case_builders())
