"""Writes ``tests/data/stretch_heap.nc``: the relaxed heap of tests/test_support_stretch.py.

45 polygons (the study's shapes for seed 3) laid in a triangle of rows of
9, 8, ..., 1, let fall onto the support and relaxed to the study's rest
criteria (Verlet, about 20 s of CPU).  The fall is chaotic: another
processor or another numpy rounds a few last bits differently and settles
another heap, so the test starts from this file rather than building its
own, and its tolerances are argued for a heap at rest, not tuned to one
machine's outcome.  Rerun after a change of the state-file format::

    .venv/bin/python tests/stretch_heap.py
"""

from pathlib import Path

import numpy as np

from sim.config import SimConfig
from sim.engine import Simulation
from sim.io import save_state
from sim.pour import GRAVITY, pile_shapes
from sim.relax import relax

ROWS = 9
#: The settings of the heap and of its probes in the test.
SETTINGS = {"pour": {"n_particles": ROWS * (ROWS + 1) // 2, "progress_interval": 1e9},
            "model": {"integrator": "verlet"}}
FILE = Path(__file__).parent / "data" / "stretch_heap.nc"


def make_heap(out=FILE):
    """Lay, drop and relax the heap and save it as a ``relaxed`` state at ``out``."""
    cfg = SimConfig.from_dict(SETTINGS)
    shapes = pile_shapes(cfg, 3)
    sim = Simulation(shapes, cfg.model, gravity=(0.0, -GRAVITY))
    step = 2.05 * float(shapes.radius.max())
    rng = np.random.default_rng(3)
    k = 0
    for row in range(ROWS):
        for c in range(ROWS - row):
            sim.place(k, (c - 0.5 * (ROWS - row - 1)) * step,
                      1.02 * float(shapes.radius.max()) + 0.9 * row * step, rng.uniform(0.0, 2 * np.pi))
            k += 1
    relax(sim, cfg, "heap")
    save_state(sim, out, cfg.to_dict(), stage="relaxed", protocol="wedge", seed=3)


if __name__ == "__main__":
    make_heap()
