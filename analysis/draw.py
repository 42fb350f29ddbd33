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
* the support, the line y = 0.

The picture is written atomically (:func:`analysis.figures.save`), so a
killed job never leaves half a picture.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .errors import InputError
from .netcdf import check_writable
from .states import State, load_state
from .stress import particle_stress

COLOUR_BY = ("pressure", "none")


def polygons_world(state: State) -> list[np.ndarray]:
    """Corners of every particle in the lab frame: a list of ``(n_corners, 2)`` arrays."""
    vx, vy, counts = state.world_vertices()
    return [np.column_stack((vx[p, :n], vy[p, :n])) for p, n in enumerate(counts)]


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


def _pressure_limits(p: np.ndarray) -> tuple[float, float, str]:
    """Colour range: from min(0, lowest) to the highest value, or to the 99th
    percentile in a pile of 100 particles or more, so that a single impact does
    not wash out the pile; and the colour bar's ``extend``."""
    lo = min(0.0, float(np.min(p)))
    hi = float(np.percentile(p, 99) if p.size >= 100 else np.max(p))
    extend = "max" if hi < float(np.max(p)) else "neither"
    return lo, (hi if hi > lo else lo + 1.0), extend


def draw_state(path_in: str, path_out: str, color_by: str = "pressure", forces: bool = True,
               dpi: int = 150) -> None:
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
    """
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    from .figures import save

    if color_by not in COLOUR_BY:
        raise ValueError(f"color_by = {color_by!r}: must be one of {', '.join(COLOUR_BY)}")
    state = load_state(path_in)
    polys = polygons_world(state)
    corners = np.concatenate(polys)
    xmin, ymin = corners.min(axis=0)
    xmax, ymax = corners.max(axis=0)
    ymin = min(ymin, 0.0)
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

    # The support: its top surface is y = 0.
    ax.axhline(0.0, color="black", linewidth=1.5)
    ax.fill_between([xmin - pad, xmax + pad], -pad, 0.0, color="0.6", hatch="///", linewidth=0)
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
    ax.set_title(", ".join(title))
    if color_by == "pressure":
        fig.colorbar(coll, ax=ax, orientation="horizontal", shrink=0.5, aspect=40, extend=extend,
                     label="particle pressure −(σxx+σyy)/2 [N/m] (Eq. 2)")
    save(fig, [str(path_out)], dpi)


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
    """
    picture_format(args.out)
    check_writable(args.out, "--out")
    try:
        draw_state(args.input, args.out, color_by=args.color_by, forces=args.forces, dpi=args.dpi)
    except OSError as err:
        raise InputError(f"{args.out}: cannot be written ({err})") from err
