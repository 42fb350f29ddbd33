"""The bench's LAMMPS polygon peer: the bodies it hands LAMMPS and what it reads back."""

import json
import re

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from sim.config import ModelParams
from sim.numerics import lammps_polygons as lp
from sim.numerics.bench import _shapes
from sim.numerics import lammps_peer
from sim.numerics.lammps_peer import PeerUnavailable


def _pile(n=60, seed=2):
    shapes = _shapes(np.random.default_rng(seed), n, ModelParams())
    theta = np.random.default_rng(seed + 1).uniform(0.0, 2.0 * np.pi, n)
    return shapes, theta, lp.bodies(shapes, theta)


def _bodies_of(text):
    """(mass, x, y) of the Atoms section and, per body, (inertia, vertices, diameter)."""
    atoms_text = text.split("Atoms # body")[1].split("Bodies")[0]
    atoms = np.array(atoms_text.split(), dtype=float).reshape(-1, 7)
    lines = text.split("Bodies")[1].strip().splitlines()
    out, k = [], 0
    while k < len(lines):
        _, nint, ndouble = map(int, lines[k].split())
        count = int(lines[k + 1])
        values = np.array(" ".join(lines[k + 2:k + 3 + count + 1]).split(), dtype=float)
        assert nint == 1 and ndouble == 6 + 3 * count + 1 == len(values)
        out.append((values[:6], values[6:6 + 3 * count].reshape(count, 3), values[-1]))
        k += 3 + count + 1
    return atoms, out


def _world_corners(shapes, theta, k):
    o = shapes.node_offset
    bx, by = shapes.node_x[o[k]:o[k + 1]], shapes.node_y[o[k]:o[k + 1]]
    c, s = np.cos(theta[k]), np.sin(theta[k])
    return c * bx - s * by, s * bx + c * by


def test_bodies_are_our_polygons_counter_clockwise_their_edges_on_ours():
    shapes, theta, pile = _pile()
    r = pile["rounding"]
    assert r == pytest.approx(lp.ROUNDING * shapes.inradius.min())
    for k, v in enumerate(pile["corners"]):
        x, y = _world_corners(shapes, theta, k)
        assert len(v) == len(x)
        inner = Polygon(v)
        assert inner.exterior.is_ccw and inner.is_valid
        # rounding the vertex polygon by r gives our polygon back but for its corners
        ours = Polygon(np.c_[x, y])
        rounded = inner.buffer(r, 256)
        assert rounded.within(ours.buffer(1e-12 * shapes.radius[k]))
        assert ours.difference(rounded).area < 0.01 * ours.area
        # every edge of ours is touched by the rounded body: the edges lie on ours
        for a, b in zip(np.c_[x, y], np.roll(np.c_[x, y], -1, axis=0)):
            mid = Point(0.5 * (a + b))
            assert rounded.exterior.distance(mid) < 1e-9 * shapes.radius[k]


def test_rounding_is_small_against_the_particles():
    shapes, _, pile = _pile(200)
    assert 2.0 * pile["rounding"] <= 0.05 * shapes.inradius.min()


def test_data_file_carries_our_masses_inertia_and_corners_in_its_length_unit():
    shapes, theta, pile = _pile()
    text = lp.data_file(pile)
    u = lp.LENGTH_UNIT
    n = len(theta)
    assert re.search(rf"^{n} atoms$", text, re.M) and re.search(rf"^{n} bodies$", text, re.M)
    atoms, bodies = _bodies_of(text)
    np.testing.assert_array_equal(atoms[:, 0], np.arange(1, n + 1))
    np.testing.assert_allclose(atoms[:, 3], shapes.mass, rtol=1e-12)
    np.testing.assert_allclose(atoms[:, 4] * u, pile["x"], rtol=1e-12, atol=1e-15)
    for k, (inertia, vertices, diameter) in enumerate(bodies):
        assert diameter * u == pytest.approx(2.0 * pile["rounding"], rel=1e-12)
        np.testing.assert_allclose(vertices[:, :2] * u, pile["corners"][k], rtol=1e-12,
                                   atol=1e-15)
        assert not vertices[:, 2].any()
        # Izz is our moment of inertia; the lamina's Ixx + Iyy = Izz, no z products
        ixx, iyy, izz, _, ixz, iyz = inertia * u * u
        assert izz == pytest.approx(shapes.inertia[k], rel=1e-10)
        assert ixx + iyy == pytest.approx(izz, rel=1e-12) and ixz == iyz == 0.0
    # the bodies start apart, inside the box, above the floor
    reach = shapes.radius.max()
    centre = np.c_[pile["x"], pile["y"]]
    gap = np.hypot(*(centre[:, None] - centre[None]).transpose(2, 0, 1))
    np.fill_diagonal(gap, np.inf)
    assert gap.min() > 2.0 * reach
    assert (np.abs(pile["x"]) + reach < 0.5 * pile["width"]).all()
    assert (pile["y"] - reach > 0.0).all() and (pile["y"] + reach < pile["height"]).all()


def test_inertia_tensor_of_a_rotated_rectangle():
    a, b, m, phi = 3.0, 1.0, 2.0, 0.3
    x0, y0 = np.array([-a, a, a, -a]) / 2, np.array([-b, -b, b, b]) / 2
    c, s = np.cos(phi), np.sin(phi)
    ixx, iyy, izz, ixy, _, _ = lp.inertia_tensor(c * x0 - s * y0, s * x0 + c * y0, m)
    # principal moments m b²/12 (about the long axis) and m a²/12, rotated by phi
    i1, i2 = m * b * b / 12.0, m * a * a / 12.0
    assert ixx == pytest.approx(i1 * c * c + i2 * s * s)
    assert iyy == pytest.approx(i1 * s * s + i2 * c * c)
    assert ixy == pytest.approx((i1 - i2) * c * s)
    assert izz == pytest.approx(m * (a * a + b * b) / 12.0)


def test_input_uses_the_study_stiffness_friction_step_and_skin():
    model = ModelParams(friction=0.4)
    shapes, theta, pile = _pile()
    u = lp.LENGTH_UNIT
    text = lp.lammps_input(pile, model, dt=3e-5, skin=1.1e-3, steps=150, repeats=4)
    style = re.search(r"^pair_style body/rounded/polygon (\S+) (\S+) (\S+) (\S+) (\S+)$",
                      text, re.M)
    c_n, c_t, mu, delta_ua, cut = map(float, style.groups())
    assert c_n == c_t and cut * u < pile["rounding"]
    assert mu == 0.0  # LAMMPS's mu would stiffen the normal force, see the module
    # no contact length reaches delta_ua: LAMMPS does not scale the forces
    assert delta_ua * u > 2.0 * shapes.radius.max()
    # damping ratio of a contact of two mean particles
    m_eff = 0.5 * np.mean(shapes.mass)
    assert c_n / (2.0 * np.sqrt(1e7 * m_eff)) == pytest.approx(lp.DAMPING_RATIO, rel=1e-6)
    assert re.search(r"^pair_coeff \* \* 10000000 0$", text, re.M)
    walls = re.findall(r"^fix \S+ all wall/body/polygon 10000000 (\S+) (\S+) ([xy])plane", text,
                       re.M)
    assert sorted(w[2] for w in walls) == ["x", "y"]
    assert all(float(w[0]) == float(w[1]) == pytest.approx(c_n) for w in walls)
    assert re.search(r"^timestep 3e-05$", text, re.M)
    assert float(re.search(r"^neighbor (\S+) bin$", text, re.M).group(1)) * u == \
        pytest.approx(1.1e-3)
    assert float(re.search(r"^fix weight all gravity (\S+)", text, re.M).group(1)) * u == \
        pytest.approx(9.81)
    assert text.count("run ${steps} pre no post yes") == 4  # with LAMMPS's statistics
    assert text.index("run 0 post no") < text.index("run ${steps} pre no post yes")
    assert re.search(r"^variable steps equal 150$", text, re.M)
    assert re.search(r"^read_data settled.data$", text, re.M) and "viscous" not in text
    settle = lp.lammps_input(pile, model, dt=3e-5, skin=1.1e-3, stage="settle")
    assert re.search(r"^read_data pile.data$", settle, re.M)
    assert re.search(r"^fix settle all viscous", settle, re.M) and "unfix settle" in settle
    assert settle.rstrip().endswith("write_data settled.data") and "${steps}" not in settle
    assert "jump" not in settle  # no target, no rounds
    with pytest.raises(ValueError, match="stage"):
        lp.lammps_input(pile, model, 3e-5, 1e-3, stage="pour")


def test_contacts_of_rounded_bodies_are_counted_once():
    r = 0.01
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    corners = [square, square + [1.0 + 1.5 * r, 0.0],  # rounded shells overlap
               square + [2.0 + 1.5 * r + 2.5 * r, 0.0],  # a gap of half a rounding radius
               square + [0.5, 1.0 + 1.9 * r]]  # on top of the first two, touching both
    assert lp.count_contacts(corners, r) == 3


# Lines of a LAMMPS 22 Jul 2025 log of this input (300 bodies, 3 timed runs).
LOG = """\
LAMMPS (22 Jul 2025 - Update 4)
print "MASS ${mtot}"
MASS 23.66776356255
   Step        Atoms        KinEng    
      2723         300   0.2928      
      2923         300   0.3016      
Loop time of 0.151232 on 1 procs for 200 steps with 300 atoms

print "STEPS ${steps}"
STEPS 200
      2923         300   0.3016      
      3123         300   0.3105      
Loop time of 0.145286 on 1 procs for 200 steps with 300 atoms

Loop time of 1.423e-06 on 1 procs for 0 steps with 300 atoms
"""


def test_log_parser_reads_loop_times_marks_and_kinetic_energy():
    parsed = lp.parse_log(LOG)
    assert parsed["loops"][1] == (0.145286, 1, 200, 300)
    assert parsed["steps"] == 200 and parsed["mass"] == pytest.approx(23.66776356255)
    assert parsed["version"] == "22 Jul 2025 - Update 4"
    assert parsed["runs"][0]["kinetic"] == [0.2928, 0.3016]
    assert parsed["runs"][1]["kinetic"] == [0.3016, 0.3105]
    with pytest.raises(RuntimeError, match="lacks"):
        lp.parse_log(LOG.replace("STEPS 200", ""))


def test_settling_runs_rounds_under_the_heaps_last_drag_until_its_target():
    model = ModelParams()
    _, _, pile = _pile()
    text = lp.lammps_input(pile, model, dt=7e-6, skin=1e-3, stage="settle", target=0.0048)
    drags = [float(g) for g in re.findall(r"^fix settle all viscous (\S+)$", text, re.M)]
    m_mean = np.mean(pile["mass"])
    assert drags == pytest.approx([lp.SETTLE_DRAG * m_mean, lp.SETTLE_ROUND_DRAG * m_mean])
    assert re.search(rf"^variable round loop {lp.SETTLE_ROUNDS}$", text, re.M)
    # the target in LAMMPS's unit of speed (cm/s), checked before each round
    assert re.search(r'^if "\$\{vrms\} <= 0.48" then "jump SELF settled"$', text, re.M)
    assert re.search(r"^variable vrms equal sqrt\(2\*ke/v_mtot\)$", text, re.M)
    assert re.search(r"^timestep 1.4e-05$", text, re.M)  # SETTLE_DT_FACTOR x dt
    assert text.index("label settled") < text.index("write_data settled.data")


# The settling lines of a log of that input (made-up speeds; dt 7e-6 s, coarse 1.4e-5 s).
SETTLE_LOG = """\
timestep 7e-06
timestep 1.4e-05
run 30000
Loop time of 90.1 on 1 procs for 30000 steps with 300 atoms
SETTLED 0 1.2
run 3571
Loop time of 10.2 on 1 procs for 3571 steps with 300 atoms
SETTLED 1 0.61
run 3571
Loop time of 10.3 on 1 procs for 3571 steps with 300 atoms
SETTLED 2 0.45
"""


def test_settle_report_says_what_the_settling_reached():
    r = lp.settle_report(SETTLE_LOG, 0.0048)
    assert r["rms_speed"] == pytest.approx([0.012, 0.0061, 0.0045])  # cm/s to m/s
    assert r["rounds"] == 2 and r["reached"] and r["rule"] == lp.SETTLE_RULE
    assert r["settle_time"] == pytest.approx((30000 + 2 * 3571) * 1.4e-5)
    assert not lp.settle_report(SETTLE_LOG, 0.004)["reached"]
    with pytest.raises(RuntimeError, match="SETTLED"):
        lp.settle_report("run 10\n", 0.004)


def test_settled_bodies_are_kept_by_rule_and_target_and_say_what_they_reached(
        monkeypatch, tmp_path, caplog):
    """Without LAMMPS: a stand-in run writes the data and the log of a settling."""
    shapes, theta, _ = _pile(20)
    monkeypatch.setattr(lp, "find_lmp", lambda: ("lmp", None))

    def run(folder, lmp, mpirun, ranks, what):
        (folder / "settled.data").write_text("data\n")
        return SETTLE_LOG
    monkeypatch.setattr(lp, "run_lmp", run)
    model = ModelParams()
    path = lp.settled_peer(shapes, theta, 7e-6, 1e-3, model, tmp_path, target=0.004)
    assert f"-settle{lp.SETTLE_RULE}-to4mms" in path.name and path.read_text() == "data\n"
    report = json.loads(lp.settle_json(path).read_text())
    assert report["rms_speed"][-1] == pytest.approx(0.0045) and not report["reached"]
    assert "NOT settled to the target rms speed 4 mm/s" in caplog.text
    assert path.with_suffix(".settle.log").read_text() == SETTLE_LOG
    # another rule settles anew
    monkeypatch.setattr(lp, "SETTLE_RULE", "other")
    assert lp.settled_peer(shapes, theta, 7e-6, 1e-3, model, tmp_path, target=0.004) != path


def test_ratios_pair_rows_with_the_peer_of_the_same_n_and_parallelism():
    rows = [{"n_particles": 3000, "threads": 1, "ns_per_particle_step": 300.0,
             "ns_per_contact": 170.0, "ratio_to_lammps": 2.0},
            {"n_particles": 10000, "threads": 1, "ns_per_particle_step": 310.0,
             "ns_per_contact": 175.0}]
    peers = [{"n_particles": 3000, "ranks": 1, "lammps_polygons_ns_per_particle_step": 600.0,
              "lammps_polygons_ns_per_contact": 340.0}]
    out = lammps_peer.ratios(rows, peers, "lammps_polygons")
    assert out[0]["ratio_to_lammps_polygons"] == pytest.approx(0.5)
    assert out[0]["ratio_to_lammps_polygons_per_contact"] == pytest.approx(0.5)
    assert out[0]["ratio_to_lammps"] == 2.0  # the disk peer's ratio stays beside it
    assert "ratio_to_lammps_polygons" not in out[1]


def test_missing_lammps_is_named_with_how_to_install_it(monkeypatch, tmp_path):
    monkeypatch.delenv(lp.LMP_ENV, raising=False)
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(PeerUnavailable, match="make bench-peers"):
        lp.find_lmp()
    monkeypatch.setenv(lp.LMP_ENV, str(tmp_path / "nowhere" / "lmp"))
    with pytest.raises(PeerUnavailable, match="nowhere"):
        lp.find_lmp()


def test_an_mpirun_beside_the_lmp_starts_it(monkeypatch, tmp_path):
    for name in ("lmp", "mpirun"):
        (tmp_path / name).write_text("#!/bin/sh\n")
        (tmp_path / name).chmod(0o755)
    monkeypatch.setenv(lp.LMP_ENV, str(tmp_path / "lmp"))
    assert lp.find_lmp() == (str(tmp_path / "lmp"), [str(tmp_path / "mpirun")])


def _lammps_or_skip():
    try:
        return lp.find_lmp()
    except PeerUnavailable as exc:
        pytest.skip(str(exc))


def test_lammps_times_a_small_settled_pile(tmp_path):
    """End to end with LAMMPS (skipped without it): 40 bodies settle in the
    box, touch, weigh what ours weigh, stay at rest and are timed on 1 and
    (with an mpirun) 2 ranks."""
    _, mpirun = _lammps_or_skip()
    model = ModelParams(integrator="verlet")
    shapes = _shapes(np.random.default_rng(5), 40, model)
    theta = np.random.default_rng(6).uniform(0.0, 2.0 * np.pi, 40)
    for ranks in (1, 2) if mpirun else (1,):
        # 2000 steps (about 50 ms): LAMMPS's CPU use comes from the kernel's
        # accounting, which may count in ticks of 1-10 ms, so a run of 50 steps
        # (about 1 ms) was once read as 0.0 % CPU on a loaded host
        r = lp.time_peer(shapes, theta, ranks, 7e-6, 1e-3, model, steps=2000, repeats=2,
                         cache=tmp_path)
        assert r["n_particles"] == 40 and r["ranks"] == ranks and r["lammps_version"]
        assert abs(r["mass_error"]) < 1e-12
        assert 1.0 < r["contacts_per_particle"] < 3.0
        assert r["lammps_polygons_ns_per_particle_step"] > 0.0
        # at rest: far below a particle falling its own size (m g d ≈ 5e-3 J/m)
        assert max(r["kinetic_energy_per_particle"]) < 1e-6
        # the terms of the row, from LAMMPS's own statistics and lmp -h
        assert len(r["neighbor_builds"]) == 2 and r["dt"] == 7e-6
        assert {"pair", "neigh", "comm", "modify", "other"} <= set(r["breakdown"])
        assert 0.0 < r["breakdown"]["pair"] < 1.0
        assert r["lammps_build"]["version"] == r["lammps_version"] and r["lammps_build"]["mpi"]
        assert "BODY" in r["lammps_build"]["packages"]
        # CPU of all ranks: some, and no more than the ranks' whole wall time (5 % for
        # the accounting's ticks)
        assert 0.0 < r["lammps_polygons_cpu_ns_per_particle_step"] \
            <= 1.05 * ranks * r["lammps_polygons_ns_per_particle_step"]
    assert len(list(tmp_path.glob("lammps-polygons-n40-*.data"))) == 1  # settled once


def test_a_settling_stopped_at_its_wall_time_limit_says_what_it_reached(monkeypatch, tmp_path):
    """Without LAMMPS: a stand-in run stops as LAMMPS does at its ``timer timeout``."""
    shapes, theta, pile = _pile(20)
    monkeypatch.setattr(lp, "find_lmp", lambda: ("lmp", None))
    mass = float(pile["mass"].sum())
    ke = 0.5 * mass * 2.0 ** 2  # LAMMPS units: 2 cm/s

    def run(folder, lmp, mpirun, ranks, what):
        (folder / "log.lammps").write_text(
            f"timestep 1.4e-05\nrun 30000\nStep Atoms KinEng \n       0      20   0 \n"
            f"     714      20   {ke:.10g} \nWARNING: Wall time limit reached (src/timer.cpp:238)\n"
            "Loop time of 900.1 on 1 procs for 800 steps with 20 atoms\n\n"
            'print "SETTLED 0 ${vrms}"\n'
            "ERROR: Compute used in variable thermo keyword between runs is not current\n")
        raise RuntimeError(f"{what} failed (exit 1)")
    monkeypatch.setattr(lp, "run_lmp", run)
    with pytest.raises(RuntimeError) as caught:
        lp.settled_peer(shapes, theta, 7e-6, 1e-3, ModelParams(), tmp_path, target=0.005)
    message = str(caught.value)
    assert "not settled: stopped at the wall-time limit of 900 s" in message
    assert "0.01 s simulated" in message  # 800 steps of 1.4e-5 s
    assert "rms speed 20 mm/s at its last thermo line" in message and "target 5 mm/s" in message
    assert not list(tmp_path.glob("*.data"))  # nothing kept to be timed
    assert len(list(tmp_path.glob("*.settle-failed.log"))) == 1
