"""The fixed part of a simulation: shapes, bodies, time step and the settings of the law.

Fixed bodies are half-planes: the support ``y < 0`` and, optionally, side walls
``x < x_left`` and ``x > x_right``; and, optionally, a rough base
(:class:`RoughBase`): a row of fixed polygons lying on the support.  In state
files a contact with a body has ``contact_j = -1`` (support), ``-2`` (left
wall), ``-3`` (right wall) or ``BODY_BASE - b`` (base polygon b).

What changes while a simulation runs is in :class:`sim.state.State`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import ModelParams
from .integrators import corrector_coefficients
from .shapes import Shapes, shapes_from_nodes
from .step import Law
from .timestep import TimeStepBound, choose_dt, stability_bound

BODY_SUPPORT, BODY_LEFT, BODY_RIGHT = -1, -2, -3
#: ``contact_j`` of base polygon 0; polygon b is ``BODY_BASE - b``.
BODY_BASE = -4


@dataclass
class RoughBase:
    """Fixed polygons lying side by side on the support (``physics.rough_base``).

    They never move and take part in contacts with the particles by the
    particles' own contact law (Young's modulus, damping, ``model.friction``),
    as particles of infinite mass and inertia; they do not touch each other,
    the support or the walls (no force is ever computed between them).  A
    particle's contacts with them are kept in ``Scene.base_slots`` rows per
    particle: base polygon b in row ``b % base_slots`` (:mod:`sim.step`).

    Attributes
    ----------
    shapes : sim.shapes.Shapes
        Their shapes (body frame), polygon after polygon from left to right.
    x, y, theta : numpy.ndarray
        Their centres (m) and orientations (rad).
    wx, wy : numpy.ndarray
        World corners (CSR by ``shapes.node_offset``).
    box : numpy.ndarray, shape (n, 4)
        Bounding boxes (xmin, xmax, ymin, ymax); their x ranges follow each
        other without overlap, so both columns 0 and 1 increase.
    top : float
        The highest corner, m.
    """

    shapes: Shapes
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    wx: np.ndarray
    wy: np.ndarray
    box: np.ndarray
    top: float

    @property
    def count(self):
        """int: Number of base polygons."""
        return len(self.x)


def place_base(shapes, x, y, theta) -> RoughBase:
    """The :class:`RoughBase` of polygons `shapes` at centres `x`, `y` (m) and
    orientations `theta` (rad).

    Raises
    ------
    ValueError
        If the polygons' x ranges overlap or are not in increasing order.
    """
    x, y, theta = (np.asarray(a, float).copy() for a in (x, y, theta))
    c = np.repeat(np.cos(theta), shapes.node_count)
    s = np.repeat(np.sin(theta), shapes.node_count)
    wx = np.repeat(x, shapes.node_count) + c * shapes.node_x - s * shapes.node_y
    wy = np.repeat(y, shapes.node_count) + s * shapes.node_x + c * shapes.node_y
    starts = shapes.node_offset[:-1]
    box = np.column_stack([np.minimum.reduceat(wx, starts), np.maximum.reduceat(wx, starts),
                           np.minimum.reduceat(wy, starts), np.maximum.reduceat(wy, starts)])
    if np.any(box[1:, 0] < box[:-1, 1]):
        k = int(np.flatnonzero(box[1:, 0] < box[:-1, 1])[0])
        raise ValueError(f"base polygons {k} and {k + 1}: their x ranges overlap or are out "
                         "of order")
    return RoughBase(shapes=shapes, x=x, y=y, theta=theta, wx=wx, wy=wy,
                     box=np.ascontiguousarray(box), top=float(np.max(wy)))


#: The gap between neighbouring base polygons, in units of the width of the
#: one on its left: far above the rounding of their world corners, which
#: would otherwise make touching x ranges overlap (:func:`place_base`), and
#: far below anything a particle could fit into.
BASE_GAP = 1e-9


def lay_base(draw, rng, x_left, x_right, density) -> RoughBase:
    """Lay polygons side by side on the support over ``[x_left, x_right]``.

    Each polygon, in the order drawn, is turned by an angle uniform in
    ``[0, 2π)`` and laid with its lowest corner on ``y = 0`` and its leftmost
    corner :data:`BASE_GAP` of the previous polygon's width to the right of
    that polygon's rightmost x (the first on ``x_left``), as long as it ends
    within ``x_right``; the row is then centred in the interval.

    Parameters
    ----------
    draw : callable
        ``draw(rng, n)``: ``n`` polygons (:class:`sim.shapes.Shapes`) drawn from `rng`.
    rng : numpy.random.Generator
        Draws the polygons and their angles (in batches, until the interval is full).
    x_left, x_right : float
        The interval, m.
    density : float
        The polygons' density, kg/m² (their masses enter only the time step's
        bound: :func:`make_scene`).

    Returns
    -------
    RoughBase
    """
    counts, node_x, node_y, xs, ys, thetas = [], [], [], [], [], []
    end = x_left
    while True:
        batch = draw(rng, 64)
        angles = rng.uniform(0.0, 2.0 * np.pi, batch.n)
        for k in range(batch.n):
            bx, by = batch.corners(k)
            c, s = np.cos(angles[k]), np.sin(angles[k])
            rx = c * bx - s * by
            ry = s * bx + c * by
            width = rx.max() - rx.min()
            if end + width > x_right:
                return _centred(counts, node_x, node_y, xs, ys, thetas, x_right - end,
                                density)
            counts.append(len(bx))
            node_x.append(bx)
            node_y.append(by)
            xs.append(end - rx.min())
            ys.append(-ry.min())
            thetas.append(angles[k])
            end += (1.0 + BASE_GAP) * width


def _centred(counts, node_x, node_y, xs, ys, thetas, room, density):
    """The base of :func:`lay_base`'s polygons moved right by half the `room` left."""
    if not counts:
        raise ValueError("no base polygon fits between the bounds of the rough base")
    shapes = shapes_from_nodes(np.array(counts, np.int64), np.concatenate(node_x),
                               np.concatenate(node_y), density)
    return place_base(shapes, np.array(xs) + 0.5 * room, ys, thetas)


@dataclass
class Scene:
    """What a run does not change (a plain structure; see :func:`make_scene`).

    Attributes
    ----------
    shapes : sim.shapes.Shapes
        All particles that may take part.
    model : sim.config.ModelParams
    capacity : int
        Number of particles in ``shapes``.
    coeffs : numpy.ndarray
        The integrator's corrector coefficients (one per scaled derivative).
    bound : sim.timestep.TimeStepBound
    dt : float
        Time step, s (a scene built for a time-step study sets its own before
        placing particles).
    rotate : bool
        Whether orientations are integrated.
    size, eps, skin : float
        Mean circumradius, the length below which geometry counts as zero
        (``1e-9 size``) and the Verlet skin of the pair list, m.
    law : sim.step.Law
        The contact law as the kernels take it, built once from ``model``:
        its parameters and the flags of the terms that can be nonzero (all
        of them with :func:`make_scene`'s ``full_law``).
    inv_mass, inv_inertia : numpy.ndarray
        Per particle.
    body_p, body_m : numpy.ndarray, shape (n_bodies, 2)
        A point and the outward normal of each half-plane body.
    body_ids : numpy.ndarray
        ``BODY_SUPPORT``, ``BODY_LEFT``, ``BODY_RIGHT`` of the bodies present.
    body_friction : numpy.ndarray
        Friction coefficient of each body.
    walls : tuple of float or None
        ``(x_left, x_right)``.
    base : RoughBase or None
        The rough base, or None for none.
    base_slots : int
        Rows per particle for its contacts with the rough base: the most base
        polygons whose x range one particle's box can reach,
        ``floor(2 R_max / w_min) + 2`` for the particles' largest
        circumradius ``R_max`` and the base polygons' narrowest x range
        ``w_min`` (0 without a base).
    """

    shapes: object
    model: ModelParams
    capacity: int
    coeffs: np.ndarray
    bound: TimeStepBound
    dt: float
    rotate: bool
    size: float
    eps: float
    skin: float
    law: Law
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    body_p: np.ndarray
    body_m: np.ndarray
    body_ids: np.ndarray
    body_friction: np.ndarray
    walls: tuple | None
    base: RoughBase | None
    base_slots: int


def make_scene(shapes, model: ModelParams, support=True, walls=None, rotate=True,
               skin=None, base=None, full_law=False) -> Scene:
    """The :class:`Scene` of :class:`sim.engine.Simulation`'s arguments (see there).

    The time step's bound (:func:`sim.timestep.stability_bound`) is that of
    the particles and the base polygons together, as if the latter could
    move: a particle's contact with a fixed polygon is softer for its mass
    than one with a particle of that polygon's shape.

    Raises
    ------
    ValueError
        If the walls are not ``x_left < x_right``.
    """
    bodies, ids = [], []
    if support:
        bodies.append((0.0, 0.0, 0.0, 1.0))
        ids.append(BODY_SUPPORT)
    if walls is not None:
        xl, xr = walls
        if not xl < xr:
            raise ValueError(f"walls = {walls!r}: x_left must be < x_right")
        bodies += [(xl, 0.0, 1.0, 0.0), (xr, 0.0, -1.0, 0.0)]
        ids += [BODY_LEFT, BODY_RIGHT]
    b = np.array(bodies, float).reshape(-1, 4)
    every = [shapes] if base is None else [shapes, base.shapes]
    bound = stability_bound(model.youngs_modulus, model.damping, model.integrator,
                            *(np.concatenate([getattr(sh, name) for sh in every])
                              for name in ("mass", "inertia", "radius", "inradius")),
                            max(_max_edge(sh) for sh in every), model.density)
    size = float(np.mean(shapes.radius))
    eps = 1e-9 * size
    return Scene(shapes=shapes, model=model, capacity=len(shapes.mass),
                 coeffs=corrector_coefficients(model.integrator), bound=bound,
                 dt=choose_dt(bound, model.dt, model.dt_safety, model.integrator),
                 rotate=bool(rotate), size=size, eps=eps,
                 skin=0.3 * size if skin is None else float(skin),
                 law=_law(model, eps, full_law),
                 inv_mass=1.0 / shapes.mass, inv_inertia=1.0 / shapes.inertia,
                 body_p=np.ascontiguousarray(b[:, :2]), body_m=np.ascontiguousarray(b[:, 2:]),
                 body_ids=np.array(ids, np.int64),
                 body_friction=np.full(len(ids), model.support_friction), walls=walls,
                 base=base, base_slots=_base_slots(shapes, base))


def _law(model, eps, full_law):
    """The :class:`sim.step.Law` of `model` with length tolerance `eps` (m):
    a term is computed where its coefficient is nonzero, every one with
    `full_law` (the skipped ones would be exactly zero: :mod:`sim.step`)."""
    return Law(float(model.youngs_modulus), float(model.damping), float(model.friction), eps,
               bool(full_law or model.damping > 0.0), bool(full_law or model.friction > 0.0),
               bool(full_law or model.support_friction > 0.0))


def _base_slots(shapes, base):
    """:attr:`Scene.base_slots` of particles `shapes` on `base` (None: 0)."""
    if base is None:
        return 0
    narrowest = float(np.min(base.box[:, 1] - base.box[:, 0]))
    return int(2.0 * float(np.max(shapes.radius)) // narrowest) + 2


def _max_edge(shapes):
    """Longest polygon edge over all particles, m."""
    longest = 0.0
    off = shapes.node_offset
    for i in range(len(shapes.mass)):
        x = shapes.node_x[off[i]:off[i + 1]]
        y = shapes.node_y[off[i]:off[i + 1]]
        longest = max(longest, float(np.max(np.hypot(np.roll(x, -1) - x,
                                                     np.roll(y, -1) - y))))
    return longest
