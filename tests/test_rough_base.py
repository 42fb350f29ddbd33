"""The rough base (``physics.rough_base``): fixed polygons on the support.

At its default (off) a pour is the one of before the setting, to the bit, and
its settings digest is unchanged.  On, the base polygons lie side by side on
the support without overlapping each other or a released particle, never
move, carry the whole weight of a pile at rest (to the rest criterion's
tolerance), reload with the pile so that a run continues bit for bit, and to
the analysis they are the support: the base pressure integrates to the
weight.  A 40-particle pour and its relaxation, about 20 s of CPU.
"""

import numpy as np
import pytest
import xarray as xr

from analysis.base_pressure import support_force_density
from analysis.states import load_state
from sim.config import STAGE_SECTIONS, ConfigError, ModelParams, SimConfig
from sim.engine import Simulation
from sim.geometry import polygon_overlap
from sim.io import load_simulation, pour_digest, save_state
from sim.pour import GRAVITY, pile_shapes, pour, rough_base
from sim.relax import relax
from sim.release import target_pile
from sim.scene import BODY_BASE, place_base
from scenes import rectangle, regular_polygon, shapes_of

SEED = 4
#: A gentle release (1 mm above the tip), so that the first particles would be
#: released into the base polygons if their release point were not raised; a
#: base as wide as a pile of these 40 particles with 0.5 deg flanks (+-0.4 m),
#: since the first ones bounce and roll up to 0.3 m away.
ROUGH = {"pour": {"n_particles": 40, "release_height": 0.001, "progress_interval": 1e9},
         "physics": {"rough_base": True, "rough_base_slope_deg": 0.5}}


def _overlap(ax, ay, bx, by):
    """Whether two convex polygons (world corners) overlap."""
    out = np.zeros(16)
    return polygon_overlap(ax, ay, bx, by, ax.mean(), ay.mean(), bx.mean(), by.mean(), 1e-12, out)


def _corners(base, b):
    """World corners of base polygon b."""
    s = slice(base.shapes.node_offset[b], base.shapes.node_offset[b + 1])
    return base.wx[s], base.wy[s]


def _world(sim, k):
    """World corners of particle k."""
    x, y = sim.shapes.corners(k)
    c, s = np.cos(sim.theta[k]), np.sin(sim.theta[k])
    return sim.position[k, 0] + c * x - s * y, sim.position[k, 1] + s * x + c * y


@pytest.fixture(scope="module")
def pile(tmp_path_factory):
    """The 40-particle pour on a rough base and its relaxation: ``(cfg, sim,
    poured file, relaxed file, the base's world corners before the pour, the
    released particles that overlapped a base polygon)``."""
    folder = tmp_path_factory.mktemp("rough")
    cfg = SimConfig.from_dict(ROUGH)
    drawn = rough_base(cfg, SEED, pile_shapes(cfg, SEED))
    overlapping = []
    place = Simulation.place

    def checked_place(sim, k, x, y, theta=0.0, vx=0.0, vy=0.0, omega=0.0):
        place(sim, k, x, y, theta, vx, vy, omega)
        ax, ay = _world(sim, k)
        overlapping.extend(k for b in range(sim.base.count) if _overlap(ax, ay, *_corners(sim.base, b)))

    Simulation.place = checked_place
    try:
        sim = pour(cfg, "wedge", SEED, folder / "poured.nc")
    finally:
        Simulation.place = place
    relax(sim, cfg)
    save_state(sim, folder / "relaxed.nc", cfg.to_dict(), stage="relaxed", protocol="wedge",
               seed=SEED)
    return cfg, sim, folder / "poured.nc", folder / "relaxed.nc", drawn, overlapping


def test_default_is_the_flat_support_bit_for_bit_with_the_same_digest(tmp_path):
    """A pour with the setting left out and one with it at its default are the
    same file to the bit, without base variables, and the settings digest is
    that of a configuration from before the setting."""
    tiny = {"pour": {"n_particles": 10, "rate": 400.0, "progress_interval": 1e9},
            "model": {"integrator": "verlet"}}
    explicit = {**tiny, "physics": {"rough_base": False, "rough_base_slope_deg": 10.0}}
    paths = []
    for k, data in enumerate((tiny, explicit)):
        paths.append(tmp_path / f"{k}.nc")
        pour(SimConfig.from_dict(data), "wedge", 1, paths[-1])
    with xr.open_dataset(paths[0]) as a, xr.open_dataset(paths[1]) as b:
        assert not [v for v in a.data_vars if v.startswith("base_")]
        assert a.attrs["step"] == b.attrs["step"]
        for v in a.data_vars:
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
    settings = SimConfig.from_dict(explicit).to_dict()
    before = {s: {k: v for k, v in settings[s].items() if not k.startswith("rough_base")}
              for s in STAGE_SECTIONS["pour"]}
    assert pour_digest(settings) == pour_digest(before)
    assert pour_digest({**settings, "physics": {**settings["physics"], "rough_base": True}}) \
        != pour_digest(before)


def test_base_polygons_lie_side_by_side_on_the_support(pile):
    """Each base polygon's lowest corner is on y = 0, their x ranges follow each
    other without overlapping, no two overlap, and they span the base of a
    triangular pile with flanks at ``physics.rough_base_slope_deg``."""
    cfg, sim, *_ = pile
    base = sim.base
    assert base.count > 10
    size = float(np.mean(sim.shapes.radius))
    assert np.allclose(base.box[:, 2], 0.0, atol=1e-12 * size)
    assert np.all(base.box[1:, 0] > base.box[:-1, 1])
    assert not any(_overlap(*_corners(base, b), *_corners(base, b + 1))
                   for b in range(base.count - 1))
    assert np.all(base.box[1:, 0] - base.box[:-1, 1] < 1e-6 * size)
    half = -base.box[0, 0]
    assert base.box[-1, 1] == pytest.approx(half, rel=1e-9)
    widest = float(np.max(base.box[:, 1] - base.box[:, 0]))
    assert target_pile(pile_shapes(cfg, SEED), cfg.physics.rough_base_slope_deg)[0] - widest < half


def test_released_particles_clear_of_the_base(pile):
    """No released particle overlaps a base polygon, though the release height
    (1 mm above the tip) lies below the base's top."""
    cfg, sim, *_, overlapping = pile
    assert cfg.pour.release_height < sim.base.top
    assert overlapping == []


def test_base_polygons_never_move(pile):
    """After the pour and the relaxation the base is, to the bit, the one
    drawn from the seed, in the simulation and in the state files."""
    cfg, sim, poured, relaxed, drawn, _ = pile
    for name in ("x", "y", "theta", "wx", "wy", "box"):
        np.testing.assert_array_equal(getattr(sim.base, name), getattr(drawn, name), err_msg=name)
    for path in (poured, relaxed):
        with xr.open_dataset(path) as ds:
            for name in ("x", "y", "theta"):
                np.testing.assert_array_equal(ds[f"base_{name}"].values, getattr(drawn, name))
            np.testing.assert_array_equal(ds["base_node_x"].values, drawn.shapes.node_x)


def test_the_base_carries_the_weight_of_the_pile_at_rest(pile):
    """At rest the contacts of the pile with the base (and the support, if any
    particle reaches it between the polygons) carry its weight W.

    The rest criterion bounds ``sum_p |F_p + m_p g| < relax.unbalanced_force W``
    (:func:`sim.relax.relax`); the sum over the particles of the y part of
    ``F_p + m_p g`` is the bodies' push minus W (the forces between particles
    cancel), so the two differ by less than that."""
    cfg, sim, *_ = pile
    c = sim.contacts()
    weight = float(np.sum(sim.shapes.mass[:sim.n])) * GRAVITY
    on_base = c["j"] <= BODY_BASE
    assert on_base.sum() >= 5
    carried = float(c["fy"][c["j"] < 0].sum())
    assert abs(carried - weight) < cfg.relax.unbalanced_force * weight
    assert float(c["fy"][on_base].sum()) > 0.9 * weight


def test_a_relaxed_pile_reloads_with_its_base_and_runs_on_bit_for_bit(pile, tmp_path):
    """A pile saved mid-run and reloaded goes on as the uninterrupted run:
    the base and its contacts' springs are in the file."""
    cfg, _, poured, *_ = pile
    sim, _ = load_simulation(poured)
    sim.run(steps=300)
    save_state(sim, tmp_path / "mid.nc", cfg.to_dict(), stage="checkpoint")
    sim.run(steps=300)
    again, _ = load_simulation(tmp_path / "mid.nc")
    again.run(steps=300)
    assert again.base.count == sim.base.count
    np.testing.assert_array_equal(again.r[:, :, :again.n], sim.r[:, :, :sim.n])
    np.testing.assert_array_equal(again.contacts()["j"], sim.contacts()["j"])


def test_the_base_pressure_is_the_force_on_the_base_layer(pile):
    """To the analysis the base polygons are the support, not particles: the
    file holds the pile's 40 particles, and the normal force density on the
    support integrates to the weight (as above)."""
    cfg, sim, _, relaxed, *_ = pile
    state = load_state(str(relaxed))
    assert state.n_particles == cfg.pour.n_particles
    assert state.contact_j.min() == -1 and state.support.sum() >= 5
    edges = np.linspace(sim.base.box[0, 0], sim.base.box[-1, 1], 21)
    normal, _ = support_force_density(state, edges)
    weight = float(state.mass.sum()) * state.gravity
    assert abs(float(np.sum(normal * np.diff(edges))) - weight) < cfg.relax.unbalanced_force * weight


@pytest.mark.parametrize("key, value, says", [
    ("rough_base", "yes", "physics.rough_base = 'yes': must be true or false"),
    ("rough_base", 1, "physics.rough_base = 1: must be true or false"),
    ("rough_base_slope_deg", 0, "physics.rough_base_slope_deg = 0: must be >= 0.1 and <= 45"),
    ("rough_base_slope_deg", 60.0, "physics.rough_base_slope_deg = 60.0: must be >= 0.1 and <= 45"),
])
def test_bad_values_are_refused_in_one_line(key, value, says):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"physics": {key: value}})
    assert str(err.value).startswith(says) and "\n" not in str(err.value)


def test_a_rough_base_needs_the_support():
    with pytest.raises(ConfigError, match=r"physics.rough_base = True: .*physics.support = False"):
        SimConfig.from_dict({"physics": {"rough_base": True, "support": False}})


def _square_on_two_octagons(tan_tilt, friction=0.3):
    """A 12 mm square laid across the flat tops of two octagons (circumradius
    5 mm) of a rough base, gravity tilted by ``atan(tan_tilt)``; friction
    ``friction`` between particles, 0.9 with the support (which it never touches).

    The octagons have more corners than the square: the narrow phase's
    scratch must fit the base's polygons too."""
    r, a = 0.005, 0.012
    octagon = regular_polygon(8, r, np.pi / 8)
    half = r * np.cos(np.pi / 8)
    base = place_base(shapes_of(octagon, octagon), [-half * (1 + 1e-9), half * (1 + 1e-9)],
                      [half, half], [0.0, 0.0])
    tilt = np.arctan(tan_tilt)
    sim = Simulation(shapes_of(rectangle(a, a)), ModelParams(friction=friction, support_friction=0.9),
                     gravity=(GRAVITY * np.sin(tilt), -GRAVITY * np.cos(tilt)), base=base)
    sim.place(0, 0.0, 2 * half + a / 2 + 1e-5)
    return sim


def test_a_square_rests_on_two_base_polygons_and_slides_past_the_friction_angle():
    """On the level tops of two base polygons a square settles with its weight
    split between them; gravity tilted within the particles' friction angle
    (tan 0.2 < mu = 0.3) it sticks, beyond it (tan 0.5) it slides, though the
    support's friction (0.9) would hold it."""
    sim = _square_on_two_octagons(0.0)
    sim.run(duration=0.05)
    c = sim.contacts()
    weight = float(sim.shapes.mass[0]) * GRAVITY
    assert sorted(c["j"]) == [BODY_BASE - 1, BODY_BASE]
    assert c["fy"].sum() == pytest.approx(weight, rel=1e-6)
    assert c["fy"] == pytest.approx([weight / 2, weight / 2], rel=1e-3)
    moved = {}
    for tan_tilt in (0.2, 0.5):
        sim = _square_on_two_octagons(tan_tilt)
        sim.run(duration=0.02)
        x0 = sim.position[0, 0]
        sim.run(duration=0.03)
        moved[tan_tilt] = sim.position[0, 0] - x0
    assert abs(moved[0.2]) < 1e-6 and moved[0.5] > 1e-4


def test_the_summary_reports_the_base_carrying_the_weight(pile, capsys):
    """``python -m sim summary`` of the relaxed pile: the support reaction is
    the weight to the rest criterion's tolerance (issue 59, item 3: -1.0, the
    base's contacts left out). At rest ``sum_p |F_p + m_p g| < u W`` (u =
    relax.unbalanced_force); its y part summed over the particles is the bodies'
    push minus W, the forces between particles cancelling, and with no walls
    every body is the base or the support: |R/W - 1| < u."""
    import json

    from sim.cli import main

    cfg, _, _, relaxed, *_ = pile
    capsys.readouterr()
    assert main(["summary", str(relaxed)]) == 0
    row = json.loads(capsys.readouterr().out)
    assert abs(row["support_reaction_over_weight_minus_1"]) < cfg.relax.unbalanced_force


def test_the_picture_draws_the_base_under_the_pile(pile, tmp_path, monkeypatch):
    """``analysis draw`` of the relaxed pile draws the base polygons where the
    simulator has them (issue 59, item 3: none were drawn and the pile floated
    above the support line): their corners are the base's world corners, and
    every contact of a particle with the base lies on a drawn polygon (within
    the overlap a contact has, 1e-3 of the mean polygon size here)."""
    from analysis import draw
    from matplotlib.path import Path as MplPath

    cfg, sim, _, relaxed, *_ = pile
    drawn = draw.base_polygons(str(relaxed))
    assert len(drawn) == sim.base.count
    for b, corners in enumerate(drawn):
        wx, wy = _corners(sim.base, b)
        np.testing.assert_allclose(corners, np.column_stack((wx, wy)), atol=1e-12)
    with xr.open_dataset(relaxed) as ds:
        on_base = ds["contact_j"].values <= BODY_BASE
        b = BODY_BASE - ds["contact_j"].values[on_base]
        points = np.column_stack((ds["contact_x"].values[on_base], ds["contact_y"].values[on_base]))
    assert len(points) >= 5
    tol = 1e-3 * float(np.mean(sim.shapes.radius))
    for k, point in zip(b, points):
        assert MplPath(drawn[k]).contains_point(point, radius=tol) or \
            MplPath(drawn[k]).contains_point(point, radius=-tol), (k, point)
    figures = []
    monkeypatch.setattr("analysis.figures.save", lambda fig, paths, dpi: figures.append(fig))
    draw.draw_state(str(relaxed), str(tmp_path / "pile.png"))
    (ax,) = [a for a in figures[0].axes if a.get_label() != "<colorbar>"]
    paths = [p.vertices for c in ax.collections for p in c.get_paths()]
    for corners in drawn:
        assert any(len(v) >= len(corners) and np.allclose(v[:len(corners)], corners)
                   for v in paths)


def test_the_support_stretch_is_refused_on_a_rough_base_in_one_line(pile, tmp_path):
    """The base polygons are fixed and the stretch moves the flat support
    under them, which touches no particle (issue 59, item 3: load 0 N, the
    whole relax.max_time run and a late failure); refused before anything runs."""
    from sim.probe import stretch_file

    cfg, _, _, relaxed, *_ = pile
    with pytest.raises(ValueError) as err:
        stretch_file(cfg, relaxed, 1e-4, tmp_path / "stretched.nc")
    said = str(err.value)
    assert "\n" not in said and said.startswith(f"{relaxed}: the pile lies on a rough base")
    assert "physics.rough_base" in said
    assert not (tmp_path / "stretched.nc").exists()


@pytest.mark.parametrize("value", [1e-9, 1e-6, 0.09])
def test_flanks_flatter_than_a_tenth_of_a_degree_are_refused_up_front(value):
    """The base spans a triangular pile of all the particles with flanks at
    rough_base_slope_deg, whose width grows as its slope's tan^(-1/2): at 1e-9
    degrees 10^7 polygons for the study's pile (issue 59, item 3: 25 min and
    2.4 GB, then killed; 1e-6 laid for 139 s before a 3 s pour). Refused when
    read, in one line naming the setting, its value and what is allowed."""
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"physics": {"rough_base": True, "rough_base_slope_deg": value}})
    said = str(err.value)
    assert said.startswith(f"physics.rough_base_slope_deg = {value}: must be >= 0.1 and <= 45")
    assert "\n" not in said


def test_walls_wider_than_the_flattest_pile_are_refused_before_a_polygon_is_laid(monkeypatch):
    """Between walls the base spans them; walls farther apart than the base of
    the flattest pile the slope allows (0.1 degrees: +-1.0 m for these 40
    particles) would lay a base no pile of them covers, at a cost growing with
    its width: refused in one line naming the walls, the particles and the
    widest walls allowed, before the first polygon is drawn."""
    import sim.pour

    monkeypatch.setattr(sim.pour, "lay_base", lambda *a, **k: pytest.fail("base laid"))
    cfg = SimConfig.from_dict({"pour": {"n_particles": 40},
                               "physics": {"rough_base": True, "walls": [-50.0, 50.0]}})
    with pytest.raises(ConfigError) as err:
        rough_base(cfg, SEED, pile_shapes(cfg, SEED))
    said = str(err.value)
    assert said.startswith("physics.walls = [-50.0, 50.0] with physics.rough_base = true:")
    assert "\n" not in said and "allowed: walls within" in said


def test_a_pour_lays_its_base_once(tmp_path, monkeypatch):
    """The check of the pour and its start share one base (issue 59, item 3:
    it was laid twice, each time as long as the other)."""
    import sim.pour
    import sim.scene

    laid = []
    lay = sim.scene.lay_base

    def counted(*args, **kwargs):
        laid.append(1)
        return lay(*args, **kwargs)

    monkeypatch.setattr(sim.pour, "lay_base", counted)
    cfg = SimConfig.from_dict({"pour": {"n_particles": 3, "progress_interval": 1e9},
                               "physics": {"rough_base": True, "rough_base_slope_deg": 1.0}})
    pour(cfg, "wedge", SEED, tmp_path / "poured.nc")
    assert len(laid) == 1
