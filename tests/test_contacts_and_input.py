"""Contact-law properties, the broad phase, the time-step rule and bad input."""

import dataclasses

import numpy as np
import pytest
import yaml

from scenes import rectangle, regular_polygon, scene, shapes_of
from sim.broadphase import candidate_pairs
from sim.config import ConfigError, ModelParams, SimConfig
from sim.contact_law import characteristic_length, normal_force, tangential_force
from sim.engine import BlowUpError, Simulation
from sim.io import StateFileError, load_simulation, save_state
from sim.shapes import make_shapes


def _contact_on_first(polygons, states):
    """Force, point and area of the contact seen by particle 0 after one step."""
    sim = scene(polygons, states, youngs_modulus=1e7, damping=0.3, friction=0.5,
                max_overlap_fraction=0.9)
    sim.run(steps=1)
    c = sim.contacts()
    assert len(c["i"]) == 1
    sign = 1.0 if c["i"][0] == 0 else -1.0
    return sign * np.array([c["fx"][0], c["fy"][0]]), np.array([c["x"][0], c["y"][0]]), \
        c["area"][0]


@pytest.mark.parametrize("seed", range(5))
def test_newtons_third_law_per_contact(seed):
    """Numbering the pair the other way round gives the opposite force at the same point."""
    rng = np.random.default_rng(seed)
    polys = [rectangle(5e-3, 3e-3), regular_polygon(6, 3e-3, rng.uniform(0, 1))]
    states = [(0, 0, rng.uniform(0, 6), *rng.normal(0, 0.1, 2), rng.normal(0, 5)),
              (3.8e-3, rng.uniform(-1e-3, 1e-3), rng.uniform(0, 6), *rng.normal(0, 0.1, 2),
               rng.normal(0, 5))]
    f_a, s_a, area_a = _contact_on_first(polys, states)
    f_b, s_b, area_b = _contact_on_first(polys[::-1], states[::-1])
    # in the second scene particle 0 is the hexagon: it feels the opposite force
    scale = np.hypot(*f_a)
    assert scale > 0
    assert np.all(np.abs(f_a + f_b) < 1e-9 * scale)
    assert np.allclose(s_a, s_b, rtol=0, atol=1e-15)
    assert area_a == pytest.approx(area_b, rel=1e-12)


def test_normal_force_never_attracts():
    """On separation the damping is clamped at -F⊥ (Appendix (ii))."""
    for rate in np.linspace(-1.0, 1.0, 41):
        f_el, total = normal_force(1e-9, rate * 1e-3, 1e-3, 0.02, 1e7, 5.0)
        assert total >= 0.0
        assert f_el == pytest.approx(1e7 * 1e-9 / 1e-3)
        if rate > 0:
            assert total > f_el


@pytest.mark.parametrize("rate", [-1e-3, -1e-5, -1e-7, 0.0, 1e-5])
def test_normal_damping_is_the_appendix_value_clamped_at_minus_the_elastic_force(rate):
    """Total = F + D* with D* = gamma sqrt(Y m) dA/dt / l, but never below 0:
    a fast separation gives exactly 0, a slow one the undamped value less D*."""
    area, l, m, Y, gamma = 1e-9, 1e-3, 0.02, 1e7, 5.0
    f_el, total = normal_force(area, rate, l, m, Y, gamma)
    expected = Y * area / l + gamma * np.sqrt(Y * m) * rate / l
    assert total == pytest.approx(max(expected, 0.0), rel=1e-12, abs=1e-300)
    if expected < 0:
        assert total == 0.0


def test_pair_history_is_carried_across_a_rebuild():
    """The tangential springs of pairs kept by a new pair list keep their
    value; new pairs start at zero (both lists sorted by (i, j))."""
    from sim.broadphase import carry_history

    old_i, old_j = np.array([0, 0, 1, 2]), np.array([1, 3, 2, 5])
    new_i, new_j = np.array([0, 1, 1, 2, 4]), np.array([3, 2, 4, 5, 6])
    carried = carry_history(old_i, old_j, np.array([1.5, -2.5, 3.5, 4.5]), new_i, new_j)
    np.testing.assert_array_equal(carried, [-2.5, 3.5, 0.0, 4.5, 0.0])


def test_tangential_force_capped_and_opposes_sliding():
    f_el = 2.0
    mu = 0.4
    spring = 0.0
    for _ in range(200):  # steady sliding in +t: spring saturates at mu F
        total, spring = tangential_force(spring, 0.01, f_el, 0.01, 1e7, mu, 1e-6)
        assert abs(total) <= mu * f_el * (1 + 1e-12)
    assert total == pytest.approx(mu * f_el)      # acts on i as -T t: opposes sliding
    assert spring == pytest.approx(mu * f_el)
    total, spring = tangential_force(spring, -0.01, f_el, 0.01, 1e7, mu, 1e-6)
    assert total < mu * f_el  # reversal unloads the spring first


def test_broad_phase_finds_every_close_pair():
    """Cell list against brute force, including a particle far from the rest."""
    rng = np.random.default_rng(7)
    n = 600
    x = rng.uniform(0, 0.15, n)
    y = rng.uniform(0, 0.15, n)
    x[0], y[0] = 40.0, -3.0
    radius = rng.uniform(2e-3, 4e-3, n)
    skin = 1e-3
    pi, pj = candidate_pairs(x, y, radius, n, skin)
    d = np.hypot(x[:, None] - x[None], y[:, None] - y[None])
    reach = radius[:, None] + radius[None] + skin
    bi, bj = np.nonzero(np.triu(d < reach, 1))
    assert list(zip(pi, pj)) == list(zip(bi, bj))  # same pairs, same (i, j) order


def test_given_dt_beyond_stability_limit_is_refused():
    shapes = make_shapes(np.random.default_rng(0), 5)
    limit = Simulation(shapes, ModelParams()).bound.dt_limit
    with pytest.raises(ValueError, match="stability limit"):
        Simulation(shapes, ModelParams(dt=1.5 * limit))
    Simulation(shapes, ModelParams(dt=0.9 * limit))


def test_blow_up_is_detected_and_last_good_state_kept():
    """A resting block stepped far beyond its stability (forced past the check) blows up.

    The rule's limit is a bound over the worst contact of two particles; for a
    block on the support the real limit is several times larger, so the step
    is made 40 times the automatic one."""
    sim = scene([rectangle(4e-3, 4e-3)], [(0, 2e-3 - 1e-7, 0, 0, 0, 0)], gravity=(0, -9.81),
                support=True)
    sim.run(steps=200)            # at rest on the support: its contact is evaluated
    sim.dt *= 40.0
    sim.r *= 40.0 ** np.arange(sim.r.shape[0])[:, None, None]
    with pytest.raises(BlowUpError, match="unstable") as err:
        sim.run(steps=20000)
    assert np.all(np.isfinite(sim.r[:, :, :2]))
    assert err.value.last_good.time == sim.time
    # the contacts reported (and saved as *.lastgood.nc) are those of the good
    # state's positions, not of the step that failed
    c = sim.contacts()
    assert len(c["i"]) == 1 and np.all(np.isfinite(c["fx"]))
    x, y = sim.position[0]
    assert np.hypot(c["x"][0] - x, c["y"][0] - y) <= sim.shapes.radius[0]
    assert c["area"][0] <= sim.model.max_overlap_fraction * sim.shapes.area[0]
    assert c["area"][0] == pytest.approx(4e-3 * max(0.0, -float(np.min(
        y + sim.shapes.node_x[:4] * np.sin(sim.theta[0]) + sim.shapes.node_y[:4] *
        np.cos(sim.theta[0])))), rel=0.05)


@pytest.mark.parametrize("section,key,value,message", [
    ("model", "youngs_modulus", -1.0, "model.youngs_modulus = -1.0: must be > 0"),
    ("model", "youngs_modulus", 0.0, "must be > 0"),
    ("model", "friction", -0.1, "model.friction = -0.1: must be >= 0"),
    ("model", "integrator", "rk4", "must be one of 'gear', 'verlet'"),
    ("model", "dt", "1e-6", "must be a number"),
    ("particles", "corners_min", 2, "particles.corners_min = 2: must be >= 3"),
    ("probe", "levels", [1.5], "probe.levels[] = 1.5: must be > 0 and < 1"),
])
def test_bad_settings_are_refused(section, key, value, message):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({section: {key: value}})
    assert message.split(":")[0].split(" = ")[0] in str(err.value)
    assert message.split(": ")[-1] in str(err.value) or message in str(err.value)


def test_unknown_setting_is_refused():
    with pytest.raises(ConfigError, match="unknown setting.*fricton"):
        SimConfig.from_dict({"model": {"fricton": 0.3}})


def test_non_convex_and_self_intersecting_polygons_are_refused():
    arrow = (np.array([0, 2, 1, 2, 0.0]) * 1e-3 - 1e-3, np.array([0, 0, 1, 2, 2.0]) * 1e-3 - 1e-3)
    with pytest.raises(ValueError, match="particle 1"):
        shapes_of(rectangle(2e-3, 2e-3), arrow)
    bowtie = (np.array([-1, 1, -1, 1.0]) * 1e-3, np.array([-1, 1, 1, -1.0]) * 1e-3)
    with pytest.raises(ValueError, match="self-intersect"):
        shapes_of(bowtie)


def test_nan_in_state_file_is_refused(tmp_path):
    import xarray as xr
    sim = scene([rectangle(4e-3, 4e-3)], [(0, 0.01, 0, 0, 0, 0)], gravity=(0, -9.81),
                support=True)
    path = tmp_path / "s.nc"
    save_state(sim, path)
    ds = xr.open_dataset(path).load()
    ds["vy"][0] = np.nan
    bad = tmp_path / "bad.nc"
    ds.to_netcdf(bad)
    with pytest.raises(StateFileError, match="vy holds NaN"):
        load_simulation(bad)


def test_config_defaults_match_the_workflow_schema():
    """The simulator's defaults and the workflow schema's agree, setting by setting."""
    with open("workflow/schemas/config.schema.yaml") as f:
        schema = yaml.safe_load(f)
    defaults = SimConfig().to_dict()
    for section, values in defaults.items():
        props = schema["properties"][section]["properties"]
        assert set(props) == set(values), section
        for key, value in values.items():
            assert props[key].get("default") == value, f"{section}.{key}"


@pytest.mark.parametrize("name, small, offset, theta", [
    ("coincident centres, turned", 1.0, 0.0, 0.3),
    ("coincident centres, aligned", 1.0, 0.0, 0.0),
    ("one square inside the other", 0.5, 0.2, 0.2),
])
def test_a_scene_starting_deeply_overlapped_is_refused_at_its_first_step(name, small, offset,
                                                                         theta):
    """Coincident centres put the contact point on both centres (l = r_i r_j / (r_i + r_j)
    is 0/0) and a nested polygon has no contact line: the run stops after one step with
    the blow-up detector's message and the start state kept, instead of a
    ZeroDivisionError inside the kernel or particles thrown apart at 1e9 m/s."""
    w = 4e-3
    sim = scene([rectangle(w, w), rectangle(small * w, small * w)],
                [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (offset * w, 0.0, theta, 0.0, 0.0, 0.0)],
                youngs_modulus=1e7)
    start = sim.position.copy()
    with pytest.raises(BlowUpError, match=r"step 1\): an overlap of .* exceeds "
                                          r"model.max_overlap_fraction"):
        sim.run(steps=300)
    np.testing.assert_array_equal(sim.position, start)
    assert sim.time == 0.0


def test_characteristic_length_of_a_contact_point_on_both_centres_is_zero():
    assert characteristic_length(0.0, 0.0) == 0.0
    assert characteristic_length(2.0, 2.0) == pytest.approx(1.0)  # r r / 2r = r / 2
    assert characteristic_length(3.0, np.inf) == 3.0
