"""The bench's LAMMPS peer: the disks it hands LAMMPS and what it reads back."""

import re

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from sim.numerics.bench import _shapes
from sim.config import ModelParams
from sim.numerics.lammps_peer import (PeerUnavailable, build_line, data_file, disk_pile,
                                      find_lmp, lammps_input, parse_build, parse_log, parse_runs,
                                      peer_terms, ratios, rms_speed, timed_terms)


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
    # the timed runs print their statistics, after a run 0 that sets the count of builds to 0
    assert text.count("run ${steps} pre no post yes") == 4
    assert text.index("run 0 post no") < text.index("run ${steps} pre no post yes")
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


# The head of `lmp -h` of Debian's lammps 20220106 (as printed), abridged where marked.
HELP = """\

Large-scale Atomic/Molecular Massively Parallel Simulator - 29 Sep 2021 - Update 2

Usage example: lmp -var t 300 -echo screen -in in.alloy

List of command line options supported by this LAMMPS executable:

-echo none/screen/log/both  : echoing of input script (-e)
-var varname value          : set index style variable (-v)

OS: Linux "Debian GNU/Linux 12 (bookworm)" 6.1.0 on x86_64

Compiler: GNU C++ 12.2.0 with OpenMP 4.5
C++ standard: C++11
MPI v3.1: Open MPI v4.1.4, package: Debian OpenMPI, ident: 4.1.4, repo rev: v4.1.4, May 26, 2022

Accelerator configuration:


Active compile time flags:

-DLAMMPS_GZIP
-DLAMMPS_SMALLBIG
sizeof(smallint): 32-bit
sizeof(bigint):   64-bit

Installed packages:

ASPHERE BODY CLASS2 COLLOID COMPRESS CORESHELL DIPOLE EXTRA-PAIR GRANULAR KIM 
KSPACE MANYBODY MC MISC MOLECULE MPIIO OPT PERI POEMS PYTHON QEQ REPLICA RIGID 
SHOCK SRD VORONOI 

List of individual style options included in this LAMMPS executable

* Atom styles:

angle           atomic          body            bond            charge          
"""


def test_build_is_read_from_lmp_help():
    b = parse_build(HELP)
    assert b["version"] == "29 Sep 2021 - Update 2"
    assert b["compiler"] == "GNU C++ 12.2.0 with OpenMP 4.5"
    assert b["mpi"] == "MPI v3.1: Open MPI v4.1.4"
    assert b["os"].startswith("Linux \"Debian GNU/Linux 12")
    assert b["accelerators"] == []  # no OPENMP, GPU, ... package in this build
    assert b["flags"] == ["-DLAMMPS_GZIP", "-DLAMMPS_SMALLBIG"]
    assert len(b["packages"]) == 26 and {"BODY", "GRANULAR"} <= set(b["packages"])
    assert "angle" not in b["packages"]  # the style lists after the packages are not packages
    omp = HELP.replace("Accelerator configuration:\n\n",
                       "Accelerator configuration:\n\nOPENMP package API: OpenMP\n"
                       "OPENMP package precision: double\n")
    assert parse_build(omp)["accelerators"] == ["OPENMP package API: OpenMP",
                                                "OPENMP package precision: double"]
    line = build_line({**b, "path": "/usr/bin/lmp"})
    assert "29 Sep 2021 - Update 2" in line and "Open MPI v4.1.4" in line
    assert "OpenMP 4.5" in line and "no accelerator package" in line and "BODY" in line


def _post(seconds, steps, cpu, sections, builds):
    """The lines LAMMPS 20220106 prints after a run with post yes (1 rank), for
    made-up numbers: Loop time, CPU use, the timing breakdown, the neighbour counts."""
    rows = "\n".join(f"{name:<8}| {t:<10.5g} | {t:<10.5g} | {t:<10.5g} |   0.0 | "
                     f"{100 * t / seconds:5.2f}" for name, t in sections.items() if name != "Other")
    other = sections["Other"]
    return f"""Loop time of {seconds} on 1 procs for {steps} steps with 300 atoms

{cpu}% CPU use with 1 MPI tasks x 1 OpenMP threads

MPI task timing breakdown:
Section |  min time  |  avg time  |  max time  |%varavg| %total
---------------------------------------------------------------
{rows}
Other   |            | {other:<10.5g} |            |       | {100 * other / seconds:5.2f}

Nlocal:        300.000 ave         300 max         300 min
Histogram: 1 0 0 0 0 0 0 0 0 0
Nghost:        0.00000 ave           0 max           0 min
Histogram: 1 0 0 0 0 0 0 0 0 0
Neighs:        681.000 ave         681 max         681 min
Histogram: 1 0 0 0 0 0 0 0 0 0

Total # of neighbors = 681
Ave neighs/atom = 2.2700000
Neighbor list builds = {builds}
Dangerous builds = 0
"""


def _sections(seconds, pair, neigh, modify):
    """Sections of a run of ``seconds``: Comm 0.5 ms, Output 10 µs, Other the rest."""
    return {"Pair": pair, "Neigh": neigh, "Comm": 5e-4, "Output": 1e-5, "Modify": modify,
            "Other": seconds - pair - neigh - 5e-4 - 1e-5 - modify}


# A log of lammps_input's timing (3 timed runs of 200 steps) in LAMMPS
# 20220106's format: the 0.1 s run, run 0 (post no), the timed runs.
LOG_POST = ("LAMMPS (29 Sep 2021 - Update 2)\n"
            'print "MASS ${mtot}"\nMASS 23.6677635625505\n'
            "run 14286\nStep Atoms KinEng c_contacts \n"
            "       0      300            0            0 \n"
            "   14286      300 2.0459905e-08          954 \n"
            + _post(0.25, 14286, 99.8, _sections(0.25, 0.2, 0.01, 0.03), 7)
            + 'variable steps equal 200\nprint "STEPS ${steps}"\nSTEPS 200\nrun 0 post no\n'
            "Step Atoms KinEng c_contacts \n   14286      300 2.0459905e-08          954 \n"
            "Loop time of 1.1e-06 on 1 procs for 0 steps with 300 atoms\n\n"
            "run 200 pre no post yes\nStep Atoms KinEng c_contacts \n"
            "   14286      300 2.0e-08          954 \n   14486      300 1.9e-08          954 \n"
            + _post(0.004, 200, 100.0, _sections(0.004, 0.0025, 0.0002, 0.0005), 2)
            + "run 200 pre no post yes\nStep Atoms KinEng c_contacts \n"
            "   14486      300 1.9e-08          954 \n   14686      300 1.8e-08          955 \n"
            + _post(0.006, 200, 50.0, _sections(0.006, 0.0045, 0.0, 0.0008), 2)
            + "run 200 pre no post yes\nStep Atoms KinEng c_contacts \n"
            "   14686      300 1.8e-08          955 \n   14886      300 1.5e-08          954 \n"
            + _post(0.005, 200, 80.0, _sections(0.005, 0.0035, 0.0003, 0.0006), 5)
            + "run 0 post no\nStep Atoms KinEng c_contacts \n   14886      300 1.5e-08          954 \n"
            "Loop time of 1.2e-06 on 1 procs for 0 steps with 300 atoms\n\n"
            'print "CONTACTS ${pairs}"\nCONTACTS 477\n')


def test_runs_of_a_log_carry_breakdown_builds_cpu_use_and_kinetic_energy():
    runs = parse_runs(LOG_POST)
    assert [r["steps"] for r in runs] == [14286, 0, 200, 200, 200, 0]
    first, setup, timed = runs[0], runs[1], runs[2]
    assert first["neighbor_builds"] == 7 and first["cpu_use"] == pytest.approx(0.998)
    assert first["kinetic"] == [0.0, 2.0459905e-08]
    assert setup["sections"] is None and setup["neighbor_builds"] is None  # post no
    assert timed["sections"] == pytest.approx({"pair": 0.0025, "neigh": 0.0002, "comm": 5e-4,
                                               "output": 1e-5, "modify": 0.0005,
                                               "other": 0.00029})
    assert timed["kinetic"] == [2.0e-08, 1.9e-08] and timed["threads"] == 1
    assert timed["dangerous_builds"] == 0


def test_timed_terms_take_the_builds_of_each_run_from_lammps_running_count():
    terms = timed_terms(parse_runs(LOG_POST), 200, 3)
    assert terms["seconds"] == 0.005  # median of 0.004, 0.006, 0.005
    # loop time x ranks x CPU use: 0.004, 0.003, 0.004
    assert terms["cpu_seconds"] == pytest.approx(0.004)
    # LAMMPS's count runs on from the setup of run 0 without one: 2, 2, 5
    assert terms["neighbor_builds"] == [2, 0, 3]
    assert terms["breakdown"]["pair"] == pytest.approx((0.0025 + 0.0045 + 0.0035) / 0.015)
    assert terms["breakdown"]["neigh"] == pytest.approx(0.0005 / 0.015)
    assert sum(terms["breakdown"].values()) == pytest.approx(1.0, abs=1e-3)
    assert terms["kinetic"] == [2.0e-08, 1.5e-08]  # start of the first, end of the last
    with pytest.raises(RuntimeError, match="4 expected"):
        timed_terms(parse_runs(LOG_POST), 200, 4)
    without = re.sub(r"^\w+ *\|.*\n", "", LOG_POST, flags=re.M)  # as after post no
    with pytest.raises(RuntimeError, match="breakdown"):
        timed_terms(parse_runs(without), 200, 3)


def test_log_parser_reads_the_version_and_the_runs_terms():
    parsed = parse_log(LOG_POST)
    assert parsed["version"] == "29 Sep 2021 - Update 2"
    assert parsed["contacts"] == 477 and len(parsed["runs"]) == 6
    terms = peer_terms(parsed, "lammps", "lmp", 300, 23.6677635625505, 7e-6, 200, 3)
    assert terms["lammps_ns_per_particle_step"] == pytest.approx(0.005 / 200 / 300 * 1e9)
    assert terms["lammps_cpu_ns_per_particle_step"] == pytest.approx(0.004 / 200 / 300 * 1e9)
    assert terms["dt"] == 7e-6 and terms["neighbor_builds"] == [2, 0, 3]
    assert terms["kinetic_energy_per_particle"] == pytest.approx([2.0e-08 / 300, 1.5e-08 / 300])
    assert terms["rms_speed"][0] == pytest.approx(np.sqrt(2 * 2.0e-08 / 23.6677635625505))


def test_rms_speed_weights_by_mass():
    # 1 kg at 3 m/s and 3 kg at rest: E = 4.5 J, M = 4 kg, sqrt(2 E / M) = 1.5 m/s
    assert rms_speed(4.5, 4.0) == pytest.approx(1.5)
