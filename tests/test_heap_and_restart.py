"""A small heap at rest (force balance) and exact restarts from state files."""

import numpy as np
import pytest

from sim.config import ModelParams
from sim.engine import Simulation
from sim.io import load_simulation, save_state
from sim.config import RelaxParams, SimConfig
from sim.relax import relax
from sim.shapes import make_shapes


def _heap(n=24, seed=3, damping=0.5):
    shapes = make_shapes(np.random.default_rng(seed), n)
    sim = Simulation(shapes, ModelParams(damping=damping), gravity=(0.0, -9.81))
    d = 2.0 * float(shapes.radius.max())
    for k in range(n):
        row, col = divmod(k, 6)
        sim.place(k, (col - 2.5 + 0.5 * (row % 2)) * d * 0.9, (0.5 + row * 0.85) * d,
                  0.37 * k)
    return sim


@pytest.fixture(scope="module")
def heap():
    """The heap relaxed by the protocol's relaxation (with its background drag)."""
    sim = _heap()
    cfg = SimConfig(relax=RelaxParams(kinetic_energy_fraction=1e-12, max_speed=1e-6,
                                      hold_time=0.02, max_time=4.0))
    relax(sim, cfg)
    assert sim.drag == 0.0
    return sim


def test_heap_at_rest_balances_forces(heap):
    """Every particle's net force is small against its weight."""
    weight = heap.shapes.mass[:heap.n] * 9.81
    net = np.hypot(*heap.net_forces().T)
    assert np.max(net / weight) < 1e-3


def test_support_carries_the_weight(heap):
    c = heap.contacts()
    support = c["j"] == -1
    # force_y acts on the particle; the support receives the opposite
    reaction = float(np.sum(c["fy"][support]))
    weight = float(np.sum(heap.shapes.mass[:heap.n]) * 9.81)
    assert reaction == pytest.approx(weight, rel=1e-4)
    assert np.count_nonzero(c["j"] >= 0) > heap.n  # a connected heap, not a layer


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_restart_continues_the_same_trajectory(tmp_path, integrator):
    """Saving mid-run and continuing from the file retraces the run bit for bit."""
    sim = _heap(n=18, seed=5, damping=0.1)
    sim.model = ModelParams(damping=0.1, integrator=integrator)
    sim = Simulation(sim.shapes, sim.model, gravity=(0.0, -9.81))
    ref = _heap(n=18, seed=5, damping=0.1)
    for k in range(18):
        sim.place(k, *ref.position[k], ref.theta[k])
    sim.run(duration=0.02)           # particles falling and colliding
    path = tmp_path / "mid.nc"
    save_state(sim, path, protocol="test", seed=5)
    sim.run(steps=3000)
    again, _ = load_simulation(path)
    assert again.dt == sim.dt
    again.run(steps=3000)
    assert again.time == pytest.approx(sim.time, rel=1e-14)
    np.testing.assert_array_equal(again.r[:, :, :18], sim.r[:, :, :18])


def test_state_file_has_contract_variables(tmp_path, heap):
    import xarray as xr
    path = tmp_path / "s.nc"
    save_state(heap, path, {"model": {}}, protocol="wedge", seed=1)
    ds = xr.open_dataset(path)
    for v in ["x", "y", "theta", "vx", "vy", "omega", "mass", "inertia", "area",
              "node_count", "node_x", "node_y", "contact_i", "contact_j", "contact_x",
              "contact_y", "force_x", "force_y", "normal_x", "normal_y", "overlap_area"]:
        assert v in ds, v
        assert "units" in ds[v].attrs and "long_name" in ds[v].attrs, v
    for a in ["Conventions", "title", "source", "history", "config", "time", "gravity",
              "protocol", "seed", "youngs_modulus", "damping", "friction", "density", "dt",
              "integrator"]:
        assert a in ds.attrs, a
    assert int(ds.node_count.sum()) == ds.sizes["node"]
    n = ds.sizes["particle"]
    assert ds.contact_i.min() >= 0 and ds.contact_i.max() < n
    normals = np.hypot(ds.normal_x, ds.normal_y)
    assert np.allclose(normals, 1.0)
    # mass follows the stored corners and density
    assert np.allclose(ds.mass, ds.area * ds.attrs["density"])


def compare_parallel_and_serial_kernels():
    """Run a packing on 2 threads and on the serial kernels; raise unless equal."""
    import numba
    from sim.numerics.bench import dense_packing

    runs = []
    for threads in (2, 1):
        numba.set_num_threads(threads)
        sim = dense_packing(600, seed=2)
        assert sim.n >= sim.parallel_threshold
        sim.run(duration=0.002)
        runs.append(sim.r[:, :, :sim.n].copy())
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    np.testing.assert_array_equal(runs[0], runs[1])


def test_parallel_and_serial_kernels_agree_bit_for_bit():
    """No write races: 2 threads and the serial kernels give the same
    trajectory (in a process of its own when this one has a single thread)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import numba

    if numba.config.NUMBA_NUM_THREADS >= 2:
        compare_parallel_and_serial_kernels()
        return
    proc = subprocess.run(
        [sys.executable, "-c",
         "import test_heap_and_restart as t; t.compare_parallel_and_serial_kernels()"],
        cwd=Path(__file__).parent, env={**os.environ, "NUMBA_NUM_THREADS": "2"},
        capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-5000:]
