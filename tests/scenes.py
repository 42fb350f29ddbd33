"""Small hand-made scenes shared by the simulator tests."""

from sim.config import ModelParams
from sim.engine import Simulation
from sim.numerics.polygons import diamond, rectangle, regular_polygon, shapes_of

__all__ = ["diamond", "rectangle", "regular_polygon", "scene", "shapes_of"]


def scene(polygons, states, gravity=(0.0, 0.0), support=False, walls=None, rotate=True,
          **model):
    """A :class:`Simulation` with particles at ``states`` = [(x, y, theta, vx, vy, w)]."""
    sim = Simulation(shapes_of(*polygons), ModelParams(**model), gravity=gravity,
                     support=support, walls=walls, rotate=rotate)
    for k, st in enumerate(states):
        sim.place(k, *st)
    return sim
