"""The rain over a finite table (``pour.line_source: table``, issue 55 item 3):
the geometry of the sieve experiments, particles that leave the table removed.

Checked on real pours: no particle of the saved pile lies beyond the table's
edge, the particles released are those on the table plus those that left it
(counted and weighed against the pile's own shapes), the flanks of a pile
that shed particles stand near the angle of repose, the frames mark a
particle that left as gone from then on, a killed pour resumes bit for bit,
and a table setting out of range is refused in one line before anything runs.
"""

import logging
import math

import numpy as np
import pytest
import xarray as xr
from scenes import dying_at_run

from sim.cli import main
from sim.config import ConfigError, SimConfig
from sim.engine import Simulation
from sim.pour import PARK_MARGIN, pile_shapes, pour, rest_pose
from sim.release import table_half_width, target_pile

QUIET = {"progress_interval": 1e9, "checkpoint_interval": 1e9}
#: A gentle release (docs/model.md: the rain needs one to lay layers down).
TABLE = {"pour": {"n_particles": 150, "line_source": "table", "release_speed": 0.2,
                  "release_height": 0.005, **QUIET}}


def radii(ds):
    """Circumradius of each particle of a state file, from its corners."""
    cut = np.cumsum(ds["node_count"].values)[:-1]
    return np.array([np.hypot(x, y).max() for x, y in zip(np.split(ds["node_x"].values, cut),
                                                           np.split(ds["node_y"].values, cut))])


class Lines(logging.Handler):
    """The log lines of a run, kept."""

    def __init__(self):
        super().__init__()
        self.lines = []

    def emit(self, record):
        self.lines.append(record.getMessage())


@pytest.fixture(scope="module")
def table_pile(tmp_path_factory):
    """A pile of 150 released particles poured on the table (seed 2), with its frames and log lines."""
    out = tmp_path_factory.mktemp("table") / "poured.nc"
    cfg = SimConfig.from_dict(TABLE)
    lines, logger = Lines(), logging.getLogger("sim")
    level = logger.level
    logger.addHandler(lines)
    logger.setLevel(logging.INFO)
    try:
        pour(cfg, "layered", 2, out, frames=out.with_name("frames.nc"))
    finally:
        logger.removeHandler(lines)
        logger.setLevel(level)
    TABLE_LOG[:] = lines.lines
    return cfg, out


#: The log lines of the module's table pour.
TABLE_LOG = []


def test_the_table_is_the_base_of_the_pile_its_released_particles_fill_twice():
    """W is the half base of a triangle at the slope holding half the released
    area (solid fraction 0.8): the rain fills that triangle when it has
    released twice its area (sim.release.table_half_width)."""
    shapes = pile_shapes(SimConfig.from_dict(TABLE), 2)
    half = table_half_width(shapes, 28.0)
    area = 0.5 * float(np.sum(shapes.area)) / 0.8
    assert half * half * math.tan(math.radians(28.0)) == pytest.approx(area, rel=1e-12)
    assert half == pytest.approx(target_pile(shapes, 28.0)[0] / math.sqrt(2.0))


def test_no_particle_of_the_saved_pile_lies_beyond_the_table(table_pile):
    _, out = table_pile
    with xr.open_dataset(out) as ds:
        assert np.all(np.abs(ds["x"].values) <= ds.attrs["table_half_width"])
        # and the contacts are among the pile's own particles (or with the support)
        assert ds["contact_i"].values.max() < ds.sizes["particle"]
        assert set(ds["contact_j"].values[ds["contact_j"].values < 0]) <= {-1}


def test_the_summary_line_counts_the_saved_piles_contacts(table_pile):
    """The pour's last line gives the kept pile's coordination, 2 × particle pairs / particles,
    from the saved contacts (it read 0.00 when the reloaded pile had evaluated no force)."""
    _, out = table_pile
    with xr.open_dataset(out) as ds:
        pairs = int(np.sum(ds["contact_j"].values >= 0))
        expected = 2 * pairs / ds.sizes["particle"]
    (line,) = [t for t in TABLE_LOG if " done: wall " in t]
    assert expected > 1.0 and f"mean coordination {expected:.2f};" in line


def test_released_are_those_on_the_table_plus_those_removed(table_pile):
    """Counted and weighed: the saved particles' masses are released masses
    (each used once), and the ones missing are as many as left the table."""
    cfg, out = table_pile
    masses = list(pile_shapes(cfg, 2).mass)
    with xr.open_dataset(out) as ds:
        assert ds.attrs["released"] == cfg.pour.n_particles
        assert ds.sizes["particle"] + ds.attrs["left_table"] == ds.attrs["released"]
        assert 0 < ds.attrs["left_table"] < ds.attrs["released"]
        for m in ds["mass"].values:
            masses.remove(m)          # raises if a saved particle is not a released one
    assert len(masses) == ds.attrs["left_table"]


def test_the_flanks_of_a_pile_that_shed_particles_stand_near_repose(table_pile):
    """The pile reaches the table's edges, and its height over the half-width
    is the tangent of the smaller of the table's slope (28°) and the angle of
    repose: the plateau rises at the rain's rate to ``W tan 28°`` by the end,
    unless flanks at repose meet below it (sim.release.table_half_width).
    The angle of repose of these polygons is 22.7-28.1° (300-particle drip
    and funnel piles, docs/model.md); 20-30° allows for the packing (0.8 ±
    5 %) and the rounding of a small pile's top; a rain wider than its pile
    (nothing shed) stands at a few degrees (the rain's apron, 7-13°)."""
    _, out = table_pile
    with xr.open_dataset(out) as ds:
        x, y, r = ds["x"].values, ds["y"].values, radii(ds)
        half = ds.attrs["table_half_width"]
    assert x.min() - r[np.argmin(x)] < -half + 2 * r.max()
    assert x.max() + r[np.argmax(x)] > half - 2 * r.max()
    assert 20.0 <= math.degrees(math.atan(float(np.max(y + r)) / half)) <= 30.0


def test_the_frames_mark_a_particle_that_left_the_table_as_gone(table_pile):
    """From the frame where it is first gone, a released particle stays NaN,
    and the last frame holds as many particles as the saved pile."""
    _, out = table_pile
    with xr.open_dataset(out.with_name("frames.nc")) as fr, xr.open_dataset(out) as ds:
        released = fr["released"].values
        gone = ~np.isfinite(fr["x"].values) & (np.arange(fr.sizes["particle"]) < released[:, None])
        assert np.all(gone[1:] >= gone[:-1])             # once gone, gone for good
        assert int(gone[-1].sum()) == ds.attrs["left_table"]
        assert int(np.isfinite(fr["x"].values[-1]).sum()) == ds.sizes["particle"]
        assert np.all(np.abs(fr["landing_x"].values[np.isfinite(fr["landing_x"].values)])
                      <= ds.attrs["table_half_width"])


def test_a_parked_particle_rests_on_its_edge():
    """The rest pose stands the polygon on the support on an edge, at rest:
    over 50 ms it neither slides nor turns."""
    cfg = SimConfig.from_dict(TABLE)
    sim = Simulation(pile_shapes(cfg, 2), cfg.model, gravity=(0.0, -9.81))
    theta, height = rest_pose(sim.shapes, 0)
    sim.place(0, 1.0, height * (1.0 + 1e-9), theta)
    sim.run(duration=0.05)
    # it sinks into its overlap with the support (about m g / Y per unit edge),
    # nothing more: 10 µm is 1 % of the 0.2 R_max gap between parking slots
    assert abs(sim.position[0, 0] - 1.0) < 1e-5
    assert abs(sim.theta[0] - theta) < 1e-3
    assert np.hypot(*sim.velocity[0]) < 1e-3          # relax.max_speed


def test_a_table_setting_out_of_range_is_refused_in_one_line(tmp_path, caplog):
    for value, words in ((5.0, ["pour.table_slope_deg = 5.0", "10", "45"]),
                         (math.inf, ["pour.table_slope_deg = inf"])):
        with pytest.raises(ConfigError) as err:
            SimConfig.from_dict({"pour": {"line_source": "table", "table_slope_deg": value}})
        assert "\n" not in str(err.value) and all(w in str(err.value) for w in words)
    status = main(["pour", "--params", '{"pour": {"line_source": "table", "table_slope_deg": 50}}',
                   "--protocol", "layered", "--seed", "1", "--out", str(tmp_path / "p.nc")])
    assert status == 2 and not (tmp_path / "p.nc").exists()
    errors = [r.getMessage() for r in caplog.records if r.levelno >= 40]
    assert len(errors) == 1 and "pour.table_slope_deg = 50" in errors[0]


def test_a_killed_table_pour_resumes_bit_for_bit(tmp_path, monkeypatch):
    """Killed after particles were parked, with a checkpoint at every pass, and
    resumed: the uninterrupted pile, to the bit."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 50, "line_source": "table", "rate": 200.0,
                                        **QUIET, "checkpoint_interval": 1e-9}})
    whole = tmp_path / "whole.nc"
    pour(cfg, "layered", 5, whole)
    ckpt, out = tmp_path / "ck.nc", tmp_path / "poured.nc"
    original = Simulation.run
    monkeypatch.setattr(Simulation, "run", dying_at_run(40))
    with pytest.raises(KeyboardInterrupt):
        pour(cfg, "layered", 5, out, checkpoint=ckpt)
    half = table_half_width(pile_shapes(cfg, 5), cfg.pour.table_slope_deg)
    with xr.open_dataset(ckpt) as partial:
        assert 0 < partial.sizes["particle"] < 50
        assert np.any(np.abs(partial["x"].values) > half + PARK_MARGIN / 2)   # some were parked
    monkeypatch.setattr(Simulation, "run", original)
    pour(cfg, "layered", 5, out, checkpoint=ckpt)
    with xr.open_dataset(whole) as a, xr.open_dataset(out) as b:
        assert (a.attrs["step"], a.attrs["time"]) == (b.attrs["step"], b.attrs["time"])
        assert a.attrs["left_table"] == b.attrs["left_table"]
        for v in ("x", "y", "theta", "vx", "vy", "omega", "contact_i", "contact_j",
                  "force_x", "force_y", "contact_spring", "integrator_state"):
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
