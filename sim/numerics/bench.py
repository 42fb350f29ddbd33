"""Benchmark: ns per particle-step in settled, loaded piles, and per scene variant.

``python -m sim bench`` times the regime a study pays for: a pile late in its
pour, at rest under its own weight, with every particle in contact.  For each
N it builds such a pile once (:func:`loaded_pile`: particles on a triangular
lattice filling a heap of :data:`HEAP_SLOPE_DEG`, collapsed under gravity and
relaxed with the study's relaxation) and keeps it in ``--cache`` (default ``.bench/``), so
later runs time the same pile.  Each pile is timed with both integrators on 1
and 2 threads: wall and CPU time of ``steps`` steps, medians of ``repeats``,
giving ns per particle-step, ns per contact, the contacts per particle (of
particle–particle contacts; the support's are counted apart) and the CPU
cores used (CPU time / wall time).  A second, kernel-by-kernel timing gives
the share of the predictor, the pair pass and the gather.  Each row also
gives the pile's time step, the CPU cost per simulated second
(:func:`cost_per_simulated_second`), the pair-list refreshes in the timed
steps and the pile's rms speed (:func:`rms_speed`) as loaded and after the
timing.  With ``--peer`` each peer's rows follow under a line naming its
LAMMPS build, with the same columns and LAMMPS's neighbour-list builds and
timing breakdown (:mod:`sim.numerics.lammps_peer`).  It prints a table,
the parallel efficiency and the cost across sizes (:func:`derived_figures`,
the figures the performance targets are stated in), and ends with one JSON
line of all of them.  ``--state FILE`` times a saved pile instead (e.g. a
poured full-size pile).

``python -m sim bench --scenes STATE`` times the steps of a saved pile under
each scene variant of :data:`SCENE_VARIANTS` (the work each skips, against the
study's full law), the variants taking turns, timed in CPU time of the process
(run it with ``NUMBA_NUM_THREADS=1``), so that other jobs on a busy machine
disturb them little and alike.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import resource
import time
from pathlib import Path

import numba
import numpy as np

from ..config import ModelParams, ParticleParams, RelaxParams, SimConfig
from ..engine import Simulation
from ..step import KERNELS_PARALLEL, KERNELS_SERIAL
from ..integrators import INTEGRATORS
from ..io import load_simulation, read_state, save_state
from ..relax import RelaxationError, relax
from ..shapes import shapes_by_settings
from . import lammps_peer, lammps_polygons

log = logging.getLogger("sim")

#: Flank slope of the lattice heap a loaded pile is built from, degrees: below
#: the angle of repose, so that the heap settles instead of flowing (a 30°
#: heap of 3000 particles was still flowing after 1.6 s).
HEAP_SLOPE_DEG = 20.0
#: Relaxation of a benchmark pile: the study's criterion, at most this long.
#: The 3000-particle heap's kinetic energy has fallen to 2e-4 m g d per
#: particle by 1 s, and the bench prints the contacts per particle it times;
#: relaxing for 3 s took that pile 23 min to build (the other core busy).
HEAP_RELAX = RelaxParams(max_time=1.0)
#: The peers ``--peer`` can time beside the piles (in this order).
PEERS = ("lammps", "lammps-polygons")


def _shapes(rng, n, model, particles=None):
    """``n`` of the study's particles (or of ``particles``) at ``model.density``."""
    return shapes_by_settings(rng, n, particles or ParticleParams(), model.density)


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
    rng = np.random.default_rng(seed)
    shapes = _shapes(rng, n, model, particles)
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


def lattice_heap(n, seed=0, model=None, particles=None, slope_deg=HEAP_SLOPE_DEG):
    """``n`` particles on a triangular lattice filling a heap with flanks of ``slope_deg``.

    The lattice spacing is the largest circumdiameter, so no two particles
    overlap; rows are filled from the support up, each as wide as the heap at
    its height.

    Returns
    -------
    Simulation
        At rest, with gravity, the support and no walls.
    """
    model = model or ModelParams(integrator="verlet")
    rng = np.random.default_rng(seed)
    shapes = _shapes(rng, n, model, particles)
    d = 2.0 * float(np.max(shapes.radius))
    row_height = d * np.sqrt(3.0) / 2.0
    cot = 1.0 / np.tan(np.radians(slope_deg))
    height = np.sqrt(n * d * row_height / cot)
    sim = Simulation(shapes, model)
    k = 0
    row = 0
    while k < n:
        y = 0.5 * d + row * row_height
        count = max(int(2.0 * (height - y) * cot / d), 1)
        for c in range(min(count, n - k)):
            x = (c - 0.5 * (count - 1) + 0.25 * (row % 2)) * d
            sim.place(k, x, y, rng.uniform(0.0, 2.0 * np.pi))
            k += 1
        row += 1
    return sim


def loaded_pile(n, seed=0, cache=Path(".bench")):
    """A settled, loaded pile of ``n`` particles, built once and kept in ``cache``.

    The lattice heap of :func:`lattice_heap` collapses under gravity and is
    relaxed with the study's relaxation (:func:`sim.relax.relax`, at most
    ``HEAP_RELAX.max_time``; a pile still creeping then is kept as it is).

    Returns
    -------
    pathlib.Path
        Its state file.
    """
    path = Path(cache) / (f"pile-n{n}-seed{seed}-slope{HEAP_SLOPE_DEG:g}"
                          f"-relax{HEAP_RELAX.max_time:g}s.nc")
    if path.exists():
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    sim = lattice_heap(n, seed)
    t0 = time.monotonic()
    try:
        relax(sim, SimConfig(relax=HEAP_RELAX), f"bench pile of {n}")
    except RelaxationError as exc:
        log.warning("%s; kept as it is", exc)
    log.info("bench pile of %d particles built in %.0f s: %.2f contacts per particle", n,
             time.monotonic() - t0, _particle_contacts(sim) / n)
    save_state(sim, path, stage="bench")
    return path


def rms_speed(sim):
    """Root-mean-square speed of the particles of ``sim``, weighted by mass
    (translational, as LAMMPS's ``ke``: :func:`sim.numerics.lammps_peer.rms_speed`), m/s."""
    n = sim.n
    v = sim.state.r[1, :2, :n] / sim.dt
    mass = sim.shapes.mass[:n]
    return lammps_peer.rms_speed(0.5 * float(np.sum(mass * (v * v).sum(axis=0))),
                                 float(mass.sum()))


def _particle_contacts(sim):
    """Particle–particle contacts of the last force evaluation."""
    return int(np.count_nonzero(sim.contacts()["j"] >= 0))


def _load(path, integrator, **options):
    """The pile of ``path`` with its springs, continued with ``integrator`` at its
    automatic time step; ``options`` change the model or the scene
    (``rotate``, ``support``, ``full_law``)."""
    base, ds = load_simulation(path)
    law = {k: v for k, v in options.items() if k not in ("rotate", "support", "full_law")}
    model = dataclasses.replace(base.model, integrator=integrator, dt=None, **law)
    sim = Simulation(base.shapes, model, base.gravity, support=options.get("support", True),
                     walls=base.walls, rotate=options.get("rotate", base.rotate),
                     full_law=options.get("full_law", False))
    sim.set_scaled_derivatives(base.scaled_derivatives(), base.dt)
    sim.set_springs(ds["contact_i"].values.astype(np.int64),
                    ds["contact_j"].values.astype(np.int64), ds["contact_spring"].values,
                    ds["contact_witness"].values.astype(np.int64))
    return sim


def kernel_shares(sim, steps):
    """Shares of the predictor, the pair pass and the gather in ``steps`` steps.

    The kernels are called one by one from Python (with the build
    :meth:`Simulation.run` would use), each timed; the pair list is not
    rebuilt, so keep ``steps`` short of a rebuild.  The predictor runs inside
    the gather's pass (:mod:`sim.step`); its share is that of the same
    prediction timed alone each step (it only rewrites the prediction the
    gather made), and the gather's share is the rest of that pass.

    Returns
    -------
    dict
        ``predict``, ``pairs``, ``gather``: fractions of a step.
    """
    sim.run(steps=1)  # current pair list
    kernels = KERNELS_PARALLEL if sim.parallel_kernels() else KERNELS_SERIAL
    predict, pairs, gather = kernels
    pt, pr, bodies = sim.kernel_state()
    law, motion, work = sim.law, sim.motion(), sim.work
    spent = np.zeros(3)
    for _ in range(steps):
        t0 = time.perf_counter()
        predict(sim.n, pt, motion, work)
        t1 = time.perf_counter()
        pairs(pt, pr, law, motion.dt, work, False)
        t2 = time.perf_counter()
        gather(sim.n, pt, pr, bodies, law, motion, work, sim.x_ref, sim.y_ref, False)
        spent += (t1 - t0, t2 - t1, time.perf_counter() - t2)
    sim.step += steps
    sim.time += steps * sim.dt
    sim.run(steps=1)  # rows of the last step, as after any run
    total = float(spent[1] + spent[2])
    return {"predict": spent[0] / total, "pairs": spent[1] / total,
            "gather": max(spent[2] - spent[0], 0.0) / total}


def measure(path, integrator, threads, steps=200, repeats=5):
    """Time ``steps`` steps of the pile of ``path`` on ``threads`` threads.

    Returns
    -------
    dict
        ``n_particles``, ``threads``, ``integrator``, ``contacts_per_particle``
        (particle–particle), ``body_contacts``, ``ns_per_particle_step``,
        ``ns_per_contact``, ``cpu_ns_per_particle_step``, ``cores_used``,
        the kernel shares ``share_predict``, ``share_pairs``,
        ``share_gather``; ``dt`` (the pile's step), ``list_refreshes`` (of
        the pair list, :mod:`sim.rebuild`, in the timed runs, each), the
        cost per simulated second (:func:`cost_per_simulated_second`) and
        ``rms_speed`` (:func:`rms_speed`) of the pile as loaded and after
        the timed runs.
    """
    numba.set_num_threads(threads)
    try:
        sim = _load(path, integrator)
        speeds = [rms_speed(sim)]
        sim.run(steps=20)  # compiles outside the timing
        walls, cpus, refreshes = [], [], []
        for _ in range(repeats):
            count = []
            # after each chunk of steps: whether the list is refreshed before the next
            sim.heartbeat = lambda s: count.append(s.state.stale or s.state.moved)
            t0 = time.perf_counter()
            c0 = time.process_time()
            sim.run(steps=steps)
            cpus.append(time.process_time() - c0)
            walls.append(time.perf_counter() - t0)
            sim.heartbeat = None
            refreshes.append(int(sum(count)))
        speeds.append(rms_speed(sim))
        contacts = _particle_contacts(sim)
        shares = kernel_shares(sim, min(steps, 50))
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    wall = float(np.median(walls))
    cpu = float(np.median(cpus))
    n = sim.n
    return {"n_particles": n, "threads": threads, "integrator": integrator,
            "contacts_per_particle": contacts / n,
            "body_contacts": len(sim.contacts()["i"]) - contacts,
            "ns_per_particle_step": wall / steps / n * 1e9,
            "ns_per_contact": wall / steps / max(contacts, 1) * 1e9,
            "cpu_ns_per_particle_step": cpu / steps / n * 1e9,
            "cores_used": cpu / wall,
            **{f"share_{k}": v for k, v in shares.items()},
            "dt": sim.dt, "steps": steps, "list_refreshes": refreshes,
            **cost_per_simulated_second(cpu / steps / n * 1e9, n, sim.dt),
            "rms_speed": speeds}


def cost_per_simulated_second(cpu_ns_per_particle_step, n, dt):
    """What a simulated second costs at ``cpu_ns_per_particle_step`` (CPU ns) and step ``dt`` (s).

    Returns
    -------
    dict
        ``cpu_s_per_simulated_s``: CPU seconds per simulated second of the
        pile of ``n`` particles; ``cpu_s_per_particle_simulated_s``: of one
        particle (CPU ns per particle-step over the step).
    """
    per_particle = cpu_ns_per_particle_step * 1e-9 / dt
    return {"cpu_s_per_simulated_s": per_particle * n,
            "cpu_s_per_particle_simulated_s": per_particle}


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

    Every variant starts from the file's state (its integrator and tangential
    springs) with the settings of :data:`SCENE_VARIANTS`; the variants run
    ``steps`` steps in turn, ``repeats`` times.

    Returns
    -------
    dict
        ``n``, ``contacts`` and, per variant, the median ns per particle-step.
    """
    integrator = load_simulation(path)[0].model.integrator
    sims = {}
    for name, (law, options) in SCENE_VARIANTS.items():
        sim = _load(path, integrator, **law, **options)
        sim.run(steps=10)  # compiles and builds the pair list outside the timing
        sims[name] = sim
    times = {name: [] for name in sims}
    for _ in range(repeats):
        for name, sim in sims.items():
            t0 = time.process_time()
            sim.run(steps=steps)
            times[name].append(time.process_time() - t0)
    study = sims["study"]
    out = {"n": study.n, "contacts": read_state(path).sizes["contact"],
           "threads": numba.get_num_threads()}
    for name, t in times.items():
        out[name] = float(np.median(t)) / steps / study.n * 1e9
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


def main(sizes=(3000, 10000), steps=200, repeats=5, integrators=("verlet", "gear"),
         threads=(1, 2), cache=Path(".bench"), state=None, peer=None):
    """Run the benchmark; print a table and a final JSON line.

    Parameters
    ----------
    sizes : tuple of int
        Particle counts of the loaded piles (built once, kept in ``cache``).
    steps, repeats : int
        Steps per timing and timings per figure (the median is reported).
    integrators : tuple of str
    threads : tuple of int
        Thread counts; those above ``NUMBA_NUM_THREADS`` are skipped.
    cache : Path
        Folder of the benchmark piles.
    state : str or Path, optional
        Time this state file instead of the built piles.
    peer : None, str or tuple of str
        Peers among :data:`PEERS` to time in this run, each on as many MPI
        ranks as threads, giving each row its ratio to them: ``"lammps"``, a
        LAMMPS disk pile of each N (:mod:`sim.numerics.lammps_peer`);
        ``"lammps-polygons"``, LAMMPS's rounded polygons of each pile
        (:mod:`sim.numerics.lammps_polygons`).

    Returns
    -------
    list of dict
        The rows of :func:`measure` (with the ratios to the peer).
    """
    unknown = sorted(set(integrators) - set(INTEGRATORS))
    if unknown:
        raise ValueError(f"bench integrators {unknown}: must be among {sorted(INTEGRATORS)}")
    peers_asked = (peer,) if isinstance(peer, str) else tuple(peer or ())
    unknown = sorted(set(peers_asked) - set(PEERS))
    if unknown:
        raise ValueError(f"bench --peer {unknown}: must be among {list(PEERS)}")
    if "lammps" in peers_asked:  # before any pile is built
        lammps_peer.find_lmp()
    if "lammps-polygons" in peers_asked:
        lammps_polygons.find_lmp()
    paths = [Path(state)] if state else [loaded_pile(n, cache=cache) for n in sizes]
    rows = []
    print(f"{'N':>6} {'integrator':>10} {'thr':>3} {'contacts/N':>10} {'ns/p-step':>9} "
          f"{'ns/contact':>10} {'cores':>5} {'predict':>7} {'pairs':>6} {'gather':>6} "
          f"{COST_HEADER} {'refreshes':>12} {'rms mm/s':>11}", flush=True)
    for path in paths:
        for integrator in integrators:
            for t in threads:
                if t > numba.config.NUMBA_NUM_THREADS:
                    log.warning("bench: %d threads skipped (NUMBA_NUM_THREADS = %d)", t,
                                numba.config.NUMBA_NUM_THREADS)
                    continue
                r = measure(path, integrator, t, steps, repeats)
                rows.append(r)
                print(f"{r['n_particles']:>6} {integrator:>10} {t:>3} "
                      f"{r['contacts_per_particle']:>10.2f} {r['ns_per_particle_step']:>9.1f} "
                      f"{r['ns_per_contact']:>10.1f} {r['cores_used']:>5.2f} "
                      f"{r['share_predict']:>7.0%} {r['share_pairs']:>6.0%} "
                      f"{r['share_gather']:>6.0%} {_cost_columns(r, 'cpu_ns_per_particle_step')} "
                      f"{_per_steps(r['list_refreshes'], steps):>12} "
                      f"{_speeds(r['rms_speed']):>11}", flush=True)
    (peers, failed), (polygon_peers, polygons_failed) = (
        _time_peer(name, paths, threads, steps, repeats, cache) if name in peers_asked
        else ([], []) for name in PEERS)
    rows = lammps_peer.ratios(lammps_peer.ratios(rows, peers), polygon_peers, "lammps_polygons")
    for r in rows:
        for name, key in (("disks", "ratio_to_lammps"), ("polygons", "ratio_to_lammps_polygons")):
            if key in r:
                print(f"against LAMMPS {name}, N = {r['n_particles']}, {r['integrator']}, "
                      f"{r['threads']} thread(s)/rank(s): {r[key]:.2f}x per "
                      f"particle-step, {r[key + '_per_contact']:.2f}x per contact, "
                      f"{r[key + '_per_simulated_s']:.2f}x CPU per simulated second")
    if polygon_peers:
        print("(LAMMPS's polygons are frictionless, their contact force linear in the depth "
              "of each vertex: the ratios compare codes on like piles, not the same physics)")
    derived = derived_figures(rows)
    for r in derived["parallel_efficiency"]:
        print(f"parallel efficiency, N = {r['n_particles']}, {r['integrator']}, "
              f"{r['threads']} threads: {r['efficiency']:.0%}")
    for r in derived["size_ratio"]:
        print(f"cost per particle-step at N = {r['n_particles']} against N = "
              f"{r['against_n']}, {r['integrator']}, {r['threads']} thread(s): {r['ratio']:.2f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"bench": rows, **derived, "lammps": peers,
                      "lammps_polygons": polygon_peers, "lammps_failures": failed,
                      "lammps_polygons_failures": polygons_failed, "peak_rss_bytes": peak,
                      "threads_available": numba.config.NUMBA_NUM_THREADS}))
    return rows


#: How each peer of :data:`PEERS` times the pile of a :class:`Simulation` on
#: ``t`` MPI ranks: ``timer(sim, t, steps, repeats, cache)``; the polygon
#: peer's bodies settle to the rms speed of the pile as loaded (:func:`rms_speed`).
PEER_TIMERS = {
    "lammps": lambda sim, t, steps, repeats, cache: lammps_peer.time_peer(
        sim.shapes, t, sim.dt, sim.skin, sim.model, steps, repeats, cache),
    "lammps-polygons": lambda sim, t, steps, repeats, cache: lammps_polygons.time_peer(
        sim.shapes, sim.theta, t, sim.dt, sim.skin, sim.model, steps, repeats, cache,
        rms_speed(sim)),
}

#: Header of the cost columns of both tables (:func:`_cost_columns`).
COST_HEADER = f"{'dt µs':>6} {'CPU ns/p-step':>13} {'CPU s/sim s':>11} {'CPU ms/p/sim s':>14}"
#: LAMMPS's sections of its timing breakdown, as the peers' table shows them.
SECTIONS = ("pair", "neigh", "comm", "modify", "output", "other")


def _cost_columns(r, cpu_key):
    """The cost columns of a row: its step, CPU ns per particle-step (``r[cpu_key]``)
    and the cost per simulated second (:func:`cost_per_simulated_second`)."""
    return (f"{r['dt'] * 1e6:>6.2f} {r[cpu_key]:>13.1f} {r['cpu_s_per_simulated_s']:>11.0f} "
            f"{r['cpu_s_per_particle_simulated_s'] * 1e3:>14.2f}")


def _per_steps(counts, steps):
    """List rebuilds (or refreshes) in the timed runs: ``total/steps in all``."""
    return f"{sum(counts)}/{steps * len(counts)}"


def _speeds(speeds):
    """rms speeds (m/s) at the start and end of a timing, in mm/s."""
    return "→".join(f"{v * 1e3:.2g}" for v in speeds)


def _time_peer(peer, paths, threads, steps, repeats, cache):
    """The peer ``peer`` (:data:`PEER_TIMERS`) for each pile, at its time step and
    skin, on each thread count as MPI ranks (settled once, kept in ``cache``);
    printed as a table under a line naming its LAMMPS build, with LAMMPS's
    neighbour-list builds and timing breakdown.  Its figures are keyed by the
    peer's name with ``_`` (``lammps_polygons_ns_per_particle_step``); each row
    gains the cost per simulated second (:func:`cost_per_simulated_second`).
    A pile the peer fails on (LAMMPS failed, or its box did not settle in
    time) gets no row: the failure is printed and the bench goes on.

    Returns
    -------
    (list of dict, list of dict)
        The rows, and the failures (``n_particles``, ``ranks``, ``error``).
    """
    key = peer.replace("-", "_")
    header = (f"{'N':>6} {'peer':>16} {'rk':>3} {'contacts/N':>10} {'ns/p-step':>9} "
              f"{'ns/contact':>10} {COST_HEADER} {'rebuilds':>10} "
              + " ".join(f"{s:>6}" for s in SECTIONS) + f" {'rms mm/s':>11}")
    peers, failures = [], []
    for path in paths:
        sim = _load(path, "verlet")
        for t in threads:
            try:
                p = PEER_TIMERS[peer](sim, t, steps, repeats, cache)
            except RuntimeError as exc:
                log.warning("bench: no %s row for N = %d on %d rank(s): %s", peer, sim.n, t, exc)
                print(f"{sim.n:>6} {peer:>16} {t:>3} no row: {exc}", flush=True)
                failures.append({"n_particles": sim.n, "ranks": t, "error": str(exc)})
                continue
            p.update(cost_per_simulated_second(p[key + "_cpu_ns_per_particle_step"],
                                               p["n_particles"], p["dt"]))
            if not peers:
                print(f"{peer}: {lammps_peer.build_line(p['lammps_build'])}", flush=True)
                print(header, flush=True)
            peers.append(p)
            print(f"{p['n_particles']:>6} {peer:>16} {t:>3} "
                  f"{p['contacts_per_particle']:>10.2f} "
                  f"{p[key + '_ns_per_particle_step']:>9.1f} "
                  f"{p[key + '_ns_per_contact']:>10.1f} "
                  f"{_cost_columns(p, key + '_cpu_ns_per_particle_step')} "
                  f"{_per_steps(p['neighbor_builds'], steps):>10} "
                  + " ".join(f"{p['breakdown'].get(s, 0.0):>6.1%}" for s in SECTIONS)
                  + f" {_speeds(p['rms_speed']):>11}", flush=True)
            if p.get("settle"):
                print(f"{'':>6} settled: {_settle_line(p['settle'])}", flush=True)
    return peers, failures


def _settle_line(settle):
    """What the settling of a polygon peer's box reached (:func:`sim.numerics.lammps_polygons.settle_report`)."""
    target = settle["target_rms_speed"]
    return (f"{settle['settle_time']:.2f} s simulated ({settle['rounds']} more rounds), rms "
            f"{_speeds(settle['rms_speed'])} mm/s after each, target (ours as loaded) "
            + ("none" if target is None else f"{target * 1e3:.2g} mm/s")
            + (": reached" if settle["reached"] else ": NOT REACHED, timed as it is"))


def derived_figures(rows):
    """The figures the bench's targets are stated in, from the rows of :func:`measure`.

    * parallel efficiency of each row on more than one thread: the 1-thread
      time of the same pile and integrator over (threads × its time);
    * cost across sizes: each row's ns per particle-step over that of the
      smallest pile with the same integrator and threads (1.0: flat in N).

    Parameters
    ----------
    rows : list of dict

    Returns
    -------
    dict
        ``parallel_efficiency`` and ``size_ratio``: lists of dicts.
    """
    def key(r, **change):
        return (change.get("n", r["n_particles"]), r["integrator"],
                change.get("threads", r["threads"]))

    cost = {key(r): r["ns_per_particle_step"] for r in rows}
    efficiency = [
        {"n_particles": r["n_particles"], "integrator": r["integrator"],
         "threads": r["threads"],
         "efficiency": cost[key(r, threads=1)] / (r["threads"] * r["ns_per_particle_step"])}
        for r in rows if r["threads"] > 1 and key(r, threads=1) in cost]
    sizes = sorted({r["n_particles"] for r in rows})
    ratio = [
        {"n_particles": r["n_particles"], "against_n": sizes[0],
         "integrator": r["integrator"], "threads": r["threads"],
         "ratio": r["ns_per_particle_step"] / cost[key(r, n=sizes[0])]}
        for r in rows if r["n_particles"] != sizes[0] and key(r, n=sizes[0]) in cost]
    return {"parallel_efficiency": efficiency, "size_ratio": ratio}
