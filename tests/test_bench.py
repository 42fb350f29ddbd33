"""The bench's derived figures: parallel efficiency, cost across sizes and per simulated second."""

import pytest

from sim.numerics.bench import cost_per_simulated_second, derived_figures
from sim.numerics.lammps_peer import ratios


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


def test_cost_per_simulated_second_is_the_cost_per_step_over_the_step():
    # 160 CPU ns per particle-step at a step of 6.4 µs: 25 ms per particle per
    # simulated second, 250 CPU s per simulated second of 10 000 particles
    cost = cost_per_simulated_second(160.0, 10000, 6.4e-6)
    assert cost["cpu_s_per_particle_simulated_s"] == pytest.approx(0.025)
    assert cost["cpu_s_per_simulated_s"] == pytest.approx(250.0)
    # half the step costs twice as much per simulated second
    assert cost_per_simulated_second(160.0, 10000, 3.2e-6)["cpu_s_per_simulated_s"] == \
        pytest.approx(500.0)


def test_ratio_per_simulated_second_compares_cpu_time_at_each_codes_step():
    ours = {"n_particles": 3000, "threads": 1, "ns_per_particle_step": 300.0,
            "ns_per_contact": 170.0, **cost_per_simulated_second(150.0, 3000, 6e-6)}
    peer = {"n_particles": 3000, "ranks": 1, "lammps_ns_per_particle_step": 100.0,
            "lammps_ns_per_contact": 85.0, **cost_per_simulated_second(100.0, 3000, 1.2e-5)}
    out = ratios([ours], [peer])[0]
    assert out["ratio_to_lammps"] == pytest.approx(3.0)  # wall, per particle-step
    # CPU: 150 ns per 6 µs against 100 ns per 12 µs
    assert out["ratio_to_lammps_per_simulated_s"] == pytest.approx(3.0)
    assert "ratio_to_lammps_per_simulated_s" not in ratios(
        [{k: v for k, v in ours.items() if not k.startswith("cpu_s")}], [peer])[0]


def test_a_peer_failing_on_one_pile_is_reported_and_the_bench_goes_on(monkeypatch, capsys):
    from types import SimpleNamespace

    from sim.numerics import bench
    monkeypatch.setattr(bench, "_load", lambda path, integrator: SimpleNamespace(n=300))

    def timer(sim, t, steps, repeats, cache):
        if t == 2:
            raise RuntimeError("LAMMPS polygon peer: 300 polygons not settled")
        return {"n_particles": 300, "ranks": t, "contacts_per_particle": 1.6, "dt": 7e-6,
                "lammps_ns_per_particle_step": 80.0, "lammps_cpu_ns_per_particle_step": 70.0,
                "lammps_ns_per_contact": 50.0, "neighbor_builds": [0, 1],
                "breakdown": {"pair": 0.5, "modify": 0.4, "other": 0.1},
                "rms_speed": [1e-3, 2e-3],
                "lammps_build": {"version": "29 Sep 2021 - Update 2", "path": "lmp",
                                 "compiler": "GNU", "mpi": "MPI", "accelerators": [],
                                 "flags": [], "packages": ["GRANULAR"]}}
    monkeypatch.setitem(bench.PEER_TIMERS, "lammps", timer)
    rows, failures = bench._time_peer("lammps", ["pile.nc"], (1, 2), 200, 2, None)
    assert [r["ranks"] for r in rows] == [1]
    assert rows[0]["cpu_s_per_particle_simulated_s"] == pytest.approx(70e-9 / 7e-6)
    assert failures == [{"n_particles": 300, "ranks": 2,
                         "error": "LAMMPS polygon peer: 300 polygons not settled"}]
    out = capsys.readouterr().out
    assert "LAMMPS 29 Sep 2021 - Update 2" in out and "no row: LAMMPS polygon peer" in out
    assert "1/400" in out  # neighbour-list builds in the timed steps
