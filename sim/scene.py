"""The fixed part of a simulation: shapes, bodies, time step and the settings of the law.

Fixed bodies are half-planes: the support ``y < 0`` and, optionally, side walls
``x < x_left`` and ``x > x_right``.  In state files a contact with a body has
``contact_j = -1`` (support), ``-2`` (left wall) or ``-3`` (right wall).

What changes while a simulation runs is in :class:`sim.state.State`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import ModelParams
from .integrators import corrector_coefficients
from .timestep import TimeStepBound, choose_dt, stability_bound

BODY_SUPPORT, BODY_LEFT, BODY_RIGHT = -1, -2, -3


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
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    body_p: np.ndarray
    body_m: np.ndarray
    body_ids: np.ndarray
    body_friction: np.ndarray
    walls: tuple | None


def make_scene(shapes, model: ModelParams, support=True, walls=None, rotate=True,
               skin=None) -> Scene:
    """The :class:`Scene` of :class:`sim.engine.Simulation`'s arguments (see there).

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
    bound = stability_bound(model.youngs_modulus, model.damping, model.integrator, shapes.mass,
                            shapes.inertia, shapes.radius, shapes.inradius, _max_edge(shapes),
                            model.density)
    size = float(np.mean(shapes.radius))
    return Scene(shapes=shapes, model=model, capacity=len(shapes.mass),
                 coeffs=corrector_coefficients(model.integrator), bound=bound,
                 dt=choose_dt(bound, model.dt, model.dt_safety, model.integrator),
                 rotate=bool(rotate), size=size, eps=1e-9 * size,
                 skin=0.3 * size if skin is None else float(skin),
                 inv_mass=1.0 / shapes.mass, inv_inertia=1.0 / shapes.inertia,
                 body_p=np.ascontiguousarray(b[:, :2]), body_m=np.ascontiguousarray(b[:, 2:]),
                 body_ids=np.array(ids, np.int64),
                 body_friction=np.full(len(ids), model.support_friction), walls=walls)


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
