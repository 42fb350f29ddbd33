"""The support-stretch probe (stage ``stretched``, sim.probe.stretch_file):
its load is what it claims and it is one that gravity cannot make.

* One square at rest on the support: stretching the support by eps moves its
  spring's anchor by eps x (the spring changes by -(2/7) Y eps x at once),
  and the square, which no other horizontal force holds, follows the surface
  by eps x.
* A small heap (45 polygons laid in a triangle and relaxed, committed as
  tests/data/stretch_heap.nc by tests/stretch_heap.py, since its fall is
  chaotic and another processor settles another heap): after a stretch of
  5e-6, 1e-5 and 2e-5 (the last through the command line), every spring
  on the support has changed by exactly what the
  particle's displacement relative to the stretched surface says (so the
  surface moved by eps x), the particles on it followed the surface, the
  pile is in equilibrium (no net horizontal force from the support, the
  weight on it), and the reaction conjugate to the stretch,
  P = sum_c x_c F_x,c over the support's contacts, grows linearly with eps
  while no contact slips, and more slowly once some do, and does positive
  work; and the Cambou strain increment it makes is not
  in the span of those of the gravity reduction and the tilt, at every RVE
  and over the whole heap (a linear pile's gravity probes span two shapes).
"""

import json
import shutil

import numpy as np
import pytest
import xarray as xr
from scenes import rectangle, scene
from stretch_heap import FILE as HEAP, SETTINGS

from sim.config import SimConfig
from sim.contact_law import tangential_stiffness
from sim.step import ROW
from sim.pour import GRAVITY
from sim.probe import probe_file, stretch_file, tilt_file
from sim.scene import BODY_SUPPORT

K_T = tangential_stiffness(1e7)
EPS = 1e-5


def test_stretching_the_support_moves_the_anchor_of_a_resting_square():
    """A stretch of 5e-7 changes the square's spring by (2/7) Y eps x = 0.07 N,
    below its Coulomb cap mu m g = 0.2 N: the square's material point at
    the contact follows the surface by eps x (the square turns a little as
    well as sliding).  A stretch of 1e-4 (14 N at once) exceeds the cap: the contact
    slips, and the square moves by no more than about mu m g / k_t."""
    sim = scene([rectangle(4e-3, 4e-3)], [(0.05, 0.00199, 0, 0, 0, 0)], gravity=(0.0, -9.81), support=True)
    sim.drag = 20.0
    sim.run(duration=0.2)
    cap = 0.5 * float(sim.shapes.mass[0]) * 9.81
    for eps, follows in ((5e-7, True), (1e-4, False)):
        x0, row = sim.position[0, 0], sim.bout[0, 0].copy()
        assert row[ROW["active"]] > 0 and abs(sim.velocity[0, 0]) < 1e-6
        spring0 = sim.bspring[0, 0]
        assert sim.stretch_body(BODY_SUPPORT, eps) == 1
        assert sim.bspring[0, 0] - spring0 == pytest.approx(-K_T * eps * row[ROW["sx"]] * -row[ROW["ny"]],
                                                            rel=1e-12)
        theta0, y0 = sim.theta[0], sim.position[0, 1]
        sim.run(duration=0.3)
        # the square's material point at the force point (it also turns a little)
        moved = sim.position[0, 0] - x0 - (sim.theta[0] - theta0) * (row[ROW["sy"]] - y0)
        if follows:
            assert moved == pytest.approx(eps * row[ROW["sx"]], rel=1e-2)
        else:
            assert 0 < moved < 2 * cap / K_T < 0.05 * eps * row[ROW["sx"]]
    with pytest.raises(ValueError, match="support_friction = 0"):
        scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)], support=True,
              support_friction=0.0).stretch_body(BODY_SUPPORT, 1e-4)
    with pytest.raises(ValueError, match="not a body of this scene"):
        scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)]).stretch_body(BODY_SUPPORT, 1e-4)


@pytest.fixture(scope="module")
def heap(tmp_path_factory):
    """The committed relaxed heap (tests/stretch_heap.py), its gravity
    reduction and tilt, and stretches of EPS / 2, EPS and 2 EPS."""
    from sim.cli import main

    d = tmp_path_factory.mktemp("heap")
    shutil.copyfile(HEAP, d / "relaxed.nc")
    cfg = SimConfig.from_dict(SETTINGS)
    probe_file(cfg, d / "relaxed.nc", 0.1, d / "reduced.nc")
    tilt_file(cfg, d / "relaxed.nc", 0.05, d / "tiltp05.nc", "tiltp05")
    stretch_file(cfg, d / "relaxed.nc", EPS / 2, d / "stretched_half.nc")
    stretch_file(cfg, d / "relaxed.nc", EPS, d / "stretched.nc")
    assert main(["probe", "--params", json.dumps(SETTINGS), "--input", str(d / "relaxed.nc"),
                 "--stretch", repr(2 * EPS), "--out", str(d / "stretched2.nc"), "--stage", "stretched"]) == 0
    return d, cfg


def _support(ds):
    """Per particle on the support: contact point, spring, normal y, force."""
    on = ds["contact_j"].values == BODY_SUPPORT
    return {int(i): (ds["contact_x"].values[on][k], ds["contact_y"].values[on][k], ds["contact_spring"].values[on][k],
                     ds["normal_y"].values[on][k], ds["force_x"].values[on][k], ds["force_y"].values[on][k])
            for k, i in enumerate(ds["contact_i"].values[on])}


def test_the_stretch_moves_the_support_surface_by_eps_x_and_its_reaction_grows_linearly(heap):
    d, cfg = heap
    a = xr.open_dataset(d / "relaxed.nc")
    weight = float(a["mass"].values.sum()) * GRAVITY
    before = _support(a)
    moments = []
    for name, eps in (("stretched_half", EPS / 2), ("stretched", EPS), ("stretched2", 2 * EPS)):
        b = xr.open_dataset(d / f"{name}.nc")
        assert b.attrs["stage"] == "stretched" and b.attrs["support_stretch"] == eps
        after = _support(b)
        both = sorted(set(before) & set(after))
        reach = K_T * eps * max(abs(after[i][0]) for i in both)      # the largest anchor move, as a force
        assert len(both) >= 8
        for i in both:
            sx, sy, spring, ny, _, _ = after[i]
            # the material point at the force point moved by du (small rotation); the spring
            # holds (2/7) Y times its displacement relative to the surface, moved by eps x
            du = (b["x"].values[i] - a["x"].values[i]) - (b["theta"].values[i] - a["theta"].values[i]) * \
                (sy - b["y"].values[i])
            assert spring - before[i][2] == pytest.approx(K_T * -ny * (du - eps * sx), abs=0.01 * reach), i
            assert du == pytest.approx(eps * sx, abs=0.1 * eps * 0.05), i          # it follows the surface
        fx = sum(c[4] for c in after.values())
        fy = sum(c[5] for c in after.values())
        u = cfg.relax.unbalanced_force
        assert abs(fx) < u * weight and fy == pytest.approx(weight, rel=2 * u)
        moment = sum(c[0] * c[4] for c in after.values())
        assert b.attrs["support_reaction_moment"] == pytest.approx(moment, rel=1e-12)
        assert b.attrs["support_reaction_moment_before"] == pytest.approx(sum(c[0] * c[4] for c in before.values()),
                                                                          rel=1e-12)
        moments.append(moment - b.attrs["support_reaction_moment_before"])
    # The relaxation leaves an unbalanced force below 1e-6 of the weight, an error of P of
    # about 1e-6 W x_max = 7e-7 N m, 4e-4 of the smallest increment: what departs from
    # linearity beyond that is contacts that slip.  The heap resists (positive work
    # eps dP / 2); below EPS no contact of this heap slips, so P grows linearly (2 %);
    # past it some do, and slip only softens a frictional heap: dP grows, by at most 2.
    half, one, two = moments
    assert half > 0
    assert one / half == pytest.approx(2.0, rel=0.02)
    assert 1.0 < two / one <= 2.0 * (1 + 1e-3)


def test_the_stretch_strains_the_heap_in_a_shape_no_gravity_probe_makes(heap):
    from analysis.params import parse_params
    from analysis.probes import probe_increments
    from analysis.states import load_state

    import analysis.general_elastic as ge

    d, _ = heap
    relaxed = load_state(str(d / "relaxed.nc"))
    probes = {k: load_state(str(d / f"{k}.nc")) for k in ("reduced", "tiltp05", "stretched", "stretched2")}
    # (grid, the least sine of the stretch's angle to the gravity plane and the least
    # smallest singular value of the three unit strains each RVE must show).  A strain
    # direction that knew nothing of the probe would have a sine uniform on [0, 1] (median
    # 0.5): the whole heap carries the claim, well above that; the small RVEs (8-20
    # particles of the committed heap, tests/stretch_heap.py) are noisy, so each must
    # only be clearly off the plane (more than 14 degrees, the three strains of rank 3)
    # and most of them as far off as a random direction would be
    grids = (('{"x_min": 0.0, "x_max": 0.0, "y_min": 0.05, "y_max": 0.05, "spacing": 0.01}, '
              '"rve": {"size": 0.3, "min_particles": 8, "min_solid_fraction": 0.0}', 0.5, 0.3),
             ('{"x_min": -0.02, "x_max": 0.02, "y_min": 0.01, "y_max": 0.01, "spacing": 0.01}, '
              '"rve": {"size": 0.025, "min_particles": 8, "min_solid_fraction": 0.3}', 0.25, 0.15))
    spans = []
    for grid, least_span, least_rank in grids:
        params = parse_params('{"grid": ' + grid + ', "strain": {"min_contacts": 6}}')
        u = ge.mandel(probe_increments(relaxed, probes, params)["strain_increment"].values)   # probe, y, x, 3
        for at in zip(*np.nonzero(np.all(np.isfinite(u), axis=(0, -1)))):
            gravity, stretch = u[:2][(slice(None), *at)], u[2][at]
            q, _ = np.linalg.qr(gravity.T)
            off_span = np.linalg.norm(stretch - q @ (q.T @ stretch)) / np.linalg.norm(stretch)
            assert off_span > least_span, at                  # sin of its angle to the gravity plane
            stack = u[:3][(slice(None), *at)]
            stack = stack / np.linalg.norm(stack, axis=1, keepdims=True)
            assert np.linalg.svd(stack, compute_uv=False)[-1] > least_rank, at    # rank 3, clear of 2
            assert np.linalg.norm(u[3][at]) / np.linalg.norm(stretch) == pytest.approx(2.0, rel=0.1)
            spans.append(off_span)
    assert len(spans) >= 5
    assert np.median(spans) > 0.5


def test_the_stretch_refuses_what_it_cannot_do_before_it_runs(heap):
    d, cfg = heap
    out = d / "refused.nc"
    with pytest.raises(ValueError, match="in \\(-0.01, 0.01\\), not 0"):
        stretch_file(cfg, d / "relaxed.nc", 0.0, out)
    frictionless = SimConfig.from_dict({**cfg.to_dict(), "model": {**cfg.to_dict()["model"], "support_friction": 0.0}})
    with pytest.raises(ValueError, match="support_friction = 0.0"):
        stretch_file(frictionless, d / "relaxed.nc", EPS, out)
    assert not out.exists()
