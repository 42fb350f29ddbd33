"""The contact law is fixed for a simulation's life: its :class:`sim.step.Law` is
built once, with the scene, and a run of many chunks of steps builds no other."""

import sys

import numpy as np

from sim.config import ModelParams
from sim.engine import Simulation
from sim.shapes import make_shapes
from sim.step import Law


def test_a_run_of_many_chunks_builds_the_law_once(monkeypatch):
    built = []

    def counted(*args):
        built.append(args)
        return Law(*args)

    # wherever a module of the simulator holds the name, it builds through the counter
    holders = [m for name, m in sys.modules.items()
               if name.split(".")[0] == "sim" and getattr(m, "Law", None) is Law]
    for module in holders:
        monkeypatch.setattr(module, "Law", counted)
    shapes = make_shapes(np.random.default_rng(2), 12)
    sim = Simulation(shapes, ModelParams(), walls=(-0.02, 0.02))
    d = 2.0 * float(shapes.radius.max())
    for k in range(12):
        sim.place(k, (k % 4 - 1.5) * 1.1 * d, (0.6 + 1.1 * (k // 4)) * d)
    chunks = []
    sim.heartbeat = lambda s: chunks.append(s.step)
    for _ in range(3):
        sim.run(steps=4 * sim.check_every)
    assert len(chunks) >= 12
    assert len(built) == 1
    assert sim.law == built[0] and sim.law.tangential
