"""A LAMMPS disk pile timed beside our polygons: the bench's reference peer.

Absolute times drift by a factor of two between hours on shared machines;
the ratio of two codes timed in the same run does not.  ``python -m sim
bench --peer lammps`` therefore builds, for each pile size it times, a pile
of as many disks in LAMMPS (Debian's ``lammps`` package, the ``lmp``
executable, ``GRANULAR`` package) and times it in the same run, on 1 and 2
MPI ranks.

The disk pile matches the polygon pile in what sets the cost of a contact
step, not in its shape:

* **N particles of the same masses**: the polygons of the pile timed beside
  it, each replaced by the disk of its area, so mass per metre of depth
  ``density * area`` is the same;
* **stiffness and friction**: ``gran/hooke/history`` with ``k_n`` equal to
  the study's Young's modulus (N/m in 2D, the slope of our force against
  overlap depth for a disk-like overlap), ``k_t = 2/7 k_n``, the study's
  friction μ between disks and against the floor;
* **the same time step** as the polygon pile (its automatic Verlet step), so
  that both move the same distance per step and rebuild their neighbour
  lists alike; LAMMPS's skin is our skin, 0.3 mean circumradii;
* **a loaded, settled pile**: disks roll freely (no rolling resistance in
  ``gran/hooke/history``), so a free heap would flow flat; the disks fill a
  box of floor and side walls (frictional ``wall/gran``) from a triangular
  lattice and settle under gravity with a viscous drag
  (:func:`settled_peer`, once, kept in the bench's cache like its polygon
  piles); the drag is removed 0.1 s before the timing.

The timing is LAMMPS's own ``Loop time`` of ``steps`` steps, the median of
``repeats`` runs, per particle-step; contacts per particle are the
particle–particle contacts (``compute contact/atom``, each counted once), as
in the polygon rows.  The input is written by :func:`lammps_input`; it is
documented in ``docs/performance.md``.

The terms of a peer's row, shared with the polygon peer: the build of its
``lmp`` (:func:`lmp_build`, from ``lmp -h``: version, compiler and OpenMP,
MPI, compile flags, packages) and, read from each timed run's log
(:func:`parse_runs`, :func:`timed_terms`), LAMMPS's own timing breakdown
(``MPI task timing breakdown``: Pair, Neigh, Comm, Modify, Output, Other),
its neighbour-list builds, its CPU use and the translational kinetic energy
of the pile at the start and end of the timed runs.
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

#: Executable looked for on PATH.
LMP = "lmp"
#: The disks settle under a viscous drag for this many free-fall times of the
#: box's height, plus :data:`SETTLE_EXTRA`, before the timing (a 10 000 box
#: settled for 0.4 s had 0.55 contacts per particle, still falling).
SETTLE_FALLS = 2.5
#: See :data:`SETTLE_FALLS`, s.
SETTLE_EXTRA = 0.2
#: Viscous drag while settling, 1/s (``fix viscous`` takes gamma = this × mass).
SETTLE_DRAG = 20.0
#: Normal damping ratio of the disk contacts (``gamma_n`` of ``gran/hooke/history``).
DAMPING_RATIO = 0.3

_LOOP = re.compile(r"^Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms",
                   re.M)
_MARK = re.compile(r"^(CONTACTS|MASS|STEPS) ([0-9.eE+-]+)\s*$", re.M)
#: A log's first line: ``LAMMPS (29 Sep 2021 - Update 2)``.
_VERSION = re.compile(r"^LAMMPS \((.+)\)\s*$", re.M)
#: A thermo line of this module's and the polygon peer's inputs: step, atoms,
#: kinetic energy, then other columns.
_THERMO = re.compile(r"^[ \t]*(\d+)[ \t]+(\d+)[ \t]+([0-9.eE+-]+)(?:[ \t]+[0-9.eE+-]+)*[ \t]*$",
                     re.M)
#: After a run with ``post yes``: the CPU use, the rows of the ``MPI task timing
#: breakdown`` (section, min, avg, max, %varavg, %total) and the neighbour counts.
_CPU_USE = re.compile(r"^([0-9.]+)% CPU use with (\d+) MPI tasks x (\d+) OpenMP threads", re.M)
_SECTION = re.compile(
    r"^(\w+)[ \t]*\|([^|\n]*)\|([^|\n]*)\|([^|\n]*)\|([^|\n]*)\|[ \t]*([0-9.eE+-]+)[ \t]*$", re.M)
_BUILDS = re.compile(r"^Neighbor list builds = (\d+)", re.M)
_DANGEROUS = re.compile(r"^Dangerous builds = (\d+)", re.M)


class PeerUnavailable(RuntimeError):
    """LAMMPS is not installed (or cannot run) on this machine."""


def find_lmp():
    """The ``lmp`` executable, or :class:`PeerUnavailable` saying how to install it."""
    path = shutil.which(LMP)
    if path is None:
        raise PeerUnavailable("bench --peer lammps: no 'lmp' on PATH; install Debian's "
                              "'lammps' package (make bench-peers does) or leave out --peer")
    return path


@functools.lru_cache(maxsize=None)
def lmp_build(lmp):
    """The build of the LAMMPS executable ``lmp``, from its ``lmp -h``.

    Returns
    -------
    dict
        ``version`` (``"29 Sep 2021 - Update 2"``), ``compiler`` (with its
        OpenMP, ``"GNU C++ 12.2.0 with OpenMP 4.5"``), ``mpi``, ``os``,
        ``accelerators`` (the lines of its ``Accelerator configuration``,
        e.g. the OPENMP package's), ``flags`` (the ``-D`` compile flags) and
        ``packages`` (installed), from :func:`parse_build` (None and empty
        where ``lmp -h`` cannot run); and ``path``.
    """
    try:
        text = subprocess.run([lmp, "-h"], capture_output=True, text=True,
                              env=dict(os.environ, OMP_NUM_THREADS="1")).stdout
    except OSError:
        text = ""
    return {**parse_build(text), "path": str(lmp)}


def parse_build(text):
    """The version and build of LAMMPS from the text of ``lmp -h`` (:func:`lmp_build`)."""
    def line(prefix):
        m = re.search(rf"^{prefix}:?\s*(.+?)\s*$", text, re.M)
        return m.group(1) if m else None

    lines = text.splitlines()

    def section(title):
        """The non-blank lines after the header ``title:`` up to the next header."""
        if f"{title}:" not in lines:
            return []
        out = []
        for x in lines[lines.index(f"{title}:") + 1:]:
            if re.match(r"^([A-Z][\w ]*:\s*$|List of )", x):
                break
            out += [x.strip()] if x.strip() else []
        return out

    version = re.search(r"^Large-scale Atomic/Molecular Massively Parallel Simulator - (.+?)\s*$",
                        text, re.M)
    mpi = re.search(r"^(MPI v[^\n]*?)(?:, package:.*)?$", text, re.M)
    return {"version": version.group(1) if version else None,
            "compiler": line("Compiler"), "mpi": mpi.group(1) if mpi else None,
            "os": line("OS"),
            "accelerators": section("Accelerator configuration"),
            "flags": re.findall(r"^(-D\w+)", text, re.M),
            "packages": " ".join(section("Installed packages")).split()}


def build_line(build):
    """One line naming a peer's LAMMPS build (:func:`lmp_build`), for the bench's table."""
    acc = "; ".join(build["accelerators"]) or "no accelerator package"
    return (f"LAMMPS {build['version']} ({build['path']}): {build['compiler']}; "
            f"{build['mpi']}; {acc}; flags {' '.join(build['flags'])}; "
            f"{len(build['packages'])} packages ({' '.join(build['packages'])})")


def disk_pile(shapes):
    """The disks of a peer pile: radii, masses and lattice positions in a box.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        The polygons of the pile timed beside it; each becomes the disk of
        its area and mass.

    Returns
    -------
    dict
        ``radius``, ``mass`` (kg per m of depth), ``x``, ``y`` (m), ``width``
        (the box's inner width, m) and ``height`` (its height, m).
    """
    n = len(shapes.area)
    radius = np.sqrt(shapes.area / np.pi)
    d = 2.0 * float(radius.max()) * 1.001  # lattice spacing: no two disks touch
    ncol = max(int(np.sqrt(n)), 1)
    row, col = np.divmod(np.arange(n), ncol)
    width = (ncol + 1.0) * d
    x = -0.5 * width + (col + 0.75 + 0.5 * (row % 2)) * d
    y = (0.5 + row * np.sqrt(3.0) / 2.0) * d
    return {"radius": radius, "mass": np.array(shapes.mass, dtype=float), "x": x, "y": y,
            "width": width, "height": float(y.max() + 2.0 * d)}


def data_file(pile):
    """A LAMMPS data file (``atom_style sphere``) of the disks of :func:`disk_pile`.

    LAMMPS takes a per-atom density and computes the mass of a sphere,
    ``4/3 π r³ ρ``; the density written is the one that gives the disk's mass
    per metre of depth, ``3 m / (4 π r³)``, and the input checks the total.
    """
    r, m = pile["radius"], pile["mass"]
    rho = 3.0 * m / (4.0 * np.pi * r ** 3)
    w, h = 0.5 * pile["width"], pile["height"]
    zt = float(4.0 * r.max())
    lines = ["LAMMPS data file: polypile bench peer, disks of the polygons' areas", "",
             f"{len(r)} atoms", "1 atom types", "",
             f"{-w:.10g} {w:.10g} xlo xhi", f"{0.0:.10g} {h:.10g} ylo yhi",
             f"{-zt:.10g} {zt:.10g} zlo zhi", "", "Atoms # sphere", ""]
    lines += [f"{k + 1} 1 {2.0 * r[k]:.12g} {rho[k]:.12g} {pile['x'][k]:.12g} "
              f"{pile['y'][k]:.12g} 0" for k in range(len(r))]
    return "\n".join(lines) + "\n"


def lammps_input(pile, model, dt, skin, steps=200, repeats=5, stage="time"):
    """The LAMMPS input that settles the disk pile (``stage="settle"``) or times it.

    Parameters
    ----------
    pile : dict
        From :func:`disk_pile`.
    model : sim.config.ModelParams
        Its Young's modulus is ``k_n``; its friction the disks' and the walls'.
    dt, skin : float
        Time step (s) and neighbour skin (m) of the polygon pile timed beside it.
    steps, repeats : int
        Steps per timed run and timed runs.
    stage : {"settle", "time"}
        ``settle`` reads ``pile.data`` (:func:`data_file`), lets the disks
        settle under a drag for :func:`settle_time` and writes
        ``settled.data``; ``time`` reads ``settled.data``, runs a tenth of a
        second without drag and then the timed runs.

    Returns
    -------
    str
    """
    if stage not in ("settle", "time"):
        raise ValueError(f"lammps_input stage {stage!r}: 'settle' or 'time'")
    kn = float(model.youngs_modulus)
    m_mean = float(np.mean(pile["mass"]))
    # gran/hooke/history: F_n = k_n delta - m_eff gamma_n v_n; gamma_n from the
    # damping ratio of a contact of two mean disks (m_eff = m/2)
    gamma_n = 2.0 * DAMPING_RATIO * np.sqrt(kn / (0.5 * m_mean))
    gran = (f"{kn:.8g} NULL {gamma_n:.8g} NULL {model.friction:.8g} 1")
    wall = (f"{kn:.8g} NULL {gamma_n:.8g} NULL {model.support_friction:.8g} 1")
    w = 0.5 * pile["width"]
    setup = f"""# polypile bench peer, {stage}: a box of disks (sim/numerics/lammps_peer.py)
units si
dimension 2
atom_style sphere
boundary f f p
newton off
comm_modify vel yes
read_data {"pile" if stage == "settle" else "settled"}.data
variable mtot equal mass(all)
print "MASS ${{mtot}}"
pair_style gran/hooke/history {gran}
pair_coeff * *
neighbor {skin:.8g} bin
neigh_modify delay 0 every 1 check yes
timestep {dt:.8g}
fix integrate all nve/sphere disc
fix flat all enforce2d
fix weight all gravity 9.81 vector 0 -1 0
fix floor all wall/gran hooke/history {wall} yplane 0.0 NULL
fix sides all wall/gran hooke/history {wall} xplane {-w:.10g} {w:.10g}
compute touching all contact/atom
compute contacts all reduce sum c_touching
thermo_style custom step atoms ke c_contacts
thermo_modify norm no lost error
thermo 100000000
"""
    if stage == "settle":
        return setup + f"""fix settle all viscous {SETTLE_DRAG * m_mean:.8g}
run {max(int(round(settle_time(pile) / dt)), 1)}
write_data settled.data
"""
    return setup + f"""run {max(int(round(0.1 / dt)), 1)}
{timed_runs(steps, repeats)}
run 0 post no
variable pairs equal c_contacts/2
print "CONTACTS ${{pairs}}"
"""


def timed_runs(steps, repeats):
    """The timed runs of a peer's input (this module's and the polygon
    peer's): a ``run 0`` whose setup starts LAMMPS's count of neighbour-list
    builds from 0, then ``repeats`` runs of ``steps`` steps without a setup,
    each followed by LAMMPS's statistics (:func:`timed_terms`)."""
    runs = "\n".join(["run ${steps} pre no post yes"] * repeats)
    return f"""variable steps equal {steps}
print "STEPS ${{steps}}"
run 0 post no
{runs}"""


#: How the disk peer starts ``lmp`` on several ranks (Debian's Open MPI, as root too).
MPIRUN = ["mpirun", "--oversubscribe"]


def run_lmp(folder, lmp, mpirun, ranks, what):
    """Run ``lmp -in in.lammps`` in ``folder`` on ``ranks`` MPI ranks; its log's text.

    Parameters
    ----------
    folder : pathlib.Path
        Holds ``in.lammps`` and the files it reads.
    lmp : str
        The LAMMPS executable.
    mpirun : list of str or None
        The command that starts it on several ranks (``-np`` follows), or
        None where there is none (then only one rank).
    ranks : int
    what : str
        The peer and the run, for the error (``"LAMMPS peer, settling 3000 disks"``).

    Raises
    ------
    PeerUnavailable
        Several ranks and no ``mpirun``.
    RuntimeError
        LAMMPS failed: its exit status and the last lines of its log.
    """
    cmd = [lmp, "-in", "in.lammps", "-log", "log.lammps", "-screen", "none"]
    if ranks > 1:
        if mpirun is None:
            raise PeerUnavailable(f"{what}: no mpirun for {ranks} ranks")
        cmd = mpirun + ["-np", str(ranks)] + cmd
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMP_NUM_THREADS="1")
    done = subprocess.run(cmd, cwd=folder, env=env, capture_output=True, text=True)
    log_text = (folder / "log.lammps").read_text() if (folder / "log.lammps").exists() else ""
    if done.returncode != 0:
        tail = (log_text + done.stdout + done.stderr).strip().splitlines()[-5:]
        raise RuntimeError(f"{what} on {ranks} rank(s) failed (exit {done.returncode}): "
                           + " | ".join(tail))
    return log_text


def settled_peer(shapes, dt, skin, model, cache=Path(".bench")):
    """The settled disk pile of ``shapes``, built once (on one rank) and kept in ``cache``.

    Returns
    -------
    pathlib.Path
        Its LAMMPS data file (positions and velocities after settling); the
        name holds N, a digest of the masses and the contact settings.
    """
    digest = hashlib.sha1(np.ascontiguousarray(shapes.mass, dtype=float).tobytes()).hexdigest()
    path = Path(cache) / (f"lammps-n{len(shapes.mass)}-m{digest[:10]}-dt{dt:.6g}-skin{skin:.6g}"
                          f"-k{model.youngs_modulus:g}-mu{model.friction:g}"
                          f"-{model.support_friction:g}.data")
    if path.exists():
        return path
    pile = disk_pile(shapes)
    n = len(pile["mass"])
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
        tmp = Path(tmp)
        (tmp / "pile.data").write_text(data_file(pile))
        (tmp / "in.lammps").write_text(lammps_input(pile, model, dt, skin, stage="settle"))
        run_lmp(tmp, find_lmp(), MPIRUN, 1, f"LAMMPS peer, settling {n} disks")
        os.replace(tmp / "settled.data", path)  # whole or not at all
    return path


def settle_time(pile, falls=SETTLE_FALLS, extra=SETTLE_EXTRA):
    """Simulated time a peer's bodies settle for before the timing, s: ``falls``
    free-fall times of the pile's height and ``extra`` seconds (the disks' by default)."""
    return falls * float(np.sqrt(2.0 * pile["height"] / 9.81)) + extra


def loop_times(text):
    """The ``Loop time`` lines of a LAMMPS log: (seconds, ranks, steps, atoms), one per ``run``."""
    return [(float(t), int(p), int(s), int(a)) for t, p, s, a in _LOOP.findall(text)]


def kinetic_energies(text):
    """The kinetic energies of a LAMMPS log's thermo lines, in order (LAMMPS units)."""
    return [float(e) for _, _, e in _THERMO.findall(text)]


def parse_runs(text):
    """Each ``run`` of a LAMMPS log: its loop time, thermo lines and, after a
    run with ``post yes``, LAMMPS's statistics of it.

    Returns
    -------
    list of dict
        One per ``Loop time`` line: ``seconds``, ``ranks``, ``steps``,
        ``atoms``; ``kinetic``, the kinetic energies of its thermo lines
        (third column, LAMMPS units); and, None after ``post no``:
        ``cpu_use`` (LAMMPS's CPU time over wall time of the loop, averaged
        over the ranks), ``threads`` (OpenMP threads per rank), ``sections``
        (section of the ``MPI task timing breakdown``, lower case → its
        average time over the ranks, s), ``neighbor_builds`` and
        ``dangerous_builds`` (LAMMPS's counts, which run on from the last
        run with a setup: see :func:`timed_terms`).
    """
    loops = list(_LOOP.finditer(text))
    runs = []
    for k, m in enumerate(loops):
        before = text[loops[k - 1].end() if k else 0:m.start()]
        after = text[m.end():loops[k + 1].start() if k + 1 < len(loops) else len(text)]
        cpu = _CPU_USE.search(after)
        builds, dangerous = _BUILDS.search(after), _DANGEROUS.search(after)
        sections = {name.lower(): float(avg) for name, _, avg, _, _, _ in _SECTION.findall(after)}
        runs.append({"seconds": float(m.group(1)), "ranks": int(m.group(2)),
                     "steps": int(m.group(3)), "atoms": int(m.group(4)),
                     "kinetic": kinetic_energies(before),
                     "cpu_use": float(cpu.group(1)) / 100.0 if cpu else None,
                     "threads": int(cpu.group(3)) if cpu else None,
                     "sections": sections or None,
                     "neighbor_builds": int(builds.group(1)) if builds else None,
                     "dangerous_builds": int(dangerous.group(1)) if dangerous else None})
    return runs


def timed_terms(runs, steps, repeats):
    """What a peer's row says of its timed runs: the last ``repeats`` runs of
    ``steps`` steps among ``runs`` (:func:`parse_runs`).

    The timed runs are ``run N pre no post yes`` after a ``run 0`` (whose
    setup sets LAMMPS's count of neighbour-list builds to 0): without a
    setup LAMMPS's count runs on, so the builds of each timed run are the
    differences of the counts it prints.

    Returns
    -------
    dict
        ``seconds`` (median loop time), ``cpu_seconds`` (median of loop time
        × ranks × CPU use), ``neighbor_builds`` (per timed run),
        ``dangerous_builds`` (the largest count printed; 0: none),
        ``breakdown`` (each section's
        share of the timed runs' loop time, summed over them), ``threads``
        (OpenMP threads per rank) and ``kinetic`` (the kinetic energy at the
        start and at the end of the timed runs, LAMMPS units).
    """
    timed = [r for r in runs if r["steps"] == steps][-repeats:]
    if len(timed) < repeats:
        raise RuntimeError(f"LAMMPS log holds {len(timed)} runs of {steps} steps, "
                           f"{repeats} expected")
    missing = [k for k, r in enumerate(timed) if r["sections"] is None]
    if missing:
        raise RuntimeError(f"LAMMPS log lacks the timing breakdown of timed runs {missing} "
                           "(run with post yes)")
    counts = [0] + [r["neighbor_builds"] for r in timed]
    loop = sum(r["seconds"] for r in timed)
    names = list(timed[0]["sections"])
    return {"seconds": float(np.median([r["seconds"] for r in timed])),
            "cpu_seconds": float(np.median([r["seconds"] * r["ranks"] * r["cpu_use"]
                                            for r in timed])),
            "neighbor_builds": [b - a for a, b in zip(counts, counts[1:])],
            "dangerous_builds": max(r["dangerous_builds"] for r in timed),
            "breakdown": {s: sum(r["sections"].get(s, 0.0) for r in timed) / loop for s in names},
            "threads": timed[0]["threads"],
            "kinetic": [timed[0]["kinetic"][0], timed[-1]["kinetic"][-1]]}


def rms_speed(kinetic, mass):
    """Root-mean-square speed, weighted by mass, of a pile of total ``mass``
    and translational kinetic energy ``kinetic``: ``sqrt(2 E / M)``."""
    return float(np.sqrt(2.0 * max(kinetic, 0.0) / mass))


def parse_log(text, marks=("contacts", "mass", "steps"), pattern=_MARK):
    """Loop times, runs and the marks of a LAMMPS log of :func:`lammps_input`
    (or, with its ``marks`` and their ``pattern``, of the polygon peer's).

    Returns
    -------
    dict
        ``loops``: list of (seconds, ranks, steps, atoms), one per ``run``;
        ``runs``: :func:`parse_runs`; ``version``: LAMMPS's, from the log's
        first line; and the printed ``marks`` (``contacts``, ``mass`` and
        ``steps``).
    """
    loops = loop_times(text)
    found = {k.lower(): float(v) for k, v in pattern.findall(text)}
    missing = set(marks) - set(found)
    if missing or not loops:
        raise RuntimeError(f"LAMMPS log lacks {sorted(missing) or 'Loop time lines'}")
    version = _VERSION.search(text)
    return {"loops": loops, "runs": parse_runs(text),
            "version": version.group(1) if version else None, **found}


def time_peer(shapes, ranks, dt, skin, model, steps=200, repeats=5, cache=Path(".bench")):
    """Time the settled disk pile of ``shapes`` (:func:`settled_peer`) on ``ranks`` MPI ranks.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        The polygons of the pile timed beside it.
    ranks : int
    dt, skin : float
        The polygon pile's time step and skin.
    model : sim.config.ModelParams
        The polygon pile's contact settings.
    steps, repeats : int
    cache : Path
        Folder of the settled disk piles.

    Returns
    -------
    dict
        ``n_particles``, ``ranks``, ``contacts_per_particle``,
        ``lammps_ns_per_particle_step`` (median of the timed runs),
        ``lammps_ns_per_contact``, ``mass_error`` (relative, of the total mass).
    """
    find_lmp()
    pile = disk_pile(shapes)
    n = len(pile["mass"])
    settled = settled_peer(shapes, dt, skin, model, cache)
    with tempfile.TemporaryDirectory(dir=cache) as tmp:
        tmp = Path(tmp)
        shutil.copy(settled, tmp / "settled.data")
        (tmp / "in.lammps").write_text(lammps_input(pile, model, dt, skin, steps, repeats))
        log_text = run_lmp(tmp, find_lmp(), MPIRUN, ranks, f"LAMMPS peer, timing {n} disks")
    parsed = parse_log(log_text)
    mass_error = parsed["mass"] / float(pile["mass"].sum()) - 1.0
    if abs(mass_error) > 1e-6:
        raise RuntimeError(f"LAMMPS peer: its disks weigh {mass_error:+.2e} (relative) "
                           "against the polygons; the data file's densities are wrong")
    pairs = parsed["contacts"]
    terms = peer_terms(parsed, "lammps", find_lmp(), n, float(pile["mass"].sum()), dt, steps,
                       repeats)
    return {"n_particles": n, "ranks": ranks, "contacts_per_particle": pairs / n,
            **terms, "lammps_ns_per_contact": terms["lammps_ns_per_particle_step"] * n
            / max(pairs, 1.0), "mass_error": mass_error}


def peer_terms(parsed, peer, lmp, n, mass, dt, steps, repeats, energy_unit=1.0):
    """The terms of a peer's row from the log of its timed runs (:func:`parse_log`).

    Parameters
    ----------
    parsed : dict
        From :func:`parse_log`.
    peer : {"lammps", "lammps_polygons"}
        The peer's name in the keys.
    lmp : str
        The LAMMPS executable that ran (:func:`lmp_build`).
    n : int
        Particles.
    mass : float
        Their total mass, kg/m.
    dt : float
        The peer's time step, s.
    steps, repeats : int
    energy_unit : float
        LAMMPS's unit of energy in J/m.

    Returns
    -------
    dict
        ``{peer}_ns_per_particle_step`` (wall, median of the timed runs),
        ``{peer}_cpu_ns_per_particle_step`` (CPU of all ranks),
        ``dt``, ``steps``, ``neighbor_builds`` (per timed run),
        ``dangerous_builds``, ``breakdown`` (LAMMPS's sections' shares of
        the loop time), ``omp_threads``, ``lammps_version``, ``lammps_build``
        (:func:`lmp_build`), ``kinetic_energy_per_particle`` (translational,
        J/m) and ``rms_speed`` (m/s, :func:`rms_speed`), each at the start
        and at the end of the timed runs.
    """
    terms = timed_terms(parsed["runs"], steps, repeats)
    kinetic = [e * energy_unit for e in terms["kinetic"]]
    return {f"{peer}_ns_per_particle_step": terms["seconds"] / steps / n * 1e9,
            f"{peer}_cpu_ns_per_particle_step": terms["cpu_seconds"] / steps / n * 1e9,
            "dt": dt, "steps": steps, "neighbor_builds": terms["neighbor_builds"],
            "dangerous_builds": terms["dangerous_builds"], "breakdown": terms["breakdown"],
            "omp_threads": terms["threads"], "lammps_version": parsed["version"],
            "lammps_build": lmp_build(lmp),
            "kinetic_energy_per_particle": [e / n for e in kinetic],
            "rms_speed": [rms_speed(e, mass) for e in kinetic]}


def ratios(rows, peers, peer="lammps"):
    """Each polygon row's ratio to the LAMMPS pile of the same N and threads = ranks.

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`sim.numerics.bench.measure`.
    peers : list of dict
        Rows of a peer's ``time_peer`` (this module's disks, or
        :mod:`sim.numerics.lammps_polygons`), keyed ``{peer}_ns_per_particle_step``
        and ``{peer}_ns_per_contact``.
    peer : {"lammps", "lammps_polygons"}
        The peer's name in the keys.

    Returns
    -------
    list of dict
        The rows with ``{peer}_ns_per_particle_step``, ``ratio_to_{peer}``
        (per particle-step) and ``ratio_to_{peer}_per_contact`` added where a
        peer of the same N and parallelism was timed, and, where both carry
        their cost per simulated second (CPU), ``ratio_to_{peer}_per_simulated_s``.
    """
    by_key = {(p["n_particles"], p["ranks"]): p for p in peers}
    out = []
    for r in rows:
        p = by_key.get((r["n_particles"], r["threads"]))
        if p is None:
            out.append(dict(r))
            continue
        out.append({**r, f"{peer}_ns_per_particle_step": p[f"{peer}_ns_per_particle_step"],
                    f"ratio_to_{peer}": r["ns_per_particle_step"] / p[f"{peer}_ns_per_particle_step"],
                    f"ratio_to_{peer}_per_contact": r["ns_per_contact"] / p[f"{peer}_ns_per_contact"]})
        if "cpu_s_per_simulated_s" in p and "cpu_s_per_simulated_s" in r:
            out[-1][f"ratio_to_{peer}_per_simulated_s"] = (r["cpu_s_per_simulated_s"]
                                                           / p["cpu_s_per_simulated_s"])
    return out
