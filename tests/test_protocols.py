"""Pouring protocols: resuming a killed pour, the layered line, relaxation and its drag."""

import logging

import numpy as np
import pytest
import xarray as xr

from analysis.balance import increment_report
from analysis.states import load_state
from sim.config import SimConfig
from sim.engine import Simulation
from sim.pour import GRAVITY, pile_shapes, pour
from sim.probe import probe_file, restore_file, tilt_file
from sim.relax import EnergyWatchdog, RelaxationError, relax, relax_file
from sim.release import pile_top, release_point, target_pile, top_width

from scenes import dying_at_run, scene

SMALL = {"pour": {"n_particles": 24, "rate": 200.0, "checkpoint_interval": 1e-9,
                  "progress_interval": 1e9},
         "model": {"integrator": "verlet"}}


def test_killed_pour_resumes_from_checkpoint_and_retraces_the_run(tmp_path, monkeypatch):
    cfg = SimConfig.from_dict(SMALL)
    whole = tmp_path / "whole.nc"
    pour(cfg, "wedge", 3, whole)

    ckpt = tmp_path / "ck.nc"
    original = Simulation.run
    monkeypatch.setattr(Simulation, "run", dying_at_run(15))
    out = tmp_path / "poured.nc"
    with pytest.raises(KeyboardInterrupt):
        pour(cfg, "wedge", 3, out, checkpoint=ckpt)
    assert ckpt.exists() and not out.exists()   # nothing that looks finished
    partial = xr.open_dataset(ckpt)
    assert 0 < partial.sizes["particle"] < 24
    partial.close()
    monkeypatch.setattr(Simulation, "run", original)

    pour(cfg, "wedge", 3, out, checkpoint=ckpt)
    assert not ckpt.exists()
    a = xr.open_dataset(whole)
    b = xr.open_dataset(out)
    assert a.attrs["time"] == b.attrs["time"]
    for v in ("x", "y", "theta", "vx", "vy", "omega"):
        np.testing.assert_array_equal(a[v].values, b[v].values)


def test_layered_line_stays_within_the_target_flanks():
    """The release line never reaches beyond a pile of layered_slope_deg."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 400}})
    shapes = pile_shapes(cfg, 1)
    half, height = target_pile(shapes, cfg.pour.layered_slope_deg)
    # the triangle holds the particles' area at solid fraction 0.8
    assert half * height == pytest.approx(np.sum(shapes.area) / 0.8)
    assert height / half == pytest.approx(np.tan(np.radians(20.0)))
    sim = Simulation(shapes, cfg.model)
    xs = [release_point(sim, cfg, "layered", 1, k)[0][0] for k in range(200)]
    assert max(np.abs(xs)) <= half
    assert max(np.abs(xs)) > 0.8 * half      # the first layer covers the base
    # a settled particle high up: the line shrinks to the flanks at that height
    sim.place(0, 0.0, 0.6 * height, 0.0)
    xs = [release_point(sim, cfg, "layered", 1, k)[0][0] for k in range(1, 200)]
    top = pile_top(sim)
    assert max(np.abs(xs)) <= half * (1 - top / height) + 1e-12


def test_layered_line_follows_the_measured_top_width():
    """Over a settled pile the line spans the width of its top (plus
    line_margin), not the whole base of the target pile."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 400, "line_margin": 0.002}})
    sim = Simulation(pile_shapes(cfg, 1), cfg.model)
    for k, x in enumerate(np.linspace(0.01, 0.03, 4)):      # a row on the support
        sim.place(k, x, 0.0032, 0.0)
    sim.run(steps=1)           # settled = slow and touching: one force evaluation finds the contacts
    assert sim.touching().all()
    r = sim.shapes.radius[:4]
    lo, hi = 0.01 - r[0] - 0.002, 0.03 + r[3] + 0.002
    assert top_width(sim, cfg.pour.top_band) == pytest.approx((lo + 0.002, hi - 0.002), abs=1e-6)
    xs = np.array([release_point(sim, cfg, "layered", 1, k)[0][0] for k in range(4, 300)])
    assert xs.min() >= lo and xs.max() <= hi
    assert xs.max() - xs.min() > 0.8 * (hi - lo)


def test_relaxation_fails_loudly_when_time_runs_out():
    cfg = SimConfig.from_dict({"relax": {"max_time": 0.002, "hold_time": 0.001, "drag": 0.0}})
    shapes = pile_shapes(SimConfig.from_dict({"pour": {"n_particles": 2}}), 0)
    sim = Simulation(shapes, cfg.model)
    sim.place(0, 0.0, 0.05, 0.0)         # still falling: not at rest
    with pytest.raises(RelaxationError, match="relax.max_time = 0.002"):
        relax(sim, cfg)


# Two polygons that rolled off the full-size wedge pile (seed 1) onto the bare
# support, as they were when the pour ended: body-frame corners (m) and state
# (x, y, theta, vx, vy, omega).  Alone on the support each rocks in a limit cycle.
ROCKER_CORNERS = ([-0.002737158512365691, -0.0016874906937216804, 0.00039863014060406796,
                   0.0026416827716659293, 0.0020429306346834084, -0.00035538817743884887],
                  [0.0009855440524517848, -0.001907432581742812, -0.0025236347387351346,
                   -0.000992895569492866, 0.0015492296519775753, 0.002555951444722304])
ROCKER_STATE = (0.9811273061951751, 0.002331363554199414, -349.2974956759441,
                0.004482984761211977, -0.0026352574019162067, -1.940812055988008)

HEPTAGON_CORNERS = ([-0.002815792006063629, -0.0026886091581005316, -0.0008513862421583409,
                     0.002000260619051215, 0.003290530378913625, 0.0015652349307173244,
                     -0.00030708360465746644],
                    [0.0019109759760094767, -0.001955969089955421, -0.00316961166477102,
                     -0.0026669675026290925, 0.0002775219430409712, 0.0028197354186042735,
                     0.0032616385471365907])
HEPTAGON_STATE = (1.081812754087111, 0.0027528255399059663, -337.75302171208455,
                  -0.0019902496108876165, 0.0007439688633269366, 0.6424208632497496)


def _rocker(relax, corners=ROCKER_CORNERS, state=ROCKER_STATE):
    cfg = SimConfig.from_dict({"model": {"integrator": "verlet"}, "relax": relax})
    sim = scene([tuple(np.array(c) for c in corners)], [state],
                gravity=(0.0, -9.81), support=True, **cfg.to_dict()["model"])
    return sim, cfg


def test_weak_drag_leaves_a_polygon_rocking_on_the_support(monkeypatch, caplog):
    """The contact law does not damp rocking, and its force point (the midpoint
    of the contact line) makes it non-conservative: under 20/s of drag alone
    (the energy watchdog silenced) the hexagon still moves at over 1 mm/s
    after 1 s. The watchdog finds that feed and names the hexagon."""
    sim, cfg = _rocker({"drag": 20.0, "rocking_drag": 20.0, "max_time": 1.0})
    with caplog.at_level(logging.INFO, logger="sim"):
        relax(sim, cfg)
    assert any("energy fed" in r.getMessage() and "rocking on the support" in r.getMessage()
               for r in caplog.records)
    monkeypatch.setattr(EnergyWatchdog, "add", lambda self, sim, net, at_rest: None)
    sim, cfg = _rocker({"drag": 20.0, "rocking_drag": 20.0, "max_time": 1.0})
    with pytest.raises(RelaxationError, match="not at rest"):
        relax(sim, cfg)
    assert np.hypot(*sim.velocity[0]) > 1e-3


def test_rocking_drag_brings_the_rocking_polygon_to_rest():
    """With the default drags (20/s, then 100/s once calm) the same hexagon comes
    to rest, where the support carries its weight to within the unbalanced
    force the rest criterion allows (|R - W| <= |F + m g|)."""
    sim, cfg = _rocker({"max_time": 1.0})
    relax(sim, cfg)
    assert np.hypot(*sim.velocity[0]) < cfg.relax.max_speed
    c = sim.contacts()
    weight = sim.shapes.mass[0] * 9.81
    assert np.all(c["j"] == -1)
    assert abs(np.sum(c["fy"]) - weight) < cfg.relax.unbalanced_force * weight


def test_drag_time_stops_a_rocker_that_never_looks_calm():
    """Alone, the heptagon's rocking keeps its kinetic energy above the
    criterion under 20/s, so only relax.drag_time brings in the 100/s that
    stops it; with the switch put off beyond max_time it never rests."""
    sim, cfg = _rocker({"max_time": 1.0, "drag_time": 2.0}, HEPTAGON_CORNERS, HEPTAGON_STATE)
    with pytest.raises(RelaxationError, match="not at rest"):
        relax(sim, cfg)
    sim, cfg = _rocker({"max_time": 1.0}, HEPTAGON_CORNERS, HEPTAGON_STATE)
    relax(sim, cfg)
    assert sim.time < cfg.relax.drag_time + 0.3


def test_probe_increment_balances_as_well_as_the_relaxed_pile(tmp_path):
    """The probe's rest criterion applies to the change of weight ΔW = Δ M g.
    Since |R - W| <= sum_p |F_p + m_p g| in every state, the relaxed pile's
    support reaction is off by at most u W and the reduced one's by u ΔW
    (u = relax.unbalanced_force), so the increment's by at most u (W + ΔW),
    read back from the state files by the analysis.  (With the relaxation's
    criteria unscaled, a 400-particle pile's increment was off by 8e-4.)"""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 40, "rate": 200.0,
                                        "progress_interval": 1e9},
                               "model": {"integrator": "verlet"}})
    level = 0.1
    pour(cfg, "wedge", 2, tmp_path / "poured.nc")
    relax_file(cfg, tmp_path / "poured.nc", tmp_path / "relaxed.nc")
    probe_file(cfg, tmp_path / "relaxed.nc", level, tmp_path / "reduced.nc")
    a, b = load_state(str(tmp_path / "relaxed.nc")), load_state(str(tmp_path / "reduced.nc"))
    weight = float(a.mass.sum()) * a.gravity
    assert b.gravity == pytest.approx((1.0 - level) * a.gravity, rel=1e-12)
    u = cfg.relax.unbalanced_force
    assert abs(a.force_y[a.support].sum() - weight) <= u * weight
    assert abs(b.force_y[b.support].sum() - (1.0 - level) * weight) <= u * level * weight
    rep = increment_report(a, b, {"support_reaction_rtol": 1e-2, "love_rtol": 2e-2})
    assert rep["passed"] and rep["weight_change"] == pytest.approx(-level * weight, rel=1e-12)
    assert abs(rep["support_reaction_rel_error"]) <= u * (1.0 + level) / level


def test_tilted_and_restored_gravity_probes_balance_their_load(tmp_path):
    """Tilting gravity of a relaxed pile by delta adds a sideways body force
    M delta g that the support must take: at rest its horizontal reaction is
    -M delta g and its vertical one the weight, each within u M delta g (the
    probe's rest criterion on the change of load, u = relax.unbalanced_force),
    for either sign of delta. Restoring full gravity after the reduction gives
    (0, -g0) exactly and the weight back on the support within u Delta W."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 40, "rate": 200.0,
                                        "progress_interval": 1e9},
                               "model": {"integrator": "verlet"}})
    pour(cfg, "wedge", 2, tmp_path / "poured.nc")
    relax_file(cfg, tmp_path / "poured.nc", tmp_path / "relaxed.nc")
    a = load_state(str(tmp_path / "relaxed.nc"))
    weight = float(a.mass.sum()) * a.gravity
    u = cfg.relax.unbalanced_force
    for delta, stage in ((0.05, "tiltp05"), (-0.05, "tiltm05")):
        tilt_file(cfg, tmp_path / "relaxed.nc", delta, tmp_path / f"{stage}.nc", stage)
        with xr.open_dataset(tmp_path / f"{stage}.nc") as ds:
            assert ds.attrs["stage"] == stage and ds.attrs["gravity_tilt"] == delta
            assert ds.attrs["gravity_x"] == pytest.approx(delta * a.gravity, rel=1e-12)
            assert ds.attrs["gravity_y"] == pytest.approx(-a.gravity, rel=1e-12)
            support = ds["contact_j"].values == -1
            rx, ry = ds["force_x"].values[support].sum(), ds["force_y"].values[support].sum()
        assert abs(rx + delta * weight) <= u * abs(delta) * weight
        assert abs(ry - weight) <= u * abs(delta) * weight + u * weight
    level = 0.1
    probe_file(cfg, tmp_path / "relaxed.nc", level, tmp_path / "reduced.nc")
    restore_file(cfg, tmp_path / "reduced.nc", tmp_path / "restored.nc")
    with xr.open_dataset(tmp_path / "restored.nc") as ds:
        assert ds.attrs["stage"] == "restored"
        assert (ds.attrs["gravity_x"], ds.attrs["gravity_y"]) == (0.0, -GRAVITY)
        support = ds["contact_j"].values == -1
        assert abs(ds["force_y"].values[support].sum() - weight) <= u * level * weight + u * weight
    with pytest.raises(ValueError, match="tilt = 0.0"):
        tilt_file(cfg, tmp_path / "relaxed.nc", 0.0, tmp_path / "x.nc", "tiltp00")


@pytest.mark.parametrize("protocol", ["wedge", "layered"])
def test_release_points_stay_inside_side_walls(protocol):
    """The line source is wider than a narrow box: its particles must still be
    released wholly inside the walls (else they start inside a wall)."""
    walls = (-0.02, 0.01)
    cfg = SimConfig.from_dict({"pour": {"n_particles": 400, "jitter": 0.05}})
    sim = Simulation(pile_shapes(cfg, 1), cfg.model, walls=walls)
    for k in range(1, 400):
        (x, _), = release_point(sim, cfg, protocol, 1, k)
        r = sim.shapes.radius[k]
        assert walls[0] + r <= x <= walls[1] - r


@pytest.mark.parametrize("stage", ["poured", "checkpoint"])
def test_a_probe_refuses_a_state_not_at_rest_before_it_runs(tmp_path, stage):
    """A gravity probe measures the response of a pile at rest; a poured state
    (or a pour's checkpoint) is refused with the file and its stage named, and
    nothing is written."""
    from scenes import rectangle

    from sim.cli import main
    from sim.io import save_state

    sim = scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)], gravity=(0.0, -9.81), support=True)
    state = tmp_path / f"{stage}.nc"
    save_state(sim, state, {"model": {}}, stage=stage, protocol="wedge", seed=1)
    out = tmp_path / "reduced.nc"
    with pytest.raises(ValueError, match=f"its stage is '{stage}', a state not at rest"):
        probe_file(SimConfig(), state, 0.1, out)
    assert main(["probe", "--input", str(state), "--level", "0.1", "--out", str(out)]) == 2
    assert not out.exists()
