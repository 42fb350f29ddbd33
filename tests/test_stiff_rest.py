"""A stiff pile comes to rest: the energy watchdog of the relaxation (issue 47, item 6).

The scene is the feed that kept a 150-polygon pile at ``youngs_modulus: 1e9``
from resting, isolated: one polygon of the default recipe lying on an edge on
the support, rocking. At 10⁹ N/m the rocking is a limit cycle that the
contact law feeds and ``relax.rocking_drag`` (100/s) does not stop; at
10⁷ N/m the same drag stops it and the watchdog stays silent, so that the
relaxation is the one of before it, bit for bit.
"""

import logging

import numpy as np
import pytest

from sim.config import ModelParams, RelaxParams, SimConfig
from sim.engine import Simulation
from sim.numerics.polygons import shapes_of
from sim.relax import EnergyWatchdog, relax
from sim.shapes import make_shapes

G = 9.81


def rocking_polygon(youngs_modulus, omega=0.2, support=True):
    """A polygon of the default recipe on one of its edges on the support,
    turned at ``omega`` rad/s: it rocks between the edge's corners."""
    shapes = make_shapes(np.random.default_rng(3), 24)
    o = shapes.node_offset
    x, y = shapes.node_x[o[12]:o[13]].copy(), shapes.node_y[o[12]:o[13]].copy()
    sim = Simulation(shapes_of((x, y)), ModelParams(youngs_modulus=youngs_modulus),
                     gravity=(0.0, -G), support=support)
    # this orientation lays an edge of 3.9 mm flat on the support (the polygon
    # of the 24-particle heap that rocked there in the 10⁹ N/m relaxation)
    theta = 6.8799
    lowest = np.min(np.sin(theta) * x + np.cos(theta) * y)
    sim.place(0, 0.0, -lowest, theta, 0.0, 0.0, omega)
    return sim


def cfg(max_time):
    """The default rest criteria and drags, within ``max_time`` seconds."""
    return SimConfig(relax=RelaxParams(max_time=max_time))


def test_stiff_rocking_polygon_comes_to_rest(caplog):
    """At 10⁹ N/m the rocking polygon rests within 0.3 s simulated (before
    the watchdog it rocked at 2 kHz until relax.max_time and the relaxation
    failed, as the 150-polygon pile did) and the watchdog names it."""
    sim = rocking_polygon(1e9)
    weight = float(sim.shapes.mass[0]) * G
    with caplog.at_level(logging.INFO, logger="sim"):
        relax(sim, cfg(0.3))
    assert sim.time <= 0.3
    # at rest: its net force is the rest criterion's fraction of its weight
    assert np.hypot(*sim.net_forces()[0]) < 1e-6 * weight
    fed = [r.getMessage() for r in caplog.records if "energy fed" in r.getMessage()]
    assert fed, "the watchdog named no feed"
    assert "particle 0" in fed[0] and "rocking on the support (1 contact)" in fed[0]


def test_soft_relaxation_is_the_one_of_before(caplog, monkeypatch):
    """At 10⁷ N/m the same rocking dies under relax.rocking_drag: the
    watchdog finds nothing and the relaxation is, bit for bit, the one
    without a watchdog (its findings suppressed)."""
    sim = rocking_polygon(1e7)
    with caplog.at_level(logging.INFO, logger="sim"):
        relax(sim, cfg(1.0))
    assert not any("energy fed" in r.getMessage() for r in caplog.records)
    monkeypatch.setattr(EnergyWatchdog, "add", lambda self, sim, net, at_rest: None)
    before = rocking_polygon(1e7)
    relax(before, cfg(1.0))
    assert before.time == sim.time
    np.testing.assert_array_equal(before.scaled_derivatives(), sim.scaled_derivatives())


def test_watchdog_does_not_blame_the_contacts_for_gravity():
    """A polygon falling freely under the drag holds its kinetic energy
    (gravity feeds it) but its contacts do no work: no finding."""
    sim = rocking_polygon(1e9, omega=0.0, support=False)
    sim.drag = 100.0
    watch = EnergyWatchdog(sim, 0.02)
    findings = []
    while sim.time < 0.1:
        sim.run(duration=1e-3)
        findings.append(watch.add(sim, sim.net_forces(), at_rest=False))
    # the window closed at least twice, and the fall is at its terminal speed g/c
    assert len(findings) > 40
    assert np.hypot(*sim.velocity[0]) == pytest.approx(G / 100.0, rel=1e-2)
    assert findings == [None] * len(findings)


def _fed(caplog):
    return [r.getMessage() for r in caplog.records if "energy fed" in r.getMessage()]


@pytest.mark.parametrize("hold_time", [0.0, 1e-4])
def test_a_short_hold_time_does_not_fool_the_watchdog(hold_time, caplog):
    """The pile not fed energy: at 10⁷ N/m relax.rocking_drag stops the rocking
    (above). With a hold time of 1e-4 s or 0 the watchdog's window was a few
    chunks of steps, shorter than the drag's own time 1/c: the kinetic energy
    sloshing between the contacts looked fed, and it raised the drag 100 -> 10000
    in 15 findings (issue 59, item 4). Its window is bounded from physics now
    (:func:`sim.relax.watch_window`): silent, and the drag applied is the one
    configured."""
    sim = rocking_polygon(1e7)
    config = SimConfig(relax=RelaxParams(max_time=1.0, hold_time=hold_time))
    with caplog.at_level(logging.INFO, logger="sim"):
        applied = relax(sim, config)
    assert _fed(caplog) == []
    assert applied == {"relax_drag_max": 100.0, "relax_drag_final": 100.0}


def test_a_fed_pile_is_still_found_at_a_zero_hold_time(caplog):
    """The pile fed energy (10⁹ N/m): with hold_time 0 the watchdog still names
    the rocking polygon and raises the drag, and the drag it reports applying is
    the one of its last finding, above relax.rocking_drag."""
    sim = rocking_polygon(1e9)
    config = SimConfig(relax=RelaxParams(max_time=0.3, hold_time=0.0))
    with caplog.at_level(logging.INFO, logger="sim"):
        applied = relax(sim, config)
    fed = _fed(caplog)
    assert fed and "particle 0" in fed[0] and "rocking on the support" in fed[0]
    last = float(fed[-1].split("drag ")[-1].split(" -> ")[1].split(" ")[0])
    assert applied["relax_drag_final"] == applied["relax_drag_max"] == last > 100.0


@pytest.mark.parametrize("youngs_modulus", [1e7, 1e9])
@pytest.mark.parametrize("drag", [1e-3, 100.0, 1e4])
def test_the_window_spans_contact_periods_and_the_drags_time(youngs_modulus, drag):
    """However short the window asked for, the watchdog's spans 20 contact
    periods ``2 pi sqrt(m / Y)`` (the kinetic energy sloshes with the elastic
    at that period, and the means of the window's halves must average it out)
    and two decay times ``1 / c`` of the drag (the kinetic energy then falls
    by e⁻² between the halves under the drag alone, a factor e beyond the
    watchdog's threshold e⁻¹, where a fluctuation cannot pass for either)."""
    sim = rocking_polygon(youngs_modulus)
    sim.drag = drag
    watch = EnergyWatchdog(sim, 1e-9)
    period = 2 * np.pi * np.sqrt(float(sim.shapes.mass[0]) / youngs_modulus)
    assert watch.window >= 20 * period
    assert watch.window >= 2.0 / drag


def test_the_relaxed_file_records_the_drag_applied(tmp_path):
    """The output records the drag the watchdog raised to, not only the
    configured one (issue 59, item 4): the stiff rocking polygon relaxed by
    python -m sim relax's own stage."""
    import xarray as xr

    from sim.io import save_state
    from sim.relax import relax_file

    sim = rocking_polygon(1e9)
    config = SimConfig(model=ModelParams(youngs_modulus=1e9), relax=RelaxParams(max_time=0.3))
    save_state(sim, tmp_path / "poured.nc", config.to_dict(), stage="poured", protocol="wedge",
               seed=1)
    relax_file(config, tmp_path / "poured.nc", tmp_path / "relaxed.nc")
    with xr.open_dataset(tmp_path / "relaxed.nc") as ds:
        assert ds.attrs["relax_drag_final"] > config.relax.rocking_drag
        assert ds.attrs["relax_drag_max"] == ds.attrs["relax_drag_final"]
