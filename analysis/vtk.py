"""Export of one particle state for ParaView / OVITO (``python -m analysis export``).

Reads a particle-state file through the contract (docs/formats.md#state-files,
:func:`analysis.states.load_state`) and writes two VTK XML unstructured-grid
files with :mod:`meshio` (binary, zlib-compressed)::

    python -m analysis export --input results/piles/wedge/seed2/relaxed.nc --vtk relaxed.vtu

writes ``relaxed.vtu`` (the particles) and ``relaxed_contacts.vtu`` (the
contact network) next to each other. All points lie in the plane z = 0.

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
* ``orientation``, rad: theta as stored (not wrapped to one turn);
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
export never leaves a complete-looking file.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from .draw import force_segments, particle_pressure
from .errors import InputError
from .netcdf import atomic_path
from .states import State, load_state
from .stress import particle_stress

CONTACTS_SUFFIX = "_contacts"


def contacts_path(path: str) -> str:
    """Name of the contact-network file that goes with the particles file ``path``.

    ``pile.vtu`` -> ``pile_contacts.vtu``.
    """
    stem, ext = os.path.splitext(path)
    return f"{stem}{CONTACTS_SUFFIX}{ext}"


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
    import meshio

    wx, wy, counts = state.world_vertices()
    n = state.n_particles
    kmax = wx.shape[1]
    keep = np.arange(kmax)[None, :] < counts[:, None]
    points = _xyz(wx[keep], wy[keep])  # row-major: particle after particle, corners in order
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # Runs of consecutive particles with the same corner count.
    starts = np.flatnonzero(np.concatenate([[True], counts[1:] != counts[:-1]]))
    ends = np.concatenate([starts[1:], [n]])

    sigma = particle_stress(state)
    stress = np.zeros((n, 3, 3))
    stress[:, :2, :2] = sigma
    n_support = np.bincount(state.contact_i[state.contact_j < 0], minlength=n).astype(np.int64)
    per_particle = {
        "particle": np.arange(n, dtype=np.int64),
        "velocity": _xyz(state.vx, state.vy),
        "angular_velocity": state.omega.astype(np.float64),
        "orientation": state.theta.astype(np.float64),
        "pressure": particle_pressure(state),
        "stress": stress.reshape(n, 9),
        "coordination": coordination(state),
        "support_contacts": n_support,
        "area": state.area.astype(np.float64),
        "mass": state.mass.astype(np.float64),
    }
    cells, cell_data = [], {k: [] for k in per_particle}
    for a, b in zip(starts, ends):
        k = int(counts[a])
        conn = offsets[a:b, None] + np.arange(k)[None, :]
        cells.append(meshio.CellBlock("polygon", conn.astype(np.int64)))
        for name, v in per_particle.items():
            cell_data[name].append(v[a:b])
    return meshio.Mesh(points, cells, cell_data=cell_data)


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
        raise InputError(f"{path_out}: the VTK output must be a .vtu file (VTK XML unstructured grid)")
    state = load_state(path_in)
    particles, contacts = particle_mesh(state), contact_mesh(state)
    path_c = contacts_path(path_out)
    try:
        # Nested: both are renamed only once both are complete.
        with atomic_path(path_out) as tmp_p, atomic_path(path_c) as tmp_c:
            meshio.write(tmp_p, particles, file_format="vtu")
            meshio.write(tmp_c, contacts, file_format="vtu")
    except OSError as err:
        raise InputError(f"{path_out}: cannot be written ({err})") from err
    return path_out, path_c


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``python -m analysis export``."""
    parser.add_argument("--input", required=True, help="particle-state file (.nc, docs/formats.md#state-files)")
    parser.add_argument("--vtk", required=True, metavar="OUT.vtu",
                        help="particles file to write (.vtu); the contact network goes to OUT_contacts.vtu")


def cmd_export(args: argparse.Namespace, params: dict) -> None:
    """``python -m analysis export``: ``args.input`` as ``args.vtk`` and its contact file.

    A state that breaks the contract raises :class:`~analysis.errors.StateError`,
    an output that cannot be written :class:`~analysis.errors.InputError`;
    ``params`` is not used.
    """
    import sys
    import time

    t0 = time.perf_counter()
    p, c = export_state(args.input, args.vtk)
    print(f"[analysis] export: {args.input} -> {p}, {c} ({time.perf_counter() - t0:.2f} s)",
          file=sys.stderr, flush=True)
