"""The pour's new sources (issue 44 items 2 and 3): the funnel point source at
the flux of the 2D Beverloo law, and the rain line source over the plateau of
the target pile, each off by default, checked against independent truth.

* The rain's line is the section of the target pile at the height where its
  lower part holds the particles released so far: checked against shapely's
  clip of the target triangle (:func:`test_rain_line_is_the_section_of_the_filled_target_pile`).
* The funnel's flux is counted from the release times of real pours over
  several seeds; a release never overlaps a polygon (shapely, at every
  release); a killed funnel or rain pour resumes bit for bit.
* The defaults change no pile: the settings digest of a default pour is that
  of the settings before these options existed (the bits of a default pour
  before and after are compared in the report of issue 44, commit message).
"""

import math

import numpy as np
import pytest
import xarray as xr
from scenes import dying_at_run
from shapely import Polygon, box
from shapely.affinity import rotate, translate

from sim.config import ConfigError, SimConfig
from sim.engine import Simulation
from sim.io import pour_digest
from sim.pour import GRAVITY, pile_shapes, pour
from sim.release import (BEVERLOO_C, BEVERLOO_K, PILE_PACKING, mean_diameter, rain_half_width,
                         release_point, source, target_pile)

QUIET = {"progress_interval": 1e9, "checkpoint_interval": 1e9}
FUNNEL = {"pour": {"n_particles": 80, "point_source": "funnel", **QUIET}}
RAIN = {"pour": {"n_particles": 60, "line_source": "rain", "rate": 200.0, **QUIET}}


def polygon(sim, i):
    """Particle i's polygon in the world frame, built here from its body-frame corners."""
    x, y = sim.shapes.corners(i)
    body = Polygon(np.column_stack([x, y]))
    return translate(rotate(body, float(sim.theta[i]), origin=(0, 0), use_radians=True),
                     float(sim.position[i, 0]), float(sim.position[i, 1]))


def recorded_pour(monkeypatch, tmp_path, cfg, protocol, seed):
    """Pour, recording each release's time, particle, the largest overlap (m²)
    of the released polygon with any other particle at that moment, and x."""
    releases = []
    original = Simulation.place

    def place(sim, k, *args, **kwargs):
        original(sim, k, *args, **kwargs)
        new = polygon(sim, k)
        overlap = max((new.intersection(polygon(sim, j)).area for j in range(sim.n) if j != k),
                      default=0.0)
        releases.append((sim.time, k, overlap, float(sim.position[k, 0])))

    monkeypatch.setattr(Simulation, "place", place)
    pour(cfg, protocol, seed, tmp_path / f"{protocol}{seed}.nc")
    monkeypatch.setattr(Simulation, "place", original)
    return np.array(releases)


def test_defaults_keep_the_settings_digest_of_the_study_piles():
    """At their defaults the new settings are left out of the digest, so a
    committed pile poured before them keeps its identity; set, they enter it."""
    before = SimConfig().to_dict()
    for key in ("point_source", "outlet_width", "outlet_height", "line_source"):
        del before["pour"][key]
    assert pour_digest(SimConfig().to_dict()) == pour_digest(before)
    funnel = SimConfig.from_dict({"pour": {"point_source": "funnel"}}).to_dict()
    wider = SimConfig.from_dict({"pour": {"point_source": "funnel", "outlet_width": 8}}).to_dict()
    rain = SimConfig.from_dict({"pour": {"line_source": "rain"}}).to_dict()
    assert len({pour_digest(c) for c in (before, funnel, wider, rain)}) == 4


@pytest.mark.parametrize("setting, value, words", [
    ("point_source", "hose", ["pour.point_source = 'hose'", "'drip', 'funnel'"]),
    ("line_source", "shower", ["pour.line_source = 'shower'", "'top', 'rain'"]),
    ("outlet_width", 1.0, ["pour.outlet_width = 1.0", "2"]),
    ("outlet_width", math.nan, ["pour.outlet_width = nan"]),
    ("outlet_height", 0.0, ["pour.outlet_height = 0.0", "> 0"]),
    ("outlet_height", 1e4, ["pour.outlet_height = 10000.0", "1000"]),
])
def test_nonsense_source_settings_are_refused_in_one_line(setting, value, words):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"pour": {setting: value}})
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text


def test_rain_line_is_the_section_of_the_filled_target_pile():
    """Independent truth: the target triangle (half base L, height H) clipped
    by shapely below the height where it holds the released area has, at that
    height, the half-width :func:`rain_half_width` gives (to 1e-9 of L: the
    bisection's resolution)."""
    shapes = pile_shapes(SimConfig.from_dict({"pour": {"n_particles": 50}}), 4)
    half, height = target_pile(shapes, 20.0)
    assert height / half == pytest.approx(math.tan(math.radians(20.0)))
    assert half * height * PILE_PACKING == pytest.approx(float(np.sum(shapes.area)))
    triangle = Polygon([(-half, 0), (half, 0), (0, height)])
    for k in (0, 1, 17, 33, 49):
        want = float(np.sum(shapes.area[:k])) / float(np.sum(shapes.area)) * triangle.area
        lo, hi = 0.0, height
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if triangle.intersection(
                box(-half, 0, half, mid)).area < want else (lo, mid)
        section = triangle.intersection(box(-half, lo - 1e-12, half, lo + 1e-12)).bounds
        assert rain_half_width(shapes, 20.0, k) == pytest.approx(section[2], abs=1e-9 * half)


def test_funnel_rate_is_the_2d_beverloo_flux():
    """W = C ρ_b sqrt(g) (D − k d)^{3/2} divided by the mean particle mass,
    computed here from the shapes' masses (not their areas)."""
    cfg = SimConfig.from_dict(FUNNEL)
    shapes = pile_shapes(cfg, 1)
    d = 2.0 * float(np.mean(shapes.radius))
    rho_b = PILE_PACKING * cfg.model.density
    mass = float(np.mean(shapes.mass))
    width = cfg.pour.outlet_width * d
    flux = BEVERLOO_C * rho_b * math.sqrt(GRAVITY) * (width - BEVERLOO_K * d) ** 1.5 / mass
    src = source(cfg, shapes, "wedge", GRAVITY)
    assert src.rate == pytest.approx(flux, rel=1e-12)
    assert src.elevation == pytest.approx(cfg.pour.outlet_height * d)
    assert mean_diameter(shapes) == d
    # the drip and both line sources keep the settings as set
    assert source(cfg, shapes, "layered", GRAVITY).rate == cfg.pour.rate


@pytest.mark.parametrize("seed", [1, 2])
def test_funnel_sets_the_flux_and_never_releases_onto_a_polygon(monkeypatch, tmp_path, seed):
    """Released per second over the pour = the Beverloo rate.  The schedule
    releases particle k at the first step at or after k/rate unless its spot
    is taken (then later, never earlier), so the count in the pour's span T
    is at most rate T + 1, and at least rate T − 1 if nothing waited; 2 % of
    the ~80 releases (1.6 particles) is that ±1 count plus the step, so the
    bound fails as soon as the stream waits for more than about one release
    interval, i.e. as soon as the pile, not the outlet, sets the flux."""
    cfg = SimConfig.from_dict(FUNNEL)
    rate = source(cfg, pile_shapes(cfg, seed), "wedge", GRAVITY).rate
    rec = recorded_pour(monkeypatch, tmp_path, cfg, "wedge", seed)
    assert len(rec) == cfg.pour.n_particles
    measured = (len(rec) - 1) / (rec[-1, 0] - rec[0, 0])
    assert measured == pytest.approx(rate, rel=0.02)
    # each polygon is released clear of every other (a touch is area 0;
    # 1e-12 of a polygon's ~3e-5 m² is the floating-point noise of shapely)
    assert rec[:, 2].max() < 1e-12 * float(np.min(pile_shapes(cfg, seed).area))


def test_rain_never_releases_onto_a_polygon_nor_off_the_plateau(monkeypatch, tmp_path):
    """In a real pour each particle k falls within the section of the target
    pile that :func:`rain_half_width` gives, whatever the pile's measured top."""
    cfg = SimConfig.from_dict(RAIN)
    shapes = pile_shapes(cfg, 3)
    rec = recorded_pour(monkeypatch, tmp_path, cfg, "layered", 3)
    assert len(rec) == cfg.pour.n_particles
    assert rec[:, 2].max() < 1e-12 * float(np.min(shapes.area))
    for _, k, _, x in rec:
        k = int(k)
        assert abs(x) <= max(rain_half_width(shapes, 20.0, k), shapes.radius[k])


@pytest.mark.parametrize("protocol, settings", [("wedge", {"point_source": "funnel",
                                                             "outlet_width": 100.0}),
                                                ("layered", {"line_source": "rain"})])
def test_new_sources_release_inside_side_walls(protocol, settings):
    """An outlet or a rain wider than a narrow box still releases each
    particle wholly inside its walls (as tests/test_protocols.py checks for
    the defaults)."""
    walls = (-0.02, 0.01)
    cfg = SimConfig.from_dict({"pour": {"n_particles": 400, **settings}})
    sim = Simulation(pile_shapes(cfg, 1), cfg.model, walls=walls)
    for k in range(1, 400):
        (x, _), = release_point(sim, cfg, protocol, 1, k)
        r = sim.shapes.radius[k]
        assert walls[0] + r <= x <= walls[1] - r


@pytest.mark.parametrize("protocol, settings", [("wedge", FUNNEL), ("layered", RAIN)])
def test_a_killed_pour_of_a_new_source_resumes_bit_for_bit(tmp_path, monkeypatch,
                                                            protocol, settings):
    """As tests/test_protocols.py does for the drip: killed in mid-pour, with a
    checkpoint at every pass, and resumed, it ends in the uninterrupted pile."""
    cfg = SimConfig.from_dict({"pour": {**settings["pour"], "n_particles": 30,
                                        "checkpoint_interval": 1e-9}})
    whole = tmp_path / "whole.nc"
    pour(cfg, protocol, 5, whole)
    ckpt, out = tmp_path / "ck.nc", tmp_path / "poured.nc"
    original = Simulation.run
    monkeypatch.setattr(Simulation, "run", dying_at_run(15))
    with pytest.raises(KeyboardInterrupt):
        pour(cfg, protocol, 5, out, checkpoint=ckpt)
    with xr.open_dataset(ckpt) as partial:
        assert 0 < partial.sizes["particle"] < 30
    monkeypatch.setattr(Simulation, "run", original)
    pour(cfg, protocol, 5, out, checkpoint=ckpt)
    with xr.open_dataset(whole) as a, xr.open_dataset(out) as b:
        assert (a.attrs["step"], a.attrs["time"]) == (b.attrs["step"], b.attrs["time"])
        for v in ("x", "y", "theta", "vx", "vy", "omega", "contact_i", "contact_j",
                  "force_x", "force_y", "contact_spring"):
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


def test_the_funnel_s_stream_speed_is_named_by_the_setting_that_sets_it():
    """A pour that does not land advises lowering its source's speed: for the funnel that is
    pour.outlet_width (the stream's speed follows from it), not a speed no setting holds."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 50, "point_source": "funnel", "outlet_width": 100}})
    src = source(cfg, pile_shapes(cfg, 1), "wedge", 9.81)
    assert src.origin[1].startswith("pour.outlet_width = 100 diameters")
