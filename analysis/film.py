"""A film of a pour from its frames (``python -m analysis film``).

Reads the frames a pour wrote with ``python -m sim pour --frames`` (the
centre, orientation and speed of every released particle every
``pour.frame_interval`` simulated seconds, with the polygons' body-frame
corners; layout in ``results/README.md``) and writes

* an MP4 film (H.264, ``yuv420p`` so that every browser and player shows
  it): the polygons to scale, coloured by their speed on a logarithmic scale
  from :data:`SPEED_FLOOR` to the 99th percentile of all speeds, the
  support, and a clock with the simulated time and the number of particles
  released; the picture frames the pile and the stream falling onto it, from
  the bulk of the particles (:func:`film_extent`), so a particle that
  bounced far along the support is left outside instead of shrinking the pile;
* optionally an HTML page holding that film (``<video>`` with the MP4 as a
  data URI), which is what ``snakemake --report`` can show inline.

The encoder is the ``ffmpeg`` binary of the ``imageio-ffmpeg`` package, which
``make venv`` installs with the project; without it the command stops with a
message saying so, before anything is drawn. Both files are written
atomically, so a killed job never leaves half a film.
"""

from __future__ import annotations

import argparse
import base64
import html
import sys
import time
from pathlib import Path

import numpy as np

from sim.atomic import atomic_path

from .errors import InputError
from .netcdf import check_writable

#: Frames per second of the film by default.
FPS = 10

#: Lowest speed of the logarithmic colour scale, m/s: slower particles (the
#: pile at rest) take its colour, so that an avalanche of cm/s and a falling
#: particle of m/s both show.
SPEED_FLOOR = 1e-3

#: Width of the film in pixels (the height follows the pile's aspect ratio).
WIDTH_PX = 1280

FRAME_VARIABLES = ("time", "x", "y", "theta", "speed", "node_count", "node_x", "node_y")


def ffmpeg_executable() -> str:
    """Path of the ffmpeg binary that ``imageio-ffmpeg`` ships.

    Raises
    ------
    InputError
        If the package or its binary is missing.
    """
    try:
        import imageio_ffmpeg
        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:
        raise InputError(f"film: no ffmpeg to encode the film ({exc}); install the package "
                         "imageio-ffmpeg (make venv does, from pyproject.toml)") from None


def world_corners(x, y, theta, node_count, node_x, node_y) -> np.ndarray:
    """Corners of released particles in the lab frame, ``(n_nodes, 2)``, polygon after polygon.

    Parameters
    ----------
    x, y, theta : (n_particles,) arrays
        Centres (m) and orientations (rad) of one frame; NaN for particles not
        yet released.
    node_count : (n_particles,) int array
    node_x, node_y : (n_nodes,) arrays
        Body-frame corners, polygon after polygon (as in a state file).
    """
    owner = np.repeat(np.arange(len(node_count)), node_count)
    c, s = np.cos(theta[owner]), np.sin(theta[owner])
    return np.column_stack((x[owner] + c * node_x - s * node_y,
                            y[owner] + s * node_x + c * node_y))


def _polygons(corners, node_count, released):
    """The released particles' polygons as a list of ``(k, 2)`` arrays."""
    split = np.split(corners, np.cumsum(node_count)[:-1])
    return [split[p] for p in np.flatnonzero(released)]


#: Share of the pile's particles left beyond each edge of the picture's frame
#: (at least one particle each side): see :func:`film_extent`.
EDGE_SHARE = 0.005

#: Margin added on each side of the pile's robust width, as a fraction of it.
EDGE_MARGIN = 0.15


def film_extent(frames) -> tuple[float, float, float, float]:
    """Axis limits (m) that frame the pile, not its farthest stray particle.

    The frame is chosen from the bulk of the particles of the **last frame**
    (the poured pile; a pile only grows during a pour), so that one particle
    that bounced far along the support does not shrink the pile to a few
    pixels:

    * the pile's edges ``x_lo``, ``x_hi`` are the positions with a share
      :data:`EDGE_SHARE` (0.5 %) of its particles beyond each, and at least
      one particle, so a single stray is left out whatever the pile's size
      (from 3 particles on; with fewer every particle counts);
    * the horizontal half-width is the larger of ``|x_lo - m|`` and
      ``|x_hi + m|``, with the margin ``m`` = :data:`EDGE_MARGIN` (15 %) of
      ``x_hi - x_lo`` plus 1.5 times the largest circumradius ``r``; the frame
      is centred on the pouring axis x = 0;
    * the top is the highest centre, over all frames, of the particles inside
      that width, plus ``1.5 r``: it holds the pile and the particles falling
      onto it from the source, not a stray outside the frame;
    * the bottom is 5 % of the height below the support, which shows the
      support line.

    Particles outside the frame are not drawn (matplotlib clips them).

    Parameters
    ----------
    frames : xarray.Dataset
        A frames file (:func:`read_frames`).

    Returns
    -------
    x_lo, x_hi, y_lo, y_hi : float
        Axis limits, m.

    Raises
    ------
    InputError
        If no frame holds a released particle.
    """
    x, y = np.asarray(frames["x"].values, float), np.asarray(frames["y"].values, float)
    finite = np.isfinite(x) & np.isfinite(y)
    if not finite.any():
        raise InputError("film: the frames hold no released particle")
    r = 1.5 * float(np.sqrt(np.max(frames["node_x"].values ** 2 + frames["node_y"].values ** 2)))
    last = next(k for k in range(len(x) - 1, -1, -1) if finite[k].any())
    xs = np.sort(x[last][finite[last]])
    n = xs.size
    cut = max(1, int(EDGE_SHARE * n)) if n >= 3 else 0
    lo, hi = float(xs[cut]), float(xs[n - 1 - cut])
    margin = EDGE_MARGIN * (hi - lo) + r
    half = max(abs(lo - margin), abs(hi + margin))
    inside = finite & (np.abs(np.where(finite, x, 0.0)) <= half)
    y_hi = float(np.max(y[inside])) + r
    return -half, half, -0.05 * y_hi, y_hi


def read_frames(path: str, option: str = "--input"):
    """Open the frames file of a pour and check that it is one, with at least one frame.

    Parameters
    ----------
    path : str
        Frames file (``python -m sim pour --frames``; layout in
        docs/formats.md#frames-of-a-pour).
    option : str
        The command-line option that named it, for the error messages.

    Returns
    -------
    xarray.Dataset
        The frames, with the variables :data:`FRAME_VARIABLES`.

    Raises
    ------
    InputError
        If the file is missing, not netCDF, lacks a variable of
        :data:`FRAME_VARIABLES` or holds no frame; the message names the
        option, the file and what is expected.
    """
    from .netcdf import read_dataset

    what = "a frames file of a pour (python -m sim pour --frames, docs/formats.md#frames-of-a-pour)"
    if not Path(path).is_file():
        raise InputError(f"{option} {path}: no such file; expected {what}")
    try:
        ds = read_dataset(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"{option} {path}: cannot be read as netCDF ({exc}); expected {what}") from None
    missing = [name for name in FRAME_VARIABLES if name not in ds.variables]
    if missing:
        raise InputError(f"{option} {path}: not a frames file (missing {', '.join(missing)}); expected {what}")
    if ds.sizes.get("frame", 0) == 0:
        raise InputError(f"{option} {path}: holds no frame (frame dimension of length 0); expected {what} "
                         "with at least one frame")
    return ds


def render_film(frames_path: str, out: str, html_out: str | None = None, fps: int = FPS,
                title: str | None = None) -> dict:
    """Write the film of the frames in ``frames_path`` to ``out`` (.mp4), and its HTML page.

    Parameters
    ----------
    frames_path : str
        Frames file of a pour (``python -m sim pour --frames``).
    out : str
        The MP4 file.
    html_out : str, optional
        An HTML page with the film embedded (for ``snakemake --report``).
    fps : int
        Frames per second.
    title : str, optional
        Title over the film (default: protocol and seed of the frames file).

    Returns
    -------
    dict
        ``frames``, ``seconds`` (length of the film), ``wall_s`` (time to render)
        and ``bytes`` (size of the MP4).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import LogNorm

    if not (isinstance(fps, int) and fps > 0):
        raise InputError(f"film: fps = {fps!r}: must be a positive integer")
    ffmpeg = ffmpeg_executable()
    t0 = time.perf_counter()
    ds = read_frames(frames_path)
    counts = ds["node_count"].values.astype(int)
    nx, ny = ds["node_x"].values, ds["node_y"].values
    speed = ds["speed"].values
    finite = speed[np.isfinite(speed)]
    v_max = max(float(np.percentile(finite, 99)) if finite.size else 1.0, 10 * SPEED_FLOOR)
    x_lo, x_hi, y_lo, y_hi = film_extent(ds)
    height_px = 2 * round(0.5 * WIDTH_PX * (y_hi - y_lo) / (x_hi - x_lo) * 1.25 + 40)
    dpi = 100
    fig = plt.figure(figsize=(WIDTH_PX / dpi, height_px / dpi), dpi=dpi)
    ax = fig.add_axes((0.06, 0.1, 0.86, 0.78))
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.set_aspect("equal", adjustable="box")
    ax.axhline(0.0, color="0.3", lw=1.5)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    polys = PolyCollection([], cmap="viridis", edgecolors="0.2", linewidths=0.2,
                           norm=LogNorm(SPEED_FLOOR, v_max))
    ax.add_collection(polys)
    fig.colorbar(polys, ax=ax, fraction=0.025, pad=0.01, label="speed (m/s)", extend="both")
    if title is None and "protocol" in ds.attrs:
        title = f"{ds.attrs['protocol']} pile, seed {ds.attrs.get('seed', '?')}"
    name = title or Path(frames_path).name
    ax.set_title(name)
    clock = ax.text(0.01, 0.97, "", transform=ax.transAxes, va="top", family="monospace")
    times = ds["time"].values
    interval = float(ds.attrs.get("frame_interval", np.diff(times).mean() if len(times) > 1 else 1.0))
    plt.rcParams["animation.ffmpeg_path"] = ffmpeg
    writer = FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"],
                          metadata={"title": name})
    xs, ys, thetas = (ds[v].values for v in ("x", "y", "theta"))
    with atomic_path(out) as tmp:
        with writer.saving(fig, tmp, dpi):
            for k in range(len(times)):
                x, y, theta = xs[k], ys[k], thetas[k]
                released = np.isfinite(x)
                corners = world_corners(np.nan_to_num(x), np.nan_to_num(y),
                                        np.nan_to_num(theta), counts, nx, ny)
                polys.set_verts(_polygons(corners, counts, released))
                polys.set_array(speed[k][released])
                clock.set_text(f"t = {times[k]:6.2f} s   {int(released.sum()):5d} particles"
                               f"   ({interval * fps:.3g} s simulated per second)")
                writer.grab_frame()
        size = Path(tmp).stat().st_size
    plt.close(fig)
    if html_out:
        write_film_page(out, html_out, name)
    return {"frames": int(len(times)), "seconds": len(times) / fps,
            "wall_s": time.perf_counter() - t0, "bytes": int(size)}


def write_film_page(film: str, out: str, title: str) -> None:
    """An HTML page showing the MP4 ``film`` (embedded as a data URI), written atomically."""
    data = base64.b64encode(Path(film).read_bytes()).decode("ascii")
    page = (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title></head>\n<body style=\"margin:0\">\n"
        f"<video controls autoplay loop muted playsinline style=\"width:100%\" "
        f"title=\"{html.escape(title)}\" src=\"data:video/mp4;base64,{data}\"></video>\n"
        "</body></html>\n")
    with atomic_path(out) as tmp:
        Path(tmp).write_text(page)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``python -m analysis film``."""
    parser.add_argument("--input", required=True, help="frames file of a pour (python -m sim pour --frames)")
    parser.add_argument("--out", required=True, help="the film (.mp4)")
    parser.add_argument("--html", default=None, help="also an HTML page with the film embedded")
    parser.add_argument("--fps", type=int, default=FPS, help=f"frames per second (default {FPS})")


def cmd_film(args: argparse.Namespace, params: dict) -> None:
    """``python -m analysis film``; ``params`` is not used.

    Both outputs are checked writable first, so an unwritable ``--html`` no
    longer leaves the film without its page after the rendering.
    """
    for option, path in (("--out", args.out), ("--html", args.html)):
        if path:
            check_writable(path, option)
    info = render_film(args.input, args.out, args.html, args.fps)
    print(f"[analysis] film: {args.input} -> {args.out}: {info['frames']} frames, "
          f"{info['seconds']:.1f} s of film, {info['bytes'] / 1e6:.2f} MB, "
          f"rendered in {info['wall_s']:.1f} s", file=sys.stderr, flush=True)
