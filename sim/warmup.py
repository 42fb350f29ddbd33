"""Compile and cache every Numba kernel once, before parallel jobs start.

Snakemake runs this as its own rule ahead of the fan-out so that concurrent
simulation jobs find the kernels in the on-disk cache instead of racing to
compile them.
"""

from __future__ import annotations

import logging
import time

import numba
import numpy as np

from .config import ModelParams
from .engine import Simulation
from .shapes import make_shapes

log = logging.getLogger("sim")


def warmup():
    """Run a few steps of a tiny scene with each integrator, walls and support.

    Each scene runs with the serial kernels and, when this process has more
    than one thread, once more with the parallel ones (the two builds are
    cached apart, :mod:`sim.step`).
    """
    t0 = time.monotonic()
    shapes = make_shapes(np.random.default_rng(0), 4)
    thresholds = (np.inf, 0) if numba.get_num_threads() > 1 else (np.inf,)
    for integrator in ("gear", "verlet"):
        for threshold in thresholds:
            sim = Simulation(shapes, ModelParams(integrator=integrator), walls=(-0.02, 0.02))
            sim.parallel_threshold = threshold
            for k in range(4):
                sim.place(k, -0.009 + 0.006 * k, 0.004 + 0.002 * (k % 2), 0.3 * k)
            sim.run(steps=20)
    log.info("kernels compiled and cached in %.1f s (%s)", time.monotonic() - t0,
             "serial and parallel builds" if len(thresholds) == 2 else "serial builds")
