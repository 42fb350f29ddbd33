"""The bench's derived figures: parallel efficiency and cost across sizes."""

import pytest

from sim.numerics.bench import derived_figures


def _row(n, integrator, threads, ns):
    return {"n_particles": n, "integrator": integrator, "threads": threads,
            "ns_per_particle_step": ns}


def test_parallel_efficiency_and_size_ratio_from_the_rows():
    rows = [_row(3000, "verlet", 1, 240.0), _row(3000, "verlet", 2, 150.0),
            _row(30000, "verlet", 1, 264.0), _row(30000, "verlet", 2, 120.0),
            _row(3000, "gear", 2, 200.0)]  # no 1-thread gear row: no efficiency
    d = derived_figures(rows)
    eff = {(r["n_particles"], r["integrator"]): r["efficiency"]
           for r in d["parallel_efficiency"]}
    # 240 ns on one thread, 150 ns on two: 240 / (2 x 150) = 0.8
    assert eff == {(3000, "verlet"): pytest.approx(0.8), (30000, "verlet"): pytest.approx(1.1)}
    ratio = {(r["n_particles"], r["threads"]): r["ratio"] for r in d["size_ratio"]}
    assert ratio == {(30000, 1): pytest.approx(1.1), (30000, 2): pytest.approx(0.8)}
    assert all(r["against_n"] == 3000 for r in d["size_ratio"])
