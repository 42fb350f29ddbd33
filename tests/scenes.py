"""Small hand-made scenes shared by the simulator tests."""

from sim.config import ModelParams
from sim.engine import Simulation
from sim.numerics.polygons import diamond, rectangle, regular_polygon, shapes_of

__all__ = ["diamond", "dying_at_run", "rectangle", "regular_polygon", "scene", "shapes_of"]


def scene(polygons, states, gravity=(0.0, 0.0), support=False, walls=None, rotate=True,
          **model):
    """A :class:`Simulation` with particles at ``states`` = [(x, y, theta, vx, vy, w)]."""
    sim = Simulation(shapes_of(*polygons), ModelParams(**model), gravity=gravity,
                     support=support, walls=walls, rotate=rotate)
    for k, st in enumerate(states):
        sim.place(k, *st)
    return sim


def dying_at_run(n):
    """A stand-in for :meth:`Simulation.run` whose `n`-th call raises
    ``KeyboardInterrupt``, as a kill between two runs of a pour would.

    Parameters
    ----------
    n : int
        The call that dies (1 = the first).

    Returns
    -------
    callable
        To set with ``monkeypatch.setattr(Simulation, "run", ...)``; the
        other calls run as :meth:`Simulation.run` does.
    """
    original, calls = Simulation.run, [0]

    def run(self, *args, **kwargs):
        calls[0] += 1
        if calls[0] == n:
            raise KeyboardInterrupt("killed")
        return original(self, *args, **kwargs)

    return run
