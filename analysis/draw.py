"""Pictures of particle states (``python -m analysis draw``).

Reads a particle-state file through the contract (docs/formats.md#state-files,
:func:`analysis.states.load_state`), so it draws any state that follows it:

* the polygons to scale (equal aspect), their corners in the lab frame
  (:meth:`analysis.states.State.world_vertices`);
* coloured by the particle pressure p = -(sigma_xx + sigma_yy)/2 (N/m), with
  sigma the particle stress of Eq. 2 of the paper
  (:func:`analysis.stress.particle_stress`). Compression is negative in
  sigma, so p > 0 under compression;
* optionally the contact-force network: a line between the centres of two
  particles in contact (from the centre to the contact point for the
  support), its width proportional to the magnitude of the contact force;
* the support, the line y = 0, and the fixed polygons of a rough base on it
  where the file has one (:func:`base_polygons`), so that a pile on a rough
  base rests on them in the picture;
* framed on the pile (:func:`pile_frame`): a particle flung far away, or
  one that lost contact, does not shrink the pile to a speck; the picture
  says which particles lie out of frame.

The picture is written atomically (:func:`analysis.figures.save`), so a
killed job never leaves half a picture.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .errors import InputError
from .netcdf import check_writable
from .states import State, load_state
from .stress import particle_stress

COLOUR_BY = ("pressure", "none")
#: Percentiles of the centres of the particles connected to the support that
#: bound the bulk of a pile, in x and in y (:func:`pile_frame`).
BULK_PERCENTILES = (1.0, 99.0)
#: How far beyond those percentiles a particle still counts as part of the
#: pile: this fraction of the larger extent between them, plus two of the
#: largest particle's sizes.
BULK_MARGIN = 0.1


def polygons_world(state: State) -> list[np.ndarray]:
    """Corners of every particle in the lab frame: a list of ``(n_corners, 2)`` arrays."""
    vx, vy, counts = state.world_vertices()
    return [np.column_stack((vx[p, :n], vy[p, :n])) for p, n in enumerate(counts)]


def base_polygons(path: str) -> list[np.ndarray]:
    """Corners of the rough base's polygons in the lab frame, left to right:
    a list of ``(n_corners, 2)`` arrays, empty for a file without a base.

    The state contract reads them as no particles
    (:func:`analysis.states.state_from_dataset`); they are the file's
    ``base_x``, ``base_y``, ``base_theta`` and body-frame corners
    ``base_node_x``, ``base_node_y`` in runs of ``base_node_count``
    (docs/formats.md#state-files), turned and moved as a particle's corners are.
    """
    import xarray as xr

    with xr.open_dataset(path, decode_times=False) as ds:
        if "base_x" not in ds:
            return []
        x, y, theta, counts, nx, ny = (ds[name].values for name in (
            "base_x", "base_y", "base_theta", "base_node_count", "base_node_x", "base_node_y"))
    ends = np.cumsum(counts)
    out = []
    for b, (lo, hi) in enumerate(zip(ends - counts, ends)):
        c, s = np.cos(theta[b]), np.sin(theta[b])
        out.append(np.column_stack((x[b] + c * nx[lo:hi] - s * ny[lo:hi],
                                    y[b] + s * nx[lo:hi] + c * ny[lo:hi])))
    return out


def particle_pressure(state: State) -> np.ndarray:
    """Particle pressure p = -(sigma_xx + sigma_yy)/2 in N/m of the Eq. 2 stress; positive under compression."""
    sigma = particle_stress(state)
    return -0.5 * (sigma[:, 0, 0] + sigma[:, 1, 1])


def force_segments(state: State) -> tuple[np.ndarray, np.ndarray]:
    """Line segments of the force network, ``(n_contacts, 2, 2)``, and the force magnitudes.

    A particle–particle contact joins the two centres; a support contact
    joins the particle's centre to the contact point.
    """
    ci, cj = state.contact_i, state.contact_j
    start = np.column_stack((state.x[ci], state.y[ci]))
    support = cj < 0
    jj = np.where(support, 0, cj)
    end = np.where(support[:, None], np.column_stack((state.contact_x, state.contact_y)),
                   np.column_stack((state.x[jj], state.y[jj])))
    return np.stack((start, end), axis=1), np.hypot(state.force_x, state.force_y)


def connected_to_support(state: State) -> np.ndarray:
    """Boolean mask of the particles that a chain of contacts joins to the
    support (or a wall): those a pile at rest rests on it through."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = state.n_particles
    ends = np.where(state.support, n, state.contact_j)  # node n: the support
    graph = coo_matrix((np.ones(ends.size), (state.contact_i, ends)), shape=(n + 1, n + 1))
    labels = connected_components(graph, directed=False)[1]
    return labels[:n] == labels[n]


def pile_frame(state: State, polys: list[np.ndarray]) -> tuple[tuple, tuple, np.ndarray]:
    """The picture's frame: around the bulk of the pile, not a stray particle.

    The bulk is made of the particles connected to the support
    (:func:`connected_to_support`; every particle when none is) whose
    centres lie within :data:`BULK_PERCENTILES` of theirs, in x and in y,
    widened by :data:`BULK_MARGIN`; the frame holds each of them whole, and
    the support.

    Parameters
    ----------
    state : State
    polys : list of ndarray
        The particles' corners in the lab frame (:func:`polygons_world`).

    Returns
    -------
    xlim, ylim : tuple of float
        The frame, without padding.
    out : ndarray of int
        The particles with a corner out of the frame, in index order.
    """
    centres = np.column_stack((state.x, state.y))
    bulk = connected_to_support(state)
    if not bulk.any():
        bulk[:] = True
    lo, hi = np.percentile(centres[bulk], BULK_PERCENTILES, axis=0)
    size = max(float(np.max(np.abs(p - c))) for p, c in zip(polys, centres))
    margin = BULK_MARGIN * float(np.max(hi - lo)) + 2.0 * size
    bulk &= np.all((centres >= lo - margin) & (centres <= hi + margin), axis=1)
    corners = np.concatenate([polys[k] for k in np.flatnonzero(bulk)])
    (xmin, ymin), (xmax, ymax) = corners.min(axis=0), corners.max(axis=0)
    ymin = min(ymin, 0.0)
    out = np.array([k for k, p in enumerate(polys)
                    if p[:, 0].min() < xmin or p[:, 0].max() > xmax
                    or p[:, 1].min() < ymin or p[:, 1].max() > ymax], dtype=np.int64)
    return (float(xmin), float(xmax)), (float(ymin), float(ymax)), out


def out_of_frame_note(state: State, out: np.ndarray, shown: int = 3) -> str:
    """The words that name the particles out of the frame (empty for none).

    Parameters
    ----------
    state : State
    out : ndarray of int
        The particles out of frame (:func:`pile_frame`).
    shown : int
        How many of them are named with their centres; the rest are counted.
    """
    if not out.size:
        return ""
    where = ", ".join(f"#{k} at ({state.x[k]:.3g}, {state.y[k]:.3g}) m" for k in out[:shown])
    more = f" and {out.size - shown} more" if out.size > shown else ""
    return (f"{out.size} particle{'s' * (out.size != 1)} out of frame (framed on the pile): "
            f"{where}{more}")


def _pressure_limits(p: np.ndarray) -> tuple[float, float, str]:
    """Colour range: from min(0, lowest) to the highest value, or to the 99th
    percentile in a pile of 100 particles or more, so that a single impact does
    not wash out the pile; and the colour bar's ``extend``."""
    lo = min(0.0, float(np.min(p)))
    hi = float(np.percentile(p, 99) if p.size >= 100 else np.max(p))
    extend = "max" if hi < float(np.max(p)) else "neither"
    return lo, (hi if hi > lo else lo + 1.0), extend


def draw_state(path_in: str, path_out: str, color_by: str = "pressure", forces: bool = True,
               dpi: int = 150) -> str:
    """Draw the particle state in ``path_in`` to ``path_out`` (format from its suffix, e.g. .png).

    Parameters
    ----------
    path_in, path_out : str
        State file (docs/formats.md#state-files) and picture.
    color_by : {"pressure", "none"}
        Colour the particles by their Eq. 2 pressure (N/m), or grey.
    forces : bool
        Draw the contact-force network on top.
    dpi : int
        Resolution of raster formats.

    Returns
    -------
    str
        What the picture says of the particles out of its frame
        (:func:`pile_frame`, :func:`out_of_frame_note`); empty for none.
    """
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    from .figures import save

    if color_by not in COLOUR_BY:
        raise ValueError(f"color_by = {color_by!r}: must be one of {', '.join(COLOUR_BY)}")
    state = load_state(path_in)
    polys = polygons_world(state)
    (xmin, xmax), (ymin, ymax), out = pile_frame(state, polys)
    note = out_of_frame_note(state, out)
    pad = 0.03 * max(xmax - xmin, ymax - ymin, 1e-12)

    fig_w = 10.0
    fig_h = min(max(3.0, fig_w * (ymax - ymin + 2 * pad) / (xmax - xmin + 2 * pad) + 2.0), 14.0)
    fig = Figure(figsize=(fig_w, fig_h), layout="constrained")
    ax = fig.add_subplot()

    coll = PolyCollection(polys, edgecolors="0.25", linewidths=0.3)
    if color_by == "pressure":
        p = particle_pressure(state)
        lo, hi, extend = _pressure_limits(p)
        coll.set_array(p)
        coll.set_cmap("viridis")
        coll.set_clim(lo, hi)
    else:
        coll.set_facecolor("0.85")
    ax.add_collection(coll)

    if forces and state.contact_i.size:
        segments, mag = force_segments(state)
        fmax = float(mag.max())
        if fmax > 0:
            ax.add_collection(LineCollection(segments, linewidths=3.0 * mag / fmax, colors="crimson",
                                             alpha=0.8, capstyle="round"))

    # The support: its top surface is y = 0; a rough base lies on it.
    ax.axhline(0.0, color="black", linewidth=1.5)
    ax.fill_between([xmin - pad, xmax + pad], -pad, 0.0, color="0.6", hatch="///", linewidth=0)
    base = base_polygons(path_in)
    if base:
        ax.add_collection(PolyCollection(base, facecolors="0.45", edgecolors="0.2",
                                         linewidths=0.3))
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(-pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")

    attrs = state.attrs
    title = [f"{attrs.get('protocol', '?')} seed {attrs.get('seed', '?')}", Path(path_in).stem]
    if "time" in attrs:
        title.append(f"t = {float(attrs['time']):.4g} s")
    title.append(f"g = {state.gravity:.4g} m/s²")
    title.append(f"{state.n_particles} particles")
    ax.set_title(", ".join(title) + (f"\n{note}" if note else ""))
    if color_by == "pressure":
        fig.colorbar(coll, ax=ax, orientation="horizontal", shrink=0.5, aspect=40, extend=extend,
                     label="particle pressure −(σxx+σyy)/2 [N/m] (Eq. 2)")
    save(fig, [str(path_out)], dpi)
    return note


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``python -m analysis draw``."""
    parser.add_argument("--input", required=True, help="particle-state file (.nc, docs/formats.md#state-files)")
    parser.add_argument("--out", required=True, help="picture to write (.png, .pdf, .svg)")
    parser.add_argument("--color-by", choices=COLOUR_BY, default="pressure",
                        help="colour particles by their Eq. 2 pressure, or not at all")
    parser.add_argument("--forces", action=argparse.BooleanOptionalAction, default=True,
                        help="draw the contact-force network (default: yes)")
    parser.add_argument("--dpi", type=int, default=150)


def picture_format(path: str, option: str = "--out") -> str:
    """The picture format of ``path`` from its extension, or :class:`~analysis.errors.InputError`.

    The formats are those matplotlib writes (png, pdf, svg, eps, jpg, tif, webp, ...); a path
    without an extension, or with another, is refused before any work, naming the option.
    """
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    ext = Path(path).suffix.lstrip(".").lower()
    if ext not in formats:
        raise InputError(f"{option} {path}: " + (f"a picture cannot be written as .{ext}" if ext else
                                                  "no extension to tell the picture's format")
                         + f"; end it in one of .{', .'.join(formats)}")
    return ext


def cmd_draw(args: argparse.Namespace, params: dict) -> None:
    """``python -m analysis draw``: the picture of ``args.input`` in ``args.out``.

    A state that breaks the contract raises :class:`~analysis.errors.StateError`
    (from :func:`~analysis.states.load_state`), a picture that cannot be
    written :class:`~analysis.errors.InputError`; ``params`` is not used.
    Particles out of the frame are named on stderr too.
    """
    picture_format(args.out)
    check_writable(args.out, "--out")
    try:
        note = draw_state(args.input, args.out, color_by=args.color_by, forces=args.forces, dpi=args.dpi)
    except OSError as err:
        raise InputError(f"{args.out}: cannot be written ({err})") from err
    if note:
        print(f"[analysis] draw {args.out}: {note}", file=sys.stderr, flush=True)
