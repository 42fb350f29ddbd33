"""How a pile grew, read from the frames of its pour (``python -m sim pour --frames``).

The film's frames (``results/README.md``: time, particles released, centre
and speed of every released particle) say, frame by frame, how steep the
flanks stood and how many particles of the pile were moving.  Used by the
table of the sources (``workflow/tools/source_growth.py``) and by the
calibration records (``workflow/tools/calibration.py``), whose numbers of the
growth are :func:`growth_statistics`.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

#: Seconds after its release from which a moving particle counts as the pile's.
OLD = 0.5
#: Particles of the pile (released more than :data:`OLD` s before) moving in one frame, from which its
#: flanks flow (:func:`growth_statistics`).
FLOW_MIN = 5
#: The growth: frames from this fraction of the particles released to the last release (:func:`growth`'s
#: ``start`` in the calibration records).
START = 0.3


def flank_angle(x, top_y, d):
    """Mean flank slope in degrees of a surface given by particle tops, or NaN.

    The surface is the highest top in bins one mean diameter wide; on each
    side of ``x = 0`` a straight line is fitted where it lies between 20 %
    and 80 % of the tip's height (at least three bins), and the angles of
    both sides are averaged.

    Parameters
    ----------
    x, top_y : ndarray
        Centre x and top (``y + R``) of the settled particles, m.
    d : float
        Bin width, m (a mean particle diameter).
    """
    bins = np.floor(x / d).astype(int)
    edges = np.unique(bins)
    h = np.array([top_y[bins == b].max() for b in edges])
    xc = (edges + 0.5) * d
    tip = h.max()
    angles = []
    for side in (xc < 0, xc > 0):
        use = side & (h > 0.2 * tip) & (h < 0.8 * tip)
        if use.sum() < 3:
            continue
        slope = np.polyfit(xc[use], h[use], 1)[0]
        angles.append(math.degrees(math.atan(abs(slope))))
    return float(np.mean(angles)) if angles else math.nan


def growth(frames, radius, d, start, settled_speed):
    """Per frame of the growth, one row: time, released, flank angle, moving
    particles, moving particles released more than :data:`OLD` s before.

    Parameters
    ----------
    frames : path-like
        The frames file of the pour.
    radius : ndarray
        Circumradius of each particle of the pour, m.
    d : float
        A mean particle diameter, m (the surface's bin width).
    start : float
        The growth's first frame: the first with this fraction of the
        particles released (its last: the last before all are).
    settled_speed : float
        Speed (m/s) below which a particle counts as settled
        (``sim.release.SETTLED_SPEED``); the moving particles are the faster
        ones whose centre lies below the tip of the settled ones.

    Returns
    -------
    ndarray, shape (frames, 5)
    """
    with xr.open_dataset(frames) as ds:
        t, released = ds.time.values, ds.released.values
        x, y, speed = ds.x.values, ds.y.values, ds.speed.values
    n = x.shape[1]
    seen = np.isfinite(x)
    released_at = np.where(seen.any(axis=0), t[np.argmax(seen, axis=0)], np.inf)
    rows = []
    for f in range(len(t)):
        if released[f] < start * n or released[f] >= n:
            continue
        on = np.isfinite(x[f])
        settled = on & (speed[f] < settled_speed)
        if not settled.any():
            continue
        tops = y[f] + radius
        tip = tops[settled].max()
        moving = on & (speed[f] >= settled_speed) & (y[f] < tip)
        rows.append((t[f], released[f], flank_angle(x[f][settled], tops[settled], d),
                     int(moving.sum()), int((moving & (released_at < t[f] - OLD)).sum())))
    return np.array(rows)


def growth_statistics(g: np.ndarray, flow_min: int = FLOW_MIN) -> dict:
    """How a pile grew, in the numbers of a calibration record, from its growth's frames.

    :data:`OLD`, :data:`FLOW_MIN` and :data:`START` were fixed, and committed,
    before the first calibration pile was poured.

    Parameters
    ----------
    g : ndarray, shape (frames, 5)
        :func:`growth` of the pile's frames.
    flow_min : int
        Old particles moving from which the flanks flow.

    Returns
    -------
    dict
        ``frames``; ``flow_fraction``: the fraction of the frames in which the
        flanks flow (at least `flow_min` old particles moving: an avalanche,
        not a particle landing); ``old_moving_median`` and ``old_moving_max``;
        ``moving_median`` (all moving particles); the flank angle's median,
        90th percentile and largest (deg, frames with an angle); and
        ``flux_per_s``, the particles released per second over the growth.
    """
    angle = g[np.isfinite(g[:, 2]), 2]
    old = g[:, 4]
    return {"frames": int(len(g)), "flow_fraction": float(np.mean(old >= flow_min)),
            "old_moving_median": float(np.median(old)), "old_moving_max": int(old.max()),
            "moving_median": float(np.median(g[:, 3])),
            "flank_median_deg": float(np.median(angle)), "flank_p90_deg": float(np.percentile(angle, 90)),
            "flank_max_deg": float(angle.max()),
            "flux_per_s": float((g[-1, 1] - g[0, 1]) / (g[-1, 0] - g[0, 0]))}


#: Quantiles of the landing-to-rest distance a record keeps (:func:`landing_displacement`).
DISTANCE_QUANTILES = (0.25, 0.5, 0.75, 0.9)


def landing_displacement(frames, x_rest, y_rest, d) -> dict:
    """How far the particles moved from where they landed to where they rest.

    A pile laid down in place (each layer where it falls, as the paper's
    layered piles are built) keeps its particles near their landing points;
    a pile built by avalanches carries them down its flanks.  The landing
    is where a particle first touched the pile (``landing_x``,
    ``landing_y`` of the frames file, :mod:`sim.frames`), the rest its centre
    in the relaxed pile; the distance is measured in mean diameters `d`.

    Parameters
    ----------
    frames : path-like
        The frames file of the pour (with its landing variables).
    x_rest, y_rest : ndarray
        Centre of every particle of the pile at rest (the relaxed state), m;
        of a pile on a table (``pour.line_source: table``) those it kept, the
        particles of the frames' last frame, in release order.
    d : float
        A mean particle diameter, m.

    Returns
    -------
    dict
        ``interior_share``: the share of the landed particles resting within
        one diameter of their landing point; ``within_2d``: within two;
        ``distance_qXX``: the quantiles :data:`DISTANCE_QUANTILES` of the
        distance (diameters); ``landed``: how many particles landed.

    Raises
    ------
    ValueError
        If the frames file has no landing variables (made before they
        existed), or its particles are not those at rest.
    """
    with xr.open_dataset(frames) as ds:
        if "landing_x" not in ds:
            raise ValueError(f"{frames}: no landing_x/landing_y (a frames file made before "
                             "landings were recorded); pour the pile again")
        lx, ly = ds["landing_x"].values, ds["landing_y"].values
        last = ds["x"].values[-1] if ds.sizes["frame"] else np.full(lx.shape, np.nan)
    x_rest, y_rest = np.asarray(x_rest, float), np.asarray(y_rest, float)
    if lx.shape != x_rest.shape and np.isfinite(last).sum() == x_rest.size:
        # a pile on a table: the state keeps, in release order, the particles of the last frame
        kept = np.isfinite(last)
        lx, ly = lx[kept], ly[kept]
    if lx.shape != x_rest.shape:
        raise ValueError(f"{frames}: {lx.size} particles landed, {x_rest.size} at rest: "
                         "not the same pile")
    landed = np.isfinite(lx)
    dist = np.hypot(x_rest - lx, y_rest - ly)[landed] / d
    out = {"landed": int(landed.sum()),
           "interior_share": float(np.mean(dist <= 1.0)) if dist.size else math.nan,
           "within_2d": float(np.mean(dist <= 2.0)) if dist.size else math.nan}
    for q in DISTANCE_QUANTILES:
        out[f"distance_q{round(100 * q)}"] = float(np.quantile(dist, q)) if dist.size else math.nan
    return out
