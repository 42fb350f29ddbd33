"""Benchmark: ns per particle-step and per contact on a dense, settling heap.

``python -m sim bench`` builds, for each N, a packing of the paper's particles
between two walls on the support (a triangular lattice with spacing equal to
the mean circumdiameter), lets it settle under gravity with the relaxation
drag until the rows have collapsed into a contact network (``settle`` seconds
of simulated time), then times a fixed number of steps on 1 and on 2 threads
without the drag.  It prints a table (with the contacts per particle, so the
figures can be judged) and ends with one JSON line of the figures.  Timings
are medians of repeats.

``python -m sim bench --scenes STATE`` times the steps of a saved pile under
each scene variant of :data:`SCENE_VARIANTS` (the work each skips, against the
study's full law), the variants taking turns, timed in CPU time of the process
(run it with ``NUMBA_NUM_THREADS=1``), so that other jobs on a busy machine
disturb them little and alike.
"""

from __future__ import annotations

import dataclasses
import json
import resource
import time

import numba
import numpy as np

from .config import ModelParams, ParticleParams
from .engine import Simulation
from .shapes import make_shapes


def dense_packing(n, seed=0, model=None, particles=None):
    """A box-confined packing of ``n`` particles on the support.

    Parameters
    ----------
    n : int
        Number of particles.
    seed : int
        Seed of the shapes and orientations.
    model : ModelParams, optional
    particles : ParticleParams, optional

    Returns
    -------
    Simulation
    """
    model = model or ModelParams()
    pp = particles or ParticleParams()
    rng = np.random.default_rng(seed)
    shapes = make_shapes(rng, n, pp.corners_min, pp.corners_max, pp.semi_axis_mean,
                         pp.semi_axis_spread, model.density, pp.min_edge_fraction,
                         pp.min_angle_deg)
    d = 2.0 * float(np.mean(shapes.radius))
    ncol = max(int(np.sqrt(n)), 1)
    width = (ncol + 0.5) * d
    sim = Simulation(shapes, model, walls=(-0.5 * width - 0.5 * d, 0.5 * width + 0.5 * d))
    for k in range(n):
        row, col = divmod(k, ncol)
        x = -0.5 * width + (col + 0.5 + 0.5 * (row % 2)) * d
        y = (0.5 + row * np.sqrt(3.0) / 2.0) * d
        sim.place(k, x, y, rng.uniform(0, 2 * np.pi))
    return sim


def _array_bytes(sim):
    """Bytes held by the simulation's arrays."""
    total = 0
    for v in list(vars(sim).values()) + list(vars(sim.shapes).values()):
        if isinstance(v, np.ndarray):
            total += v.nbytes
    return total


def measure(n, steps=300, settle=0.05, repeats=3, threads=(1, 2), seed=0):
    """Time ``steps`` steps of a settled packing of ``n`` particles.

    Returns
    -------
    dict
        ``n``, ``contacts``, ``ns_per_particle_step`` and ``ns_per_contact``
        for each thread count, ``bytes_per_particle``.
    """
    sim = dense_packing(n, seed)
    sim.drag = 100.0
    sim.run(duration=settle)
    sim.drag = 0.0
    n_contacts = len(sim.contacts()["i"])
    out = {"n": n, "contacts": n_contacts, "dt": sim.dt,
           "bytes_per_particle": _array_bytes(sim) / n}
    for t in threads:
        if t > numba.config.NUMBA_NUM_THREADS:
            continue
        numba.set_num_threads(t)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            sim.run(steps=steps)
            times.append(time.perf_counter() - t0)
        med = float(np.median(times))
        out[f"ns_per_particle_step_{t}t"] = med / steps / n * 1e9
        out[f"ns_per_contact_{t}t"] = med / steps / max(n_contacts, 1) * 1e9
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


# name: (model settings changed, Simulation options changed)
SCENE_VARIANTS = {
    "study": ({}, {}),
    "friction 0, full law": ({"friction": 0.0, "support_friction": 0.0}, {"full_law": True}),
    "friction 0": ({"friction": 0.0, "support_friction": 0.0}, {}),
    "damping 0, full law": ({"damping": 0.0}, {"full_law": True}),
    "damping 0": ({"damping": 0.0}, {}),
    "no rotation": ({}, {"rotate": False}),
    "no support": ({}, {"support": False}),
}


def scene_costs(path, steps=200, repeats=5):
    """CPU ns per particle-step of the pile of a state file under each scene variant.

    Every variant starts from the file's state (its time step, integrator and
    tangential springs) with the settings of :data:`SCENE_VARIANTS`; the
    variants run ``steps`` steps in turn, ``repeats`` times.

    Returns
    -------
    dict
        ``n``, ``contacts`` and, per variant, the median ns per particle-step.
    """
    from .io import load_simulation

    base, ds = load_simulation(path)
    c = {"i": ds["contact_i"].values.astype(np.int64),
         "j": ds["contact_j"].values.astype(np.int64), "spring": ds["contact_spring"].values}
    sims = {}
    for name, (law, options) in SCENE_VARIANTS.items():
        sim = Simulation(base.shapes, dataclasses.replace(base.model, **law), base.gravity,
                         support=options.get("support", True), walls=base.walls,
                         rotate=options.get("rotate", base.rotate))
        sim.full_law = options.get("full_law", False)
        sim.set_scaled_derivatives(base.scaled_derivatives(), base.dt)
        sim.set_springs(c["i"], c["j"], c["spring"])
        sim.run(steps=10)  # compiles and builds the pair list outside the timing
        sims[name] = sim
    times = {name: [] for name in sims}
    for _ in range(repeats):
        for name, sim in sims.items():
            t0 = time.process_time()
            sim.run(steps=steps)
            times[name].append(time.process_time() - t0)
    out = {"n": base.n, "contacts": len(c["i"]), "threads": numba.get_num_threads()}
    for name, t in times.items():
        out[name] = float(np.median(t)) / steps / base.n * 1e9
    return out


def main_scenes(path, steps=200, repeats=5):
    """Print :func:`scene_costs` as a table and a final JSON line."""
    r = scene_costs(path, steps, repeats)
    print(f"{r['n']} particles, {r['contacts'] / r['n']:.2f} contacts per particle, "
          f"{r['threads']} thread(s), CPU time, median of {repeats}")
    print(f"{'scene':>22} {'ns/p-step':>10} {'vs study':>9}")
    for name in SCENE_VARIANTS:
        print(f"{name:>22} {r[name]:>10.1f} {r[name] / r['study']:>9.3f}")
    print(json.dumps({"scene_costs": r}))
    return r


def main(sizes=(1000, 3000, 10000, 30000), steps=300):
    """Run the benchmark and print a table and a final JSON line."""
    rows = []
    print(f"{'N':>7} {'contacts/N':>10} {'ns/p-step 1t':>13} {'ns/p-step 2t':>13} "
          f"{'ns/contact 2t':>14} {'B/particle':>11}", flush=True)
    for n in sizes:
        r = measure(n, steps=steps)
        rows.append(r)
        print(f"{n:>7} {r['contacts'] / n:>10.2f} "
              f"{r.get('ns_per_particle_step_1t', np.nan):>13.1f} "
              f"{r.get('ns_per_particle_step_2t', np.nan):>13.1f} "
              f"{r.get('ns_per_contact_2t', np.nan):>14.1f} "
              f"{r['bytes_per_particle']:>11.0f}", flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"bench": rows, "peak_rss_bytes": peak,
                      "threads_available": numba.config.NUMBA_NUM_THREADS}))
    return rows
