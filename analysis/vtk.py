"""Export of particle states for ParaView / OVITO (``python -m analysis export``).

A state: reads a particle-state file through the contract
(docs/formats.md#state-files, :func:`analysis.states.load_state`) and writes
two VTK XML unstructured-grid files with :mod:`meshio` (binary,
zlib-compressed)::

    python -m analysis export --input results/piles/wedge/seed2/relaxed.nc --vtk relaxed.vtu

writes ``relaxed.vtu`` (the particles) and ``relaxed_contacts.vtu`` (the
contact network) next to each other. All points lie in the plane z = 0.

A pour: reads the frames a pour wrote (``python -m sim pour --frames``) and
writes a ParaView time series, one polygon file per frame and a collection
that gives each its simulated time (see *Frames of a pour* below)::

    python -m analysis export --frames results/piles/wedge/seed2/frames.nc --vtk pour.pvd

Why two files and not one file with a ``kind`` field
----------------------------------------------------
A VTK file has one set of cell-data arrays for all its cells. In a single
file the particle fields (pressure, velocity, ...) would have to be padded on
the contact cells and the contact fields on the particle cells, so every
colour map would start on made-up values and the user would first have to
split the grid with a Threshold filter on ``kind``. With two files each one
holds only fields that mean something on every one of its cells, opens as
its own pipeline source that can be coloured, hidden, filtered (Tube, Glyph)
and exported independently, and the particle cell ids equal the particle
indices of the state file.

Particles: ``OUT.vtu``
----------------------
One ``VTK_POLYGON`` cell per particle, **in particle order** (cell id =
particle index), its ``node_count`` corners in the lab frame
(:meth:`analysis.states.State.world_vertices`), counter-clockwise; corners
are not shared between particles. Cell data (name, units: meaning):

* ``particle``, 1: index of the particle in the state file;
* ``velocity``, m/s: (vx, vy, 0), velocity of the centre of mass;
* ``angular_velocity``, rad/s: omega, counter-clockwise positive;
* ``orientation``, rad: theta wrapped to one turn, (-pi, pi]
  (:func:`wrap_angle`; the state file keeps the integrated angle, which may
  be several turns);
* ``pressure``, N/m: p = -(sigma_xx + sigma_yy)/2 of the particle stress of
  Eq. 2 (:func:`analysis.draw.particle_pressure`), positive under compression;
* ``stress``, N/m: the Eq. 2 particle stress sigma_ij
  (:func:`analysis.stress.particle_stress`) as a 3x3 tensor, row-major
  (xx, xy, xz, yx, ...), z row and column zero; compression negative (the
  docs/formats.md sign convention); not symmetrised;
* ``coordination``, 1: number of particle–particle contacts of the particle
  (contacts with the support, ``contact_j = -1``, not counted);
* ``support_contacts``, 1: number of its contacts with the support;
* ``area``, m²: area of the polygon;
* ``mass``, kg: mass.

Contacts: ``OUT_contacts.vtu``
------------------------------
One ``VTK_LINE`` cell per contact, in contact order (cell id = contact
index): from the centre of ``contact_i`` to the centre of ``contact_j``, or,
for a contact with the support (``contact_j = -1``), from the centre of
``contact_i`` to the contact point. Every line has its own two points, so
ParaView's *Cell Data to Point Data* carries each contact's value to its
ends unchanged (needed for *Tube* with a radius varying by force). Cell
data (name, units: meaning):

* ``contact``, 1: index of the contact in the state file;
* ``contact_i``, ``contact_j``, 1: particle indices of the pair, ``contact_j``
  = -1 for the support;
* ``force``, N: (force_x, force_y, 0), the total contact force acting on
  ``contact_i`` (``contact_j`` gets its negative);
* ``normal_force``, N: f_n = -force · n, n = (normal_x, normal_y) the unit
  normal from ``contact_i`` towards ``contact_j``: the force component along
  the contact normal, signed so that it is **positive when the contact pushes
  the two apart** (compression), like ``pressure``; negative only where
  damping makes a contact attractive;
* ``tangential_force``, N: \\|force - (force · n) n\\| >= 0;
* ``normal``, 1: (normal_x, normal_y, 0);
* ``overlap_area``, m²: overlap area A of the two polygons;
* ``length``, m: length of the drawn line.

Global attributes of the state (time, gravity, ...) are not carried: meshio
does not write VTK field data to ``.vtu``; they stay in the netCDF file.

Frames of a pour: ``OUT.pvd`` and ``OUT/``
-------------------------------------------
``OUT/OUT_0000.vtu``, ``OUT/OUT_0001.vtu``, ... (four digits, more beyond
10 000 frames): frame k of the frames file as one ``VTK_POLYGON`` cell per
particle released by then, in particle order, its corners in the lab frame
from the frame's centre and orientation (float32 in the frames file) and the
body-frame corners; written by the same polygon writer as ``OUT.vtu``
(:func:`polygon_mesh`). Cell data: ``particle`` (index in the frames file;
the cell id as long as particles are released in index order, as a pour
does), ``orientation`` (rad, wrapped to (-pi, pi]) and ``speed`` (m/s, of
the centre of mass). A frame before the first release is a grid without
cells (with the same, empty, arrays).

``OUT.pvd``: a VTK ``Collection`` listing the frame files (paths relative
to it) with ``timestep`` = the frame's simulated time in s (``time`` of the
frames file, written with all its digits), which ParaView's time controls
step through: *File > Open* ``OUT.pvd`` (one source, one time step per
frame), *Apply*, colour by ``speed``, then *Play*.

Opening in ParaView
-------------------
*File > Open* both files, *Apply*; switch the render view to 2D.
Colour ``OUT.vtu`` by ``pressure`` (or ``coordination``, ``velocity``
Magnitude). For the force network colour ``OUT_contacts.vtu`` by
``normal_force``; for line widths growing with the force apply
*Cell Data to Point Data* then *Tube* (Scalars ``normal_force``, Vary Radius
By Scalar, Radius Factor e.g. 10). Arrows of the force at the contact midpoints:
*Cell Centers* then *Glyph* (Orientation ``force``, Scale ``force``).
Show a subset with *Threshold* (e.g. ``contact_j`` between -1 and -1 for the
support contacts, ``coordination`` for rattlers).

OVITO: not tried. Its manual lists VTK among the geometry formats it imports
as triangle meshes (extra objects next to particle data); whether a given
OVITO version opens these polygon and line grids with their cell data is
unverified, and its particle modifiers (coordination, clusters) would want
the particles as points, not polygons.

Both files are written atomically (:func:`analysis.netcdf.atomic_path`),
each to a temporary name renamed only after both are complete, so a failed
export never leaves a complete-looking file. A pour's frames go to a
temporary folder that replaces ``OUT/`` once complete, and ``OUT.pvd`` is
written last (:func:`export_frames`).
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from sim.atomic import OutputError, atomic_path

from .draw import force_segments, particle_pressure
from .errors import InputError
from .states import State, load_state
from .stress import particle_stress

CONTACTS_SUFFIX = "_contacts"


def contacts_path(path: str) -> str:
    """Name of the contact-network file that goes with the particles file ``path``.

    ``pile.vtu`` -> ``pile_contacts.vtu``.
    """
    stem, ext = os.path.splitext(path)
    return f"{stem}{CONTACTS_SUFFIX}{ext}"


def wrap_angle(theta) -> np.ndarray:
    """Angles wrapped to one turn, (-pi, pi] (float64).

    The simulator keeps integrating the orientation, so a particle that has
    rolled holds theta of several turns; the exported ``orientation`` is the
    same direction in (-pi, pi]: pi stays pi and -pi becomes pi.

    Parameters
    ----------
    theta : array_like
        Angles, rad.

    Returns
    -------
    numpy.ndarray
        ``theta - 2 pi k`` in (-pi, pi], float64; NaN stays NaN.
    """
    theta = np.asarray(theta, dtype=np.float64)
    wrapped = np.pi - np.mod(np.pi - theta, 2.0 * np.pi)
    # np.mod may round a tiny negative remainder up to 2 pi, giving -pi
    return np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)


def _xyz(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``(n, 3)`` float64 points or vectors with z = 0."""
    return np.column_stack((x, y, np.zeros_like(x))).astype(np.float64)


def coordination(state: State) -> np.ndarray:
    """Number of particle–particle contacts of every particle.

    Parameters
    ----------
    state : State

    Returns
    -------
    numpy.ndarray
        ``(n_particles,)`` int; each contact counts once for ``contact_i``
        and once for ``contact_j``; contacts with the support
        (``contact_j = -1``) are not counted.
    """
    pp = state.contact_j >= 0
    n = state.n_particles
    return (np.bincount(state.contact_i[pp], minlength=n)
            + np.bincount(state.contact_j[pp], minlength=n)).astype(np.int64)


def contact_force_components(state: State) -> tuple[np.ndarray, np.ndarray]:
    """Normal and tangential force of every contact.

    Parameters
    ----------
    state : State

    Returns
    -------
    normal_force : numpy.ndarray
        ``(n_contacts,)`` N, ``-f · n`` with ``f`` the force on ``contact_i``
        and ``n`` the normal from ``contact_i`` to ``contact_j``: positive when
        the contact pushes the particles apart.
    tangential_force : numpy.ndarray
        ``(n_contacts,)`` N, magnitude of ``f - (f · n) n``.
    """
    fx, fy, nx, ny = state.force_x, state.force_y, state.normal_x, state.normal_y
    fn = fx * nx + fy * ny
    return -fn, np.hypot(fx - fn * nx, fy - fn * ny)


def particle_mesh(state: State):
    """The particles as a :class:`meshio.Mesh` of polygon cells in particle order.

    Parameters
    ----------
    state : State

    Returns
    -------
    meshio.Mesh
        Points: all corners (``sum(node_count)``, z = 0). meshio keeps
        polygons of one corner count per cell block, so consecutive particles
        with the same ``node_count`` form one block; the blocks follow each
        other in particle order, so the file's cell ids are the particle
        indices. Cell data as in the module docstring.
    """
    wx, wy, counts = state.world_vertices()
    n = state.n_particles
    kmax = wx.shape[1]
    keep = np.arange(kmax)[None, :] < counts[:, None]
    corners = np.column_stack((wx[keep], wy[keep]))  # row-major: particle after particle, corners in order

    sigma = particle_stress(state)
    stress = np.zeros((n, 3, 3))
    stress[:, :2, :2] = sigma
    n_support = np.bincount(state.contact_i[state.contact_j < 0], minlength=n).astype(np.int64)
    per_particle = {
        "particle": np.arange(n, dtype=np.int64),
        "velocity": _xyz(state.vx, state.vy),
        "angular_velocity": state.omega.astype(np.float64),
        "orientation": wrap_angle(state.theta),
        "pressure": particle_pressure(state),
        "stress": stress.reshape(n, 9),
        "coordination": coordination(state),
        "support_contacts": n_support,
        "area": state.area.astype(np.float64),
        "mass": state.mass.astype(np.float64),
    }
    return polygon_mesh(corners, counts, per_particle)


def polygon_mesh(corners: np.ndarray, counts: np.ndarray, cell_data: dict[str, np.ndarray]):
    """Polygons as a :class:`meshio.Mesh`, one ``polygon`` cell per polygon, in order.

    The one writer of polygon grids: a state's particles (:func:`particle_mesh`)
    and each frame of a pour (:func:`frame_mesh`).

    Parameters
    ----------
    corners : (sum(counts), 2) array
        Lab-frame corners, m, polygon after polygon, each counter-clockwise.
    counts : (n,) int array
        Corners of each polygon.
    cell_data : dict of str to array
        Per-polygon values, first axis of length ``n`` (vectors ``(n, 3)``).

    Returns
    -------
    meshio.Mesh
        Points: the corners with z = 0, not shared between polygons. meshio
        keeps polygons of one corner count per cell block, so consecutive
        polygons with the same count form one block; the blocks follow each
        other in order, so the file's cell ids are the polygons' indices.
        Without polygons the mesh holds one empty polygon block that carries
        the (empty) cell data, so every file of a series has the same arrays.
    """
    import meshio

    counts = np.asarray(counts, dtype=np.int64)
    n = counts.size
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if corners.shape[0] != counts.sum():
        raise ValueError(f"{corners.shape[0]} corners for polygons of {int(counts.sum())} corners in all")
    points = _xyz(corners[:, 0], corners[:, 1])
    offsets = np.cumsum(counts) - counts
    # Runs of consecutive polygons with the same corner count.
    starts = np.flatnonzero(np.diff(counts, prepend=-1) != 0)
    ends = np.append(starts[1:], n)
    cells, data = [], {k: [] for k in cell_data}
    for a, b in zip(starts, ends):
        k = int(counts[a])
        conn = offsets[a:b, None] + np.arange(k)[None, :]
        cells.append(meshio.CellBlock("polygon", conn.astype(np.int64)))
        for name, v in cell_data.items():
            data[name].append(np.asarray(v)[a:b])
    if not cells:
        cells.append(meshio.CellBlock("polygon", np.zeros((0, 3), dtype=np.int64)))
        for name, v in cell_data.items():
            data[name].append(np.asarray(v)[:0])
    return meshio.Mesh(points, cells, cell_data=data)


def contact_mesh(state: State):
    """The contact network as a :class:`meshio.Mesh` of line cells in contact order.

    Parameters
    ----------
    state : State

    Returns
    -------
    meshio.Mesh
        ``2 n_contacts`` points (each line its own two, z = 0): centre of
        ``contact_i`` to the centre of ``contact_j``, or to the contact point
        for a support contact. Cell data as in the module docstring.
    """
    import meshio

    ci, cj = state.contact_i, state.contact_j
    m = ci.size
    segments, _ = force_segments(state)  # (m, 2 ends, 2): the lines of the pictures
    points = np.zeros((2 * m, 3))
    points[:, :2] = segments.reshape(2 * m, 2)  # start, end of contact 0, then of contact 1, ...
    start, end = points[0::2], points[1::2]
    fn, ft = contact_force_components(state)
    data = {
        "contact": np.arange(m, dtype=np.int64),
        "contact_i": ci.astype(np.int64),
        "contact_j": cj.astype(np.int64),
        "force": _xyz(state.force_x, state.force_y),
        "normal_force": fn,
        "tangential_force": ft,
        "normal": _xyz(state.normal_x, state.normal_y),
        "overlap_area": state.overlap_area.astype(np.float64),
        "length": np.linalg.norm(end - start, axis=1),
    }
    conn = np.arange(2 * m, dtype=np.int64).reshape(m, 2)
    return meshio.Mesh(points, [meshio.CellBlock("line", conn)], cell_data={k: [v] for k, v in data.items()})


def export_state(path_in: str, path_out: str) -> tuple[str, str]:
    """Export the particle state ``path_in`` to ``path_out`` and its contact file.

    Parameters
    ----------
    path_in : str
        State file (docs/formats.md#state-files).
    path_out : str
        Particles file, must end in ``.vtu``; the contact network goes to
        :func:`contacts_path` of it.

    Returns
    -------
    tuple of str
        The two files written (particles, contacts).

    Raises
    ------
    StateError
        ``path_in`` is missing or breaks the contract.
    InputError
        ``path_out`` does not end in ``.vtu`` or cannot be written.
    """
    import meshio

    if os.path.splitext(path_out)[1].lower() != ".vtu":
        raise InputError(f"--vtk {path_out}: the VTK output of a state must be a .vtu file (VTK XML "
                         "unstructured grid); a pour's frames (--frames) are written as a .pvd collection")
    state = load_state(path_in)
    particles, contacts = particle_mesh(state), contact_mesh(state)
    path_c = contacts_path(path_out)
    # Nested: both are renamed only once both are complete.
    with atomic_path(path_out) as tmp_p, atomic_path(path_c) as tmp_c:
        meshio.write(tmp_p, particles, file_format="vtu")
        meshio.write(tmp_c, contacts, file_format="vtu")
    return path_out, path_c


def frame_mesh(frames, k: int):
    """Frame ``k`` of a pour as a :class:`meshio.Mesh`: one polygon per released particle.

    Parameters
    ----------
    frames : xarray.Dataset
        A frames file (:func:`analysis.film.read_frames`).
    k : int
        Index of the frame.

    Returns
    -------
    meshio.Mesh
        The particles released by frame ``k`` (finite centre), in particle
        order, their corners in the lab frame from the frame's centre and
        orientation and the body-frame corners
        (:func:`analysis.film.world_corners`, float64). Cell data: ``particle``
        (index in the frames file), ``orientation`` (rad, wrapped to (-pi, pi]
        by :func:`wrap_angle`) and ``speed`` (m/s).
    """
    from .film import world_corners

    x, y, theta, speed = (np.asarray(frames[v].values[k], dtype=np.float64) for v in ("x", "y", "theta", "speed"))
    counts = np.asarray(frames["node_count"].values, dtype=np.int64)
    released = np.isfinite(x) & np.isfinite(y) & np.isfinite(theta)
    corners = world_corners(x, y, theta, counts, np.asarray(frames["node_x"].values, dtype=np.float64),
                            np.asarray(frames["node_y"].values, dtype=np.float64))
    return polygon_mesh(corners[np.repeat(released, counts)], counts[released], {
        "particle": np.flatnonzero(released).astype(np.int64),
        "orientation": wrap_angle(theta[released]),
        "speed": speed[released],
    })


def series_folder(path: str) -> str:
    """Folder of the frame files that go with the collection ``path``: ``pour.pvd`` -> ``pour/``."""
    return os.path.splitext(path)[0]


def _pvd_text(files: list[str], times: np.ndarray) -> str:
    """A ParaView collection (.pvd) of ``files`` (relative paths) at ``times`` (s)."""
    import xml.etree.ElementTree as ET

    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for f, t in zip(files, times):
        ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part="0", file=f)
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def export_frames(path_in: str, path_out: str) -> tuple[str, list[str]]:
    """Export the frames of a pour as a ParaView time series: ``OUT.pvd`` and ``OUT/``.

    Parameters
    ----------
    path_in : str
        Frames file (``python -m sim pour --frames``, docs/formats.md#frames-of-a-pour).
    path_out : str
        The collection, must end in ``.pvd``. Frame ``k`` goes to
        ``OUT/OUT_kkkk.vtu`` (:func:`frame_mesh`; the folder is
        :func:`series_folder`), and the collection lists each file with the
        frame's simulated time as its ``timestep``.

    Returns
    -------
    pvd : str
        The collection written.
    files : list of str
        The frame files, in frame order.

    Raises
    ------
    InputError
        ``path_in`` is missing, not a frames file or holds no frame
        (:func:`analysis.film.read_frames`, naming ``--frames``); ``path_out``
        does not end in ``.pvd`` or cannot be written.

    Notes
    -----
    The frame files are written into a temporary folder that replaces
    ``OUT/`` once complete; an existing ``OUT.pvd`` is removed before and the
    new one written (atomically) last, so a failed export never leaves a
    collection that lists missing or stale frames.
    """
    import shutil

    import meshio

    from .film import read_frames

    if os.path.splitext(path_out)[1].lower() != ".pvd":
        raise InputError(f"--vtk {path_out}: a pour's frames are written as a ParaView collection; "
                         "the output must end in .pvd (with one .vtu per frame in the folder of its name)")
    frames = read_frames(path_in, "--frames")
    times = np.asarray(frames["time"].values, dtype=np.float64)
    folder = series_folder(os.path.abspath(path_out))
    stem = os.path.basename(folder)
    digits = max(4, len(str(len(times) - 1)))
    names = [f"{stem}_{k:0{digits}d}.vtu" for k in range(len(times))]
    parent = os.path.dirname(folder)
    tmp = os.path.join(parent, f".{stem}.{os.getpid()}.tmp")
    old = os.path.join(parent, f".{stem}.{os.getpid()}.old")
    try:
        if os.path.exists(folder) and not os.path.isdir(folder):
            raise InputError(f"--vtk {path_out}: {folder} is a file, not the folder of the frames")
        os.makedirs(tmp, exist_ok=True)
        for k, name in enumerate(names):
            meshio.write(os.path.join(tmp, name), frame_mesh(frames, k), file_format="vtu")
        if os.path.exists(path_out):
            os.remove(path_out)
        if os.path.isdir(folder):
            os.replace(folder, old)
        os.replace(tmp, folder)
        with atomic_path(path_out) as tmp_pvd:
            with open(tmp_pvd, "w", encoding="utf-8") as fh:
                fh.write(_pvd_text([f"{stem}/{name}" for name in names], times))
    except OutputError:
        raise
    except OSError as err:
        raise InputError(f"--vtk {path_out}: cannot be written ({err})") from err
    finally:
        for d in (tmp, old):
            shutil.rmtree(d, ignore_errors=True)
    return path_out, [os.path.join(series_folder(path_out), name) for name in names]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``python -m analysis export``."""
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--input", help="particle-state file (.nc, docs/formats.md#state-files): "
                     "--vtk OUT.vtu and OUT_contacts.vtu")
    src.add_argument("--frames", help="frames file of a pour (python -m sim pour --frames): a ParaView time "
                     "series, --vtk OUT.pvd listing OUT/OUT_0000.vtu, ... with their simulated times")
    parser.add_argument("--vtk", required=True, metavar="OUT",
                        help="with --input the particles file (.vtu), the contact network going to "
                             "OUT_contacts.vtu; with --frames the collection (.pvd)")


def cmd_export(args: argparse.Namespace, params: dict) -> None:
    """``python -m analysis export``: a state (``--input``) or a pour's frames (``--frames``) as VTK.

    A state that breaks the contract raises :class:`~analysis.errors.StateError`,
    a frames file that is missing or holds no frame and an output that cannot
    be written :class:`~analysis.errors.InputError`; ``params`` is not used.
    """
    import sys
    import time

    t0 = time.perf_counter()
    if args.frames is not None:
        pvd, files = export_frames(args.frames, args.vtk)
        done = f"{args.frames} -> {pvd} and {len(files)} frames in {series_folder(pvd)}/"
    else:
        p, c = export_state(args.input, args.vtk)
        done = f"{args.input} -> {p}, {c}"
    print(f"[analysis] export: {done} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr, flush=True)
