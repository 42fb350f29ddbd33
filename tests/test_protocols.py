"""Pouring protocols: resuming a killed pour, the layered line, relaxation failure."""

import numpy as np
import pytest
import xarray as xr

from sim import protocols
from sim.config import SimConfig
from sim.engine import Simulation

SMALL = {"pour": {"n_particles": 24, "rate": 200.0, "checkpoint_interval": 1e-9,
                  "progress_interval": 1e9},
         "model": {"integrator": "verlet"}}


def test_killed_pour_resumes_from_checkpoint_and_retraces_the_run(tmp_path, monkeypatch):
    cfg = SimConfig.from_dict(SMALL)
    whole = tmp_path / "whole.nc"
    protocols.pour(cfg, "wedge", 3, whole)

    ckpt = tmp_path / "ck.nc"
    calls = {"n": 0}
    original = Simulation.run

    def dying_run(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 15:
            raise KeyboardInterrupt("killed")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Simulation, "run", dying_run)
    out = tmp_path / "poured.nc"
    with pytest.raises(KeyboardInterrupt):
        protocols.pour(cfg, "wedge", 3, out, checkpoint=ckpt)
    assert ckpt.exists() and not out.exists()   # nothing that looks finished
    partial = xr.open_dataset(ckpt)
    assert 0 < partial.sizes["particle"] < 24
    partial.close()
    monkeypatch.setattr(Simulation, "run", original)

    protocols.pour(cfg, "wedge", 3, out, checkpoint=ckpt)
    assert not ckpt.exists()
    a = xr.open_dataset(whole)
    b = xr.open_dataset(out)
    assert a.attrs["time"] == b.attrs["time"]
    for v in ("x", "y", "theta", "vx", "vy", "omega"):
        np.testing.assert_array_equal(a[v].values, b[v].values)


def test_layered_line_stays_within_the_target_flanks():
    """The release line never reaches beyond a pile of layered_slope_deg."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 400}})
    shapes = protocols.pile_shapes(cfg, 1)
    half, height = protocols.target_pile(shapes, cfg.pour.layered_slope_deg)
    # the triangle holds the particles' area at solid fraction 0.8
    assert half * height == pytest.approx(np.sum(shapes.area) / 0.8)
    assert height / half == pytest.approx(np.tan(np.radians(20.0)))
    sim = Simulation(shapes, cfg.model)
    xs = [protocols.release_point(sim, cfg, "layered", 1, k)[0] for k in range(200)]
    assert max(np.abs(xs)) <= half
    assert max(np.abs(xs)) > 0.8 * half      # the first layer covers the base
    # a settled particle high up: the line shrinks to the flanks at that height
    sim.place(0, 0.0, 0.6 * height, 0.0)
    xs = [protocols.release_point(sim, cfg, "layered", 1, k)[0] for k in range(1, 200)]
    top = protocols.pile_top(sim)
    assert max(np.abs(xs)) <= half * (1 - top / height) + 1e-12


def test_relaxation_fails_loudly_when_time_runs_out():
    cfg = SimConfig.from_dict({"relax": {"max_time": 0.002, "drag": 0.0}})
    shapes = protocols.pile_shapes(SimConfig.from_dict({"pour": {"n_particles": 2}}), 0)
    sim = Simulation(shapes, cfg.model)
    sim.place(0, 0.0, 0.05, 0.0)         # still falling: not at rest
    with pytest.raises(protocols.RelaxationError, match="relax.max_time = 0.002"):
        protocols.relax(sim, cfg)
