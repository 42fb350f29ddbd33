"""Compile and cache every Numba kernel once, before parallel jobs start.

Snakemake runs this as its own rule ahead of the fan-out so that concurrent
simulation jobs find the kernels in the on-disk cache instead of racing to
compile them.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .config import ModelParams
from .engine import Simulation
from .shapes import make_shapes

log = logging.getLogger("sim")


def warmup():
    """Run a few steps of a tiny scene with each integrator, walls and support."""
    t0 = time.monotonic()
    shapes = make_shapes(np.random.default_rng(0), 4)
    for integrator in ("gear", "verlet"):
        sim = Simulation(shapes, ModelParams(integrator=integrator), walls=(-0.02, 0.02))
        for k in range(4):
            sim.place(k, -0.009 + 0.006 * k, 0.004 + 0.002 * (k % 2), 0.3 * k)
        sim.run(steps=20)
    log.info("kernels compiled and cached in %.1f s", time.monotonic() - t0)
