"""The simulator skips the work a scene does not need, and skipping changes nothing:
no damping force with γ = 0, no tangential force or spring history with μ = 0,
no body contacts without bodies, no orientation update with rotation fixed."""

import numpy as np
import pytest

from sim.config import ConfigError, ModelParams, PhysicsParams, ProbeParams, SimConfig
from sim.engine import Simulation
from sim.pour import pour
from sim.shapes import make_shapes

from scenes import regular_polygon, scene

N = 30


def _heap(model, rotate=True, n=N, seed=4, full_law=False):
    """n polygons dropped in rows of six between walls onto the support
    (every term of the contact law computed with `full_law`)."""
    shapes = make_shapes(np.random.default_rng(seed), n)
    d = 2.0 * float(shapes.radius.max())
    sim = Simulation(shapes, model, gravity=(0.0, -9.81), walls=(-3.3 * d, 3.3 * d),
                     rotate=rotate, full_law=full_law)
    for k in range(n):
        row, col = divmod(k, 6)
        sim.place(k, (col - 2.5 + 0.3 * (row % 2)) * d, (0.6 + 1.05 * row) * d, 0.37 * k,
                  0.05 * ((-1) ** k), -0.2)
    return sim


def _run_colliding(sim, duration=0.1, chunks=20):
    """Run ``sim``; the particle pairs and the particles on the support seen in contact."""
    pairs, on_support = set(), set()
    for _ in range(chunks):
        sim.run(duration=duration / chunks)
        c = sim.contacts()
        pairs |= set(zip(c["i"][c["j"] >= 0], c["j"][c["j"] >= 0]))
        on_support |= set(c["i"][c["j"] == -1])
    return pairs, on_support


@pytest.mark.parametrize("law", [
    {"friction": 0.0, "support_friction": 0.0},
    {"friction": 0.0},
    {"damping": 0.0},
    {"friction": 0.0, "support_friction": 0.0, "damping": 0.0},
], ids=["frictionless", "frictionless pairs", "undamped", "neither"])
def test_skipping_zero_terms_retraces_the_full_law_bit_for_bit(law):
    """A term whose coefficient is zero is skipped; the trajectory of a falling,
    colliding heap is the same, bit for bit, as with every term computed."""
    runs = []
    for full_law in (False, True):
        sim = _heap(ModelParams(**law), full_law=full_law)
        pairs, on_support = _run_colliding(sim)
        runs.append((sim.r[:, :, :sim.n].copy(), sim.contacts()))
    (r_fast, c_fast), (r_full, c_full) = runs
    assert len(pairs) > N // 2 and on_support    # collisions, and with the support
    np.testing.assert_array_equal(r_fast, r_full)
    for key in ("i", "j", "fx", "fy", "area", "spring"):
        np.testing.assert_array_equal(c_fast[key], c_full[key], err_msg=key)


def test_frictionless_contacts_keep_no_spring_and_push_along_the_normal():
    sim = _heap(ModelParams(friction=0.0, support_friction=0.0))
    _run_colliding(sim)
    c = sim.contacts()
    assert len(c["i"]) > 0
    assert not np.any(c["spring"])
    # the force is normal: no component along the tangent (-n_y, n_x)
    tangential = -c["fx"] * c["ny"] + c["fy"] * c["nx"]
    assert np.max(np.abs(tangential)) <= 1e-12 * np.max(np.hypot(c["fx"], c["fy"]))


def test_without_a_support_nothing_happens_below_y0():
    """A particle placed across y = 0 with no support feels nothing and keeps
    its state exactly; the same particle with the support is pushed out."""
    hexagon = regular_polygon(6, 3e-3)
    alone = scene([hexagon], [(0.0, -1e-3, 0.2, 0.0, 0.0, 0.0)])
    alone.run(steps=500)
    assert len(alone.contacts()["i"]) == 0
    np.testing.assert_array_equal(alone.position, [[0.0, -1e-3]])
    np.testing.assert_array_equal(alone.velocity, [[0.0, 0.0]])
    assert alone.theta[0] == 0.2
    supported = scene([hexagon], [(0.0, -1e-3, 0.2, 0.0, 0.0, 0.0)], support=True)
    supported.run(steps=500)
    assert supported.velocity[0, 1] > 0.0


def test_fixed_rotation_keeps_every_orientation_exactly():
    """Released with spin, colliding and piling up: with rotation fixed every θ
    stays what it was placed with, bit for bit, and no particle spins."""
    fixed = _heap(ModelParams(), rotate=False)
    theta0 = fixed.theta.copy()
    pairs, _ = _run_colliding(fixed)
    np.testing.assert_array_equal(fixed.theta, theta0)
    assert not np.any(fixed.omega)
    assert len(pairs) > N
    free = _heap(ModelParams())
    free.run(duration=0.1)
    assert np.max(np.abs(free.theta - theta0)) > 1e-3        # the same heap does rotate


def test_a_spin_given_to_a_fixed_particle_is_dropped():
    hexagon = regular_polygon(6, 3e-3)
    sim = scene([hexagon], [(0.0, 0.01, 0.2, 0.1, 0.0, 50.0)], gravity=(0.0, -9.81),
                rotate=False)
    sim.run(steps=200)
    assert sim.theta[0] == 0.2 and sim.omega[0] == 0.0
    assert sim.position[0, 0] > 0.0


@pytest.mark.parametrize("physics, words", [
    ({"walls": [0.1, -0.1]}, ["physics.walls", "x_left must be < x_right"]),
    ({"walls": [0.1]}, ["physics.walls", "[x_left, x_right]"]),
    ({"rotation": "no"}, ["physics.rotation", "'no'", "true or false"]),
    ({"gravity": 1}, ["physics", "'gravity'", "allowed", "rotation"]),
])
def test_bad_physics_names_the_setting(physics, words):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"physics": physics})
    for w in words:
        assert w in str(err.value)


def test_physics_reaches_the_simulation_and_no_probe_is_allowed(tmp_path):
    from sim.config import ParticleParams, PourParams
    from sim.io import read_state

    assert ProbeParams(levels=[]).levels == ()
    cfg = SimConfig(pour=PourParams(n_particles=3, rate=200.0),
                    particles=ParticleParams(),
                    physics=PhysicsParams(walls=(-0.05, 0.05), rotation=False))
    sim = pour(cfg, "wedge", 1, tmp_path / "poured.nc", settle_time=0.01)
    assert not sim.rotate and sim.walls == (-0.05, 0.05)
    ds = read_state(tmp_path / "poured.nc")
    assert ds.attrs["rotate"] == 0 and ds.attrs["wall_left"] == -0.05
    no_support = SimConfig(physics=PhysicsParams(support=False))
    with pytest.raises(ConfigError, match="physics.support = false"):
        pour(no_support, "wedge", 1, tmp_path / "never.nc")
    assert not (tmp_path / "never.nc").exists()


def test_scene_bench_times_every_variant_from_the_same_state(tmp_path):
    from sim.numerics.bench import SCENE_VARIANTS, scene_costs
    from sim.io import save_state

    sim = _heap(ModelParams())
    _run_colliding(sim, duration=0.05, chunks=5)
    save_state(sim, tmp_path / "heap.nc", protocol="test", seed=4)
    costs = scene_costs(tmp_path / "heap.nc", steps=5, repeats=1)
    assert costs["n"] == N and costs["contacts"] == len(sim.contacts()["i"]) > 0
    assert all(costs[name] > 0 for name in SCENE_VARIANTS)
