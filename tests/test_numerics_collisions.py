"""Error against run time for binary collisions (sim.numerics): the reference
against the analytic linear spring, the simulator against the reference, the
integrators' orders of convergence, the data files and bad settings."""

import math

import numpy as np
import pytest
import xarray as xr
import yaml
from snakemake.utils import validate

from sim.config import ConfigError
from sim.numerics.collision_scenes import CollisionCase, measure, reference, scene
from sim.numerics.collisions import CollisionSettings, main, observed_order, time_to_reach
from sim.numerics.polygons import rectangle, shapes_of
from sim.numerics.reference import EdgeOnFlat, collision_reference, linear_spring_half_period

REPO = __import__("pathlib").Path(__file__).resolve().parents[1]
SCHEMA = str(REPO / "workflow" / "schemas" / "config.schema.yaml")


def test_reference_gives_the_linear_spring_half_period():
    """A square's edge onto the support, undamped and frictionless: F = Y L d / l
    with l = r_i = W − d.  At a tiny speed the overlap stays below 1e-6 of W,
    so the spring is linear, k = Y L / W: the contact lasts π sqrt(m/k) and the
    collision is elastic (the force depends on d only)."""
    w = 2e-3
    shapes = shapes_of(rectangle(2 * w, 2 * w))
    m, inertia = shapes.mass[0], shapes.inertia[0]
    y = 1e7
    out = collision_reference(EdgeOnFlat(2 * w, w, None), m, inertia, np.inf, np.inf, y,
                              0.0, 0.0, 1e-4, 0.0, 0.0)
    half = linear_spring_half_period(y * 2 * w / w, m)
    assert abs(out.duration / half - 1) < 1e-5
    assert abs(out.normal_restitution - 1) < 1e-9
    # largest overlap: the amplitude v / omega times the edge
    assert abs(out.max_overlap_area / (2 * w * 1e-4 * half / math.pi) - 1) < 1e-5


CASES = [CollisionCase("edge_elastic", "edge", 0.0, 0.0),
         CollisionCase("edge_damped_friction", "edge", 0.3, 0.5),
         CollisionCase("corner_elastic", "corner", 0.0, 0.0),
         CollisionCase("corner_damped_friction", "corner", 0.3, 0.5)]


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_simulator_converges_to_the_reference(case, integrator):
    """At a hundredth of the stability limit every observable agrees with the
    independent solve_ivp solution (geometry, force law, friction history and
    integrator together)."""
    ref = reference(case)
    out, _ = measure(case, integrator, 0.01 * scene(case, integrator).bound.dt_limit)
    assert abs(out.normal_restitution - ref.normal_restitution) < 5e-4
    assert abs(out.tangential_restitution - ref.tangential_restitution) < 5e-4
    assert abs(out.duration / ref.duration - 1) < 1e-4
    assert abs(out.max_overlap_area / ref.max_overlap_area - 1) < 1e-3
    if case.friction > 0:
        assert ref.tangential_restitution < 0.9  # friction did act


def _errors(case, integrator, fractions):
    ref = reference(case)
    limit = scene(case, integrator).bound.dt_limit
    rows = []
    for f in fractions:
        out, _ = measure(case, integrator, f * limit)
        rows.append([abs(out.normal_restitution - ref.normal_restitution),
                     abs(out.duration / ref.duration - 1),
                     abs(out.max_overlap_area / ref.max_overlap_area - 1)])
    return limit * np.asarray(fractions), np.array(rows)


def test_verlet_is_second_order_and_gear_second_order_at_a_kink():
    """Elastic edge-on-edge collision.  Velocity Verlet converges at second
    order.  Gear's fifth order is lost: the force F ∝ d is continuous but its
    time derivative jumps at touch-down and separation, and Gear shows about
    second order (1.6–2.6 over this range), with a constant some hundred
    times smaller than Verlet's."""
    case = CASES[0]
    fractions = [0.1, 0.0316, 0.01]
    dt, verlet = _errors(case, "verlet", fractions)
    for k in range(3):
        assert 1.8 < observed_order(dt, verlet[:, k], floor=0) < 2.2
    dt, gear = _errors(case, "gear", fractions)
    for k in (0, 2):
        assert 1.5 < observed_order(dt, gear[:, k], floor=0) < 3.0
    assert np.all(gear[-1] < verlet[-1] / 30)


def test_observed_order_and_time_to_reach():
    """The fit recovers a power law; the time to reach a target is the first
    point from which every finer one meets it."""
    dt = np.geomspace(1e-1, 1e-4, 7)
    assert observed_order(dt, 3 * dt ** 2) == pytest.approx(2.0)
    wall = np.array([1.0, 2, 3, 4])
    assert time_to_reach(wall, [1e-2, 1e-5, 1e-3, 1e-6], 1e-4) == 4.0
    assert time_to_reach(wall, [1e-5, 1e-5, 1e-5, 1e-6], 1e-4) == 1.0
    assert math.isnan(time_to_reach(wall, [1e-5, 1e-5, 1e-5, 1e-3], 1e-4))


def test_command_writes_cf_netcdf_figure_and_table(tmp_path):
    params = {"numerics": {"collisions": {
        "steps_per_decade": 1, "smallest_fraction": 0.1, "repeats": 1,
        "cases": [{"name": "edge_friction", "contact": "edge", "friction": 0.5}]}}}
    files = {k: tmp_path / f"c.{k}" for k in ("nc", "png", "md")}
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(params))
    assert main(["--params", f"@{path}", "--nc", str(files["nc"]), "--figure",
                 str(files["png"]), "--table", str(files["md"])]) == 0
    with xr.open_dataset(files["nc"]) as ds:
        for key in ("Conventions", "title", "source", "history", "config"):
            assert ds.attrs[key]
        assert yaml.safe_load(ds.attrs["config"]) == params
        assert ds.sizes == {"case": 1, "integrator": 2, "dt_fraction": 2}
        for name, var in ds.data_vars.items():
            assert "long_name" in var.attrs, name
            if var.dtype.kind == "f":
                assert "units" in var.attrs, name
        assert ds.dt_fraction.values[0] == 1.0
        assert np.all(ds.wall_time > 0) and np.all(ds.steps > 0)
        assert float(ds.reference_tangential_restitution[0]) < 0.9
    assert files["png"].read_bytes()[:4] == b"\x89PNG"
    table = files["md"].read_text()
    assert table.count("| edge_friction |") == 8  # 4 observables x 2 integrators
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left


@pytest.mark.parametrize("settings, message", [
    ({"repeats": 0}, "numerics.collisions.repeats = 0"),
    ({"integrators": ["rk4"]}, "'rk4' is not one of"),
    ({"smallest_fraction": 2.0}, "numerics.collisions.smallest_fraction = 2.0"),
    ({"cases": [{"name": "a", "contact": "face"}]}, "contact = 'face': must be one of"),
    ({"cases": [{"name": "a", "contact": "edge"}] * 2}, "must be unique"),
    ({"tolerance": 1}, "unknown setting(s) ['tolerance']"),
])
def test_bad_settings_are_refused_with_the_setting_named(settings, message):
    with pytest.raises(ConfigError) as err:
        CollisionSettings.from_dict(settings)
    assert message in str(err.value)


@pytest.mark.parametrize("name", ["numerics.yaml", "numerics_ci.yaml"])
def test_configs_validate_and_schema_defaults_are_the_code_defaults(name):
    config = {"protocols": {"wedge": {"seeds": [1]}}}
    validate(config, SCHEMA)
    from sim.numerics.stability import StabilitySettings
    for section, klass in (("collisions", CollisionSettings), ("stability", StabilitySettings)):
        default = klass()
        for key, value in config["numerics"][section].items():
            code = getattr(default, key)
            assert (list(code) if isinstance(code, tuple) else code) == value, (section, key)
    shipped = yaml.safe_load((REPO / "config" / name).read_text())
    validate(shipped | {"protocols": {"wedge": {"seeds": [1]}}}, SCHEMA)
    CollisionSettings.from_dict(shipped["numerics"]["collisions"])
    StabilitySettings.from_dict(shipped["numerics"]["stability"])
    if name == "numerics.yaml":  # the full config spells out the defaults
        assert shipped["numerics"] == config["numerics"]
