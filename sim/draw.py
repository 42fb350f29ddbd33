"""Pictures of particle states (`python -m sim draw`).

Reads a particle-state file of CONTRACT.md section 1 directly with xarray (no
simulator internals), so it draws any state that follows the contract:

* the polygons to scale (equal aspect), corners taken from the ragged
  body-frame arrays ``node_count``/``node_x``/``node_y``, rotated by ``theta``
  and moved to the centre of mass ``x``, ``y``;
* coloured by the particle pressure p = -(sigma_xx + sigma_yy)/2 (N/m), with
  sigma the particle stress of Eq. 2 of the paper,
  sigma_ij = 1/V sum_c x_i^c f_j^c (x^c branch vector from the centre of mass
  to the contact point, f^c the force acting on the particle). Compression
  is negative in sigma, so p > 0 under compression;
* optionally the contact-force network: a line between the centres of two
  particles in contact (from the centre to the contact point for the
  support), its width proportional to the magnitude of the contact force;
* the support, the line y = 0.

The file is written to a temporary name next to the target and renamed, so a
killed job never leaves half a picture.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = [
    "polygons_world",
    "particle_stress",
    "particle_pressure",
    "draw_state",
    "main",
]

# Variables of CONTRACT.md section 1 that the picture needs.
_NEEDED = (
    "x", "y", "theta", "area", "node_count", "node_x", "node_y",
    "contact_i", "contact_j", "contact_x", "contact_y", "force_x", "force_y",
)


def _check_contract(ds, path="<dataset>"):
    missing = [name for name in _NEEDED if name not in ds.variables]
    if missing:
        raise ValueError(
            f"{path}: not a particle-state file of CONTRACT.md section 1, "
            f"missing variables {missing}"
        )


def polygons_world(ds):
    """Corners of every particle in the world frame.

    Returns a list of (n_corners, 2) arrays, one per particle, from the
    contiguous ragged body-frame corners (``node_count``, ``node_x``,
    ``node_y``) rotated by ``theta`` and translated to (``x``, ``y``).
    """
    counts = np.asarray(ds["node_count"].values, dtype=np.int64)
    nx = np.asarray(ds["node_x"].values, dtype=float)
    ny = np.asarray(ds["node_y"].values, dtype=float)
    if counts.sum() != nx.size:
        raise ValueError(
            f"node_count sums to {counts.sum()} corners but node_x has {nx.size}"
        )
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    theta = np.asarray(ds["theta"].values, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    out = []
    for p, (a, n) in enumerate(zip(starts, counts)):
        bx, by = nx[a:a + n], ny[a:a + n]
        wx = x[p] + c[p] * bx - s[p] * by
        wy = y[p] + s[p] * bx + c[p] * by
        out.append(np.column_stack((wx, wy)))
    return out


def particle_stress(ds):
    """Particle stress tensors of Eq. 2, shape (n_particles, 2, 2), in N/m.

    sigma^p_ij = 1/V^p sum_c x_i^c f_j^c, summed over the contacts c of
    particle p, with x^c = (contact point) - (centre of mass of p) and f^c the
    force acting on p: ``force`` on ``contact_i``, ``-force`` on
    ``contact_j`` (``contact_j = -1`` is the support, which gets nothing).
    """
    n = ds.sizes["particle"]
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    area = np.asarray(ds["area"].values, dtype=float)
    ci = np.asarray(ds["contact_i"].values, dtype=np.int64)
    cj = np.asarray(ds["contact_j"].values, dtype=np.int64)
    px = np.asarray(ds["contact_x"].values, dtype=float)
    py = np.asarray(ds["contact_y"].values, dtype=float)
    fx = np.asarray(ds["force_x"].values, dtype=float)
    fy = np.asarray(ds["force_y"].values, dtype=float)

    moment = np.zeros((n, 2, 2))
    # Side i: the force as stored.
    branch = np.column_stack((px - x[ci], py - y[ci])) if ci.size else np.zeros((0, 2))
    force = np.column_stack((fx, fy)) if ci.size else np.zeros((0, 2))
    np.add.at(moment, ci, branch[:, :, None] * force[:, None, :])
    # Side j (particles only): the reaction.
    on_j = cj >= 0
    if np.any(on_j):
        j = cj[on_j]
        branch_j = np.column_stack((px[on_j] - x[j], py[on_j] - y[j]))
        force_j = -force[on_j]
        np.add.at(moment, j, branch_j[:, :, None] * force_j[:, None, :])
    return moment / area[:, None, None]


def particle_pressure(ds):
    """Particle pressure p = -(sigma_xx + sigma_yy)/2 in N/m (Eq. 2 stress);
    positive under compression."""
    sigma = particle_stress(ds)
    return -0.5 * (sigma[:, 0, 0] + sigma[:, 1, 1])


def _force_segments(ds):
    """Line segments of the force network and the force magnitudes."""
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    ci = np.asarray(ds["contact_i"].values, dtype=np.int64)
    cj = np.asarray(ds["contact_j"].values, dtype=np.int64)
    px = np.asarray(ds["contact_x"].values, dtype=float)
    py = np.asarray(ds["contact_y"].values, dtype=float)
    mag = np.hypot(np.asarray(ds["force_x"].values, dtype=float),
                   np.asarray(ds["force_y"].values, dtype=float))
    start = np.column_stack((x[ci], y[ci]))
    support = cj < 0
    jj = np.where(support, 0, cj)
    end = np.where(support[:, None], np.column_stack((px, py)),
                   np.column_stack((x[jj], y[jj])))
    return np.stack((start, end), axis=1), mag


def _atomic_savefig(fig, path_out, dpi):
    path_out = Path(path_out)
    path_out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path_out.name}.", suffix=".tmp",
                               dir=path_out.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            fig.savefig(handle, format=path_out.suffix.lstrip(".") or "png", dpi=dpi)
        os.replace(tmp, path_out)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def draw_state(path_in, path_out, color_by="pressure", forces=True, dpi=150):
    """Draw the particle state in `path_in` (CONTRACT.md section 1) to
    `path_out` (format from its suffix, e.g. .png).

    color_by: "pressure" (particle pressure of Eq. 2, N/m) or "none".
    forces: draw the contact-force network on top.
    """
    import xarray as xr
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    if color_by not in ("pressure", "none"):
        raise ValueError(f"color_by must be 'pressure' or 'none', not {color_by!r}")
    with xr.open_dataset(path_in) as ds:
        ds = ds.load()
    _check_contract(ds, path_in)

    polys = polygons_world(ds)
    corners = np.concatenate(polys) if polys else np.zeros((0, 2))
    if corners.size:
        xmin, ymin = corners.min(axis=0)
        xmax, ymax = corners.max(axis=0)
    else:
        xmin, xmax, ymin, ymax = -1e-2, 1e-2, 0.0, 1e-2
    ymin = min(ymin, 0.0)
    width = max(xmax - xmin, 1e-12)
    height = max(ymax - ymin, 1e-12)
    pad = 0.03 * max(width, height)

    fig_w = 10.0
    fig_h = min(max(3.0, fig_w * (height + 2 * pad) / (width + 2 * pad) + 2.0), 14.0)
    fig = Figure(figsize=(fig_w, fig_h), layout="constrained")
    ax = fig.add_subplot()

    coll = PolyCollection(polys, edgecolors="0.25", linewidths=0.3)
    extend = "neither"
    if color_by == "pressure":
        p = particle_pressure(ds)
        coll.set_array(p)
        coll.set_cmap("viridis")
        # Colour range: from min(0, lowest) to the highest value, or to the
        # 99th percentile in a pile of 100 particles or more, so that a single
        # impact does not wash out the pile.
        lo = min(0.0, float(np.min(p))) if p.size else 0.0
        hi = float(np.percentile(p, 99) if p.size >= 100 else np.max(p)) if p.size else 1.0
        if p.size and hi < float(np.max(p)):
            extend = "max"
        coll.set_clim(lo, hi if hi > lo else lo + 1.0)
    else:
        coll.set_facecolor("0.85")
    ax.add_collection(coll)

    if forces and ds.sizes.get("contact", 0) > 0:
        segments, mag = _force_segments(ds)
        fmax = float(mag.max()) if mag.size else 0.0
        if fmax > 0:
            lines = LineCollection(segments, linewidths=3.0 * mag / fmax,
                                   colors="crimson", alpha=0.8, capstyle="round")
            ax.add_collection(lines)

    # The support: its top surface is y = 0.
    ax.axhline(0.0, color="black", linewidth=1.5)
    ax.fill_between([xmin - pad, xmax + pad], -pad, 0.0, color="0.6",
                    hatch="///", linewidth=0)

    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(-pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")

    attrs = ds.attrs
    title = [f"{attrs.get('protocol', '?')} seed {attrs.get('seed', '?')}",
             Path(path_in).stem]
    if "time" in attrs:
        title.append(f"t = {float(attrs['time']):.4g} s")
    if "gravity" in attrs:
        title.append(f"g = {float(attrs['gravity']):.4g} m/s²")
    title.append(f"{ds.sizes['particle']} particles")
    ax.set_title(", ".join(title))
    if color_by == "pressure":
        fig.colorbar(coll, ax=ax, orientation="horizontal", shrink=0.5,
                     aspect=40, extend=extend,
                     label="particle pressure −(σxx+σyy)/2 [N/m] (Eq. 2)")

    _atomic_savefig(fig, path_out, dpi)


def main(argv=None):
    """Command line of `python -m sim draw`. Exits non-zero with a message on
    error; returns 0 on success."""
    parser = argparse.ArgumentParser(
        prog="python -m sim draw",
        description="Draw a particle-state file (CONTRACT.md section 1) as a picture.",
    )
    parser.add_argument("--input", required=True, help="particle-state file (.nc)")
    parser.add_argument("--out", required=True, help="picture to write (.png, .pdf, .svg)")
    parser.add_argument("--color-by", choices=("pressure", "none"), default="pressure",
                        help="colour particles by their Eq. 2 pressure, or not at all")
    parser.add_argument("--forces", action=argparse.BooleanOptionalAction, default=True,
                        help="draw the contact-force network (default: yes)")
    parser.add_argument("--dpi", type=int, default=150)
    args = parser.parse_args(argv)
    if not os.path.exists(args.input):
        raise SystemExit(f"draw: error: input file {args.input} does not exist")
    try:
        draw_state(args.input, args.out, color_by=args.color_by,
                   forces=args.forces, dpi=args.dpi)
    except (OSError, ValueError, KeyError) as err:
        raise SystemExit(f"draw: error: {args.input}: {err}") from err
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
