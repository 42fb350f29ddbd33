"""The bench's LAMMPS peer: the disks it hands LAMMPS and what it reads back."""

import re

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from sim.numerics.bench import _shapes
from sim.config import ModelParams
from sim.numerics.lammps_peer import (PeerUnavailable, data_file, disk_pile, find_lmp,
                                      lammps_input, parse_log, ratios)


def test_disks_take_the_polygons_areas_and_masses_and_start_apart_inside_the_box():
    model = ModelParams()
    n = 400
    shapes = _shapes(np.random.default_rng(3), n, model)
    pile = disk_pile(shapes)
    # areas by shapely from the polygons' corners, independently of our geometry
    o = shapes.node_offset
    areas = np.array([Polygon(np.c_[shapes.node_x[o[i]:o[i + 1]],
                                    shapes.node_y[o[i]:o[i + 1]]]).area for i in range(n)])
    np.testing.assert_allclose(np.pi * pile["radius"] ** 2, areas, rtol=1e-12)
    np.testing.assert_allclose(pile["mass"], model.density * areas, rtol=1e-12)
    disks = [Point(x, y).buffer(r, 64) for x, y, r in zip(pile["x"], pile["y"], pile["radius"])]
    # no two disks touch at the start (neighbours on the lattice are the closest)
    dx = pile["x"][:, None] - pile["x"][None, :]
    dy = pile["y"][:, None] - pile["y"][None, :]
    gap = np.hypot(dx, dy) - (pile["radius"][:, None] + pile["radius"][None, :])
    np.fill_diagonal(gap, np.inf)
    assert gap.min() > 0.0
    box = Polygon([(-0.5 * pile["width"], 0.0), (0.5 * pile["width"], 0.0),
                   (0.5 * pile["width"], pile["height"]), (-0.5 * pile["width"], pile["height"])])
    assert all(box.contains(d) for d in disks)


def test_data_file_densities_give_lammps_sphere_masses_equal_to_the_disks():
    pile = disk_pile(_shapes(np.random.default_rng(1), 50, ModelParams()))
    text = data_file(pile)
    rows = text.split("Atoms # sphere")[1].split()
    atoms = np.array(rows, dtype=float).reshape(-1, 7)  # id type diameter density x y z
    assert atoms.shape[0] == 50 and re.search(r"^50 atoms$", text, re.M)
    r = 0.5 * atoms[:, 2]
    # LAMMPS (atom_style sphere) sets mass = 4/3 pi r^3 density
    np.testing.assert_allclose(4.0 / 3.0 * np.pi * r ** 3 * atoms[:, 3], pile["mass"],
                               rtol=1e-10)
    np.testing.assert_allclose(atoms[:, 4], pile["x"], rtol=1e-10)


def test_input_uses_the_study_stiffness_friction_step_and_skin():
    model = ModelParams(friction=0.4, support_friction=0.7)
    pile = disk_pile(_shapes(np.random.default_rng(0), 30, model))
    text = lammps_input(pile, model, dt=3e-5, skin=1.1e-3, steps=150, repeats=4)
    assert re.search(r"^pair_style gran/hooke/history 10000000 NULL \S+ NULL 0.4 1$", text, re.M)
    assert len(re.findall(r"wall/gran hooke/history 10000000 NULL \S+ NULL 0.7 1", text)) == 2
    assert re.search(r"^timestep 3e-05$", text, re.M)
    assert re.search(r"^neighbor 0.0011 bin$", text, re.M)
    assert text.count("run ${steps} pre no post no") == 4
    assert re.search(r"^variable steps equal 150$", text, re.M)
    assert re.search(r"^read_data settled.data$", text, re.M) and "viscous" not in text
    settle = lammps_input(pile, model, dt=3e-5, skin=1.1e-3, stage="settle")
    assert re.search(r"^read_data pile.data$", settle, re.M)
    assert re.search(r"^fix settle all viscous", settle, re.M)
    assert settle.rstrip().endswith("write_data settled.data") and "${steps}" not in settle


# Lines of a real LAMMPS 20220106 log of this input (300 disks, 2 timed runs).
LOG = """\
print "MASS ${mtot}"
MASS 23.6677635625505
Step Atoms KinEng c_contacts
       0      300            0            0
   20000      300 6.8078031e-08          940
Loop time of 0.352564 on 1 procs for 20000 steps with 300 atoms

print "STEPS ${steps}"
STEPS 200
Loop time of 0.00379848 on 1 procs for 200 steps with 300 atoms

Loop time of 0.00378459 on 1 procs for 200 steps with 300 atoms

Loop time of 3.25e-07 on 1 procs for 0 steps with 300 atoms
print "CONTACTS ${pairs}"
CONTACTS 471
"""


def test_log_parser_reads_loop_times_and_marks():
    parsed = parse_log(LOG)
    assert parsed["loops"][1] == (0.00379848, 1, 200, 300)
    assert len(parsed["loops"]) == 4
    assert parsed["contacts"] == 471 and parsed["steps"] == 200
    assert parsed["mass"] == pytest.approx(23.6677635625505)
    with pytest.raises(RuntimeError, match="lacks"):
        parse_log(LOG.replace("CONTACTS 471", ""))


def test_ratios_pair_rows_with_the_peer_of_the_same_n_and_parallelism():
    rows = [{"n_particles": 3000, "threads": 1, "ns_per_particle_step": 300.0,
             "ns_per_contact": 170.0},
            {"n_particles": 3000, "threads": 2, "ns_per_particle_step": 180.0,
             "ns_per_contact": 100.0},
            {"n_particles": 10000, "threads": 1, "ns_per_particle_step": 310.0,
             "ns_per_contact": 175.0}]
    peers = [{"n_particles": 3000, "ranks": 1, "lammps_ns_per_particle_step": 80.0,
              "lammps_ns_per_contact": 85.0},
             {"n_particles": 3000, "ranks": 2, "lammps_ns_per_particle_step": 45.0,
              "lammps_ns_per_contact": 50.0}]
    out = ratios(rows, peers)
    assert out[0]["ratio_to_lammps"] == pytest.approx(3.75)
    assert out[0]["ratio_to_lammps_per_contact"] == pytest.approx(2.0)
    assert out[1]["ratio_to_lammps"] == pytest.approx(4.0)
    assert "ratio_to_lammps" not in out[2]  # no peer of 10 000 timed


def test_missing_lmp_is_named_with_how_to_install_it(monkeypatch):
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(PeerUnavailable, match="make bench-peers"):
        find_lmp()
