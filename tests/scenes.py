"""Small hand-made scenes shared by the simulator tests."""

import numpy as np

from sim.config import ModelParams
from sim.engine import Simulation
from sim.shapes import shapes_from_nodes

DENSITY = 2500.0


def rectangle(w, h):
    """Corners of a w × h rectangle centred at the origin, counter-clockwise."""
    return np.array([-w / 2, w / 2, w / 2, -w / 2]), np.array([-h / 2, -h / 2, h / 2, h / 2])


def diamond(half_diagonal):
    """A square standing on a corner (corners on the axes)."""
    r = half_diagonal
    return np.array([0.0, r, 0.0, -r]), np.array([-r, 0.0, r, 0.0])


def regular_polygon(n, radius, phase=0.0):
    """Corners of a regular n-gon of circumradius ``radius``."""
    a = phase + 2 * np.pi * np.arange(n) / n
    return radius * np.cos(a), radius * np.sin(a)


def shapes_of(*polygons, density=DENSITY):
    """:class:`sim.shapes.Shapes` of the given (x, y) corner arrays."""
    counts = np.array([len(p[0]) for p in polygons])
    return shapes_from_nodes(counts, np.concatenate([p[0] for p in polygons]),
                             np.concatenate([p[1] for p in polygons]), density)


def scene(polygons, states, gravity=(0.0, 0.0), support=False, walls=None, rotate=True,
          **model):
    """A :class:`Simulation` with particles at ``states`` = [(x, y, theta, vx, vy, w)]."""
    sim = Simulation(shapes_of(*polygons), ModelParams(**model), gravity=gravity,
                     support=support, walls=walls, rotate=rotate)
    for k, st in enumerate(states):
        sim.place(k, *st)
    return sim
