"""Settings at the ends of their ranges are refused before the run, in one
line naming the settings, their values and what is allowed (docs/model.md,
"Time-step rule"): a step that cannot resolve the motion, a run of more steps
than is sane, a drag beyond the integrator's stability, a modulus or mass
beyond double precision.  The study's own settings pass, the rules hold for a
real pour and the drag's limit is the integrator's own."""

import json
import logging
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from sim import cli
from sim.config import SECTIONS, ModelParams, SimConfig
from sim.engine import Simulation
from sim.integrators import stability_limit
from sim.io import load_simulation
from sim.pour import GRAVITY, check_pour, pile_shapes, pour
from sim.relax import check_stage, relax_file
from sim.release import pile_height_bound
from sim.shapes import make_shapes
from sim.timestep import FREE_ZETA, drag_limit

REPO = Path(__file__).resolve().parents[1]

#: A pour of 20 particles with each extreme, and what its one line must name.
POUR_EXTREMES = [
    ({"model": {"youngs_modulus": 1.0e-300}}, "model.youngs_modulus = 1e-300"),
    ({"model": {"youngs_modulus": 1.0e-250}}, "model.youngs_modulus = 1e-250"),   # the motion
    ({"model": {"youngs_modulus": 1.0e308}}, "model.youngs_modulus = 1e+308"),
    ({"model": {"density": 1.0e308}}, "model.density = 1e+308"),
    ({"model": {"density": 1.0e250}}, "model.density = 1e+250"),                 # the motion
    ({"model": {"density": 1.0e-308}}, "model.density = 1e-308"),
    ({"pour": {"release_height": 1.0e308}}, "pour.release_height = 1e+308"),
    ({"pour": {"release_height": 100.0}}, "pour.release_height = 100.0"),
    ({"model": {"dt": 1.0e-300}}, "model.dt = 1e-300"),
    ({"model": {"dt": 5.0e-324}}, "model.dt = 5e-324"),
    ({"pour": {"rate": 1.0e-308}}, "pour.rate = 1e-308"),
    ({"pour": {"spin_drag": 1.0e4}, "model": {"dt_safety": 1.0}}, "pour.spin_drag = 10000.0"),
    ({"pour": {"spin_drag": 1.0e9}}, "pour.spin_drag = 1000000000.0"),           # the schema
    ({"particles": {"semi_axis_mean": 1.0e-120}}, "particles.semi_axis_mean = 1e-120"),
    ({"pour": {"jitter": 1.0e308}}, "pour.jitter = 1e+308"),
    ({"pour": {"release_speed": 1.0e308}}, "pour.release_speed = 1e+308"),
    ({"pour": {"layered_slope_deg": 1.0e-300}}, "pour.layered_slope_deg = 1e-300"),
]


def _cli(argv, caplog):
    """Exit status and the ERROR lines of ``python -m sim ARGV`` run in this process."""
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="sim"):
        status = cli.main(argv)
    return status, [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR], \
        [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize("params, named", POUR_EXTREMES,
                         ids=[json.dumps(p) for p, _ in POUR_EXTREMES])
def test_a_pour_at_an_extreme_is_refused_in_one_line_before_it_starts(tmp_path, caplog, params,
                                                                      named):
    params = {**params, "pour": {"n_particles": 20, **params.get("pour", {})}}
    out = tmp_path / "poured.nc"
    status, errors, lines = _cli(["pour", "--params", json.dumps(params), "--protocol", "wedge",
                                  "--seed", "1", "--out", str(out), "--checkpoint",
                                  str(tmp_path / "ck.nc")], caplog)
    assert status == 2
    assert len(errors) == 1 and "\n" not in errors[0]
    assert named in errors[0] and ("allowed" in errors[0] or "must be" in errors[0]), errors[0]
    # before the pour started: no log line of it, no lock, nothing written
    assert not any("started by process" in line for line in lines)
    assert list(tmp_path.iterdir()) == []


def test_the_line_is_all_the_terminal_shows(tmp_path):
    """Through the command line itself: one line on stderr, no traceback."""
    params = {"pour": {"n_particles": 20, "release_height": 1.0e308}}
    proc = subprocess.run([sys.executable, "-m", "sim", "pour", "--params", json.dumps(params),
                           "--protocol", "wedge", "--seed", "1", "--out",
                           str(tmp_path / "p.nc")], capture_output=True, text=True, cwd=REPO,
                          timeout=120)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "pour.release_height = 1e+308" in proc.stderr and "Traceback" not in proc.stderr


def _study(name):
    data = yaml.safe_load((REPO / "config" / name).read_text())
    return SimConfig.from_dict({k: v for k, v in data.items() if k in SECTIONS})


@pytest.mark.parametrize("name", ["config.yaml", "smoke.yaml"])
@pytest.mark.parametrize("integrator", ["verlet", "gear"])
def test_the_studys_settings_pass(name, integrator):
    cfg = _study(name)
    cfg = SimConfig.from_dict({**cfg.to_dict(), "model": {**cfg.to_dict()["model"],
                                                          "integrator": integrator}})
    check_pour(cfg, "wedge", 1, pile_shapes(cfg, 1))    # the protocol and seed change no bound


@pytest.fixture(scope="module")
def poured(tmp_path_factory):
    """A poured pile of 12 particles."""
    out = tmp_path_factory.mktemp("poured") / "poured.nc"
    pour(SimConfig.from_dict({"pour": {"n_particles": 12, "rate": 400.0},
                              "model": {"integrator": "verlet"}}), "wedge", 3, out)
    return out


@pytest.fixture(scope="module")
def relaxed(poured):
    """The poured pile relaxed."""
    out = poured.with_name("relaxed.nc")
    relax_file(SimConfig.from_dict({"model": {"integrator": "verlet"}}), poured, out)
    return out


def test_the_studys_relaxation_and_probes_pass_on_a_pile(poured):
    cfg = _study("config.yaml")
    sim, _ = load_simulation(poured, cfg.model)
    check_stage(cfg, sim, "relax")
    check_stage(cfg, sim, "probe", extra_time=cfg.probe.ramp_time, gravity=0.9 * GRAVITY)


@pytest.mark.parametrize("params, named", [
    ({"relax": {"max_time": 1.0e9}}, "relax.max_time = 1000000000.0"),
    ({"relax": {"rocking_drag": 1.0e4}, "model": {"dt": "limit"}}, "relax.rocking_drag = 10000.0"),
    ({"model": {"dt": 1.0e-300}}, "model.dt = 1e-300"),
])
@pytest.mark.parametrize("command", [["relax"], ["probe", "--level", "0.1"]])
def test_a_relaxation_or_probe_at_an_extreme_is_refused_in_one_line(tmp_path, caplog, poured, relaxed,
                                                                    params, named, command):
    state = poured if command == ["relax"] else relaxed   # the stage each command takes
    if params.get("model", {}).get("dt") == "limit":      # the pile's own stability limit
        sim, _ = load_simulation(state)
        params = {**params, "model": {"dt": sim.bound.dt_limit}}
    out = tmp_path / "out.nc"
    status, errors, _ = _cli([*command, "--params", json.dumps(params), "--input", str(state),
                              "--out", str(out)], caplog)
    assert status == 2
    assert len(errors) == 1 and named in errors[0] and "allowed" in errors[0], errors
    assert not out.exists()


def test_no_particle_of_a_pour_outruns_the_bound_of_the_motion_rule(tmp_path, monkeypatch):
    """The rule's speed, from the energy a released particle can gain, bounds
    every speed of a real pour (sampled after every run of steps)."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 12, "rate": 400.0},
                               "model": {"integrator": "verlet"}})
    shapes = pile_shapes(cfg, 3)
    p = cfg.pour
    bound = math.sqrt(p.release_speed ** 2 + 2 * GRAVITY * (
        p.release_height + shapes.radius.max() + pile_height_bound(shapes)))
    fastest = []
    real_run = Simulation.run

    def run(sim, *args, **kwargs):
        done = real_run(sim, *args, **kwargs)
        fastest.append(float(np.max(np.hypot(*sim.velocity.T))) if sim.n else 0.0)
        return done

    monkeypatch.setattr(Simulation, "run", run)
    pour(cfg, "wedge", 3, tmp_path / "poured.nc")
    # released at 1 m/s, the particles fall a few cm: well above the start, below the bound
    assert p.release_speed < max(fastest) < bound


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_the_drag_limit_of_a_free_particle_is_where_its_spin_starts_to_grow(integrator):
    """A free particle spinning under a drag c decays for c dt below the
    rule's limit (:data:`FREE_ZETA`) and grows beyond it: the limit is the
    integrator's own, not a margin."""
    shapes = make_shapes(np.random.default_rng(1), 1)
    limit = 2.0 * FREE_ZETA * stability_limit(integrator, FREE_ZETA)
    spins = {}
    for factor in (0.97, 1.03):
        sim = Simulation(shapes, ModelParams(integrator=integrator), gravity=(0.0, 0.0),
                         support=False)
        sim.spin_drag = factor * limit / sim.dt
        sim.check_every = 10 ** 9      # the blow-up detector would stop the growing one
        sim.place(0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
        sim.run(steps=400)
        spins[factor] = abs(sim.omega[0])
    assert spins[0.97] < 1.0 < spins[1.03]
    # and the rule refuses that drag at that step
    assert drag_limit(sim.bound, integrator, 1.03 * limit / sim.dt) < sim.dt


def test_a_drag_within_the_schema_passes_the_studys_step():
    """relax.drag and rocking_drag at the schema's largest, 10⁴/s, pass the
    automatic step of both integrators (the rule lowers the limit by less
    than the default dt_safety leaves)."""
    for integrator in ("gear", "verlet"):
        cfg = SimConfig.from_dict({"relax": {"drag": 1.0e4, "rocking_drag": 1.0e4},
                                   "model": {"integrator": integrator}})
        check_stage(cfg, Simulation(pile_shapes(cfg, 1), cfg.model), "relax")
