"""Macroscopic observables of a pile: surface profile, angle of repose, coordination.

These are cheap numpy reductions over a state, used for progress lines, run
summaries and the numerical-accuracy study.
"""

from __future__ import annotations

import numpy as np

from .scene import BODY_BASE, BODY_SUPPORT


def surface_profile(x, y, radius, bin_width):
    """Height of the free surface on a grid of x bins.

    Parameters
    ----------
    x, y, radius : numpy.ndarray
        Particle centres and circumradii, m.
    bin_width : float
        Width of the x bins, m.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Bin centres and the highest ``y + R`` of the particles whose centres
        fall in each bin (NaN for empty bins).
    """
    if len(x) == 0:
        return np.empty(0), np.empty(0)
    lo = np.floor(x.min() / bin_width) * bin_width
    idx = np.floor((x - lo) / bin_width).astype(np.int64)
    nb = int(idx.max()) + 1
    top = np.full(nb, -np.inf)
    np.maximum.at(top, idx, y + radius)
    top[~np.isfinite(top)] = np.nan
    return lo + (np.arange(nb) + 0.5) * bin_width, top


def flank_angles(x, y, radius, bin_width=None, band=(0.15, 0.75)):
    """Slope angles of the left and the right flank of a pile, in degrees.

    The surface profile (:func:`surface_profile`) is cut to heights between
    ``band[0]`` and ``band[1]`` of the pile height (leaving out the rounded
    tip and the foot), and a straight line is fitted to each flank (left of
    the highest bin, right of it).

    Returns
    -------
    (float, float)
        Left and right angle in degrees; NaN where a flank has fewer than 3
        bins (or the pile fewer than 10 particles).
    """
    if len(x) < 10:
        return float("nan"), float("nan")
    bin_width = bin_width or 2.0 * float(np.mean(radius))
    xc, top = surface_profile(x, y, radius, bin_width)
    ok = np.isfinite(top)
    xc, top = xc[ok], top[ok]
    h = top.max()
    k = int(np.argmax(top))
    angles = []
    for side in (slice(0, k + 1), slice(k, None)):
        xs, ts = xc[side], top[side]
        sel = (ts > band[0] * h) & (ts < band[1] * h)
        if sel.sum() < 3:
            angles.append(float("nan"))
            continue
        slope = np.polyfit(xs[sel], ts[sel], 1)[0]
        angles.append(float(np.degrees(np.arctan(abs(slope)))))
    return angles[0], angles[1]


def angle_of_repose(x, y, radius, bin_width=None, band=(0.15, 0.75)):
    """Mean of the two :func:`flank_angles` of a pile, in degrees (NaN if either is)."""
    return float(np.mean(flank_angles(x, y, radius, bin_width, band)))


def mean_coordination(contact_i, contact_j, n):
    """Mean number of particle–particle contacts per particle (support excluded)."""
    pair = contact_j >= 0
    if n == 0:
        return float("nan")
    return 2.0 * float(np.count_nonzero(pair)) / n


def pile_summary(position, radius, mass, gravity_y, contact_i, contact_j, contact_fy):
    """The shape of a pile and how its support carries it.

    Parameters
    ----------
    position : numpy.ndarray, shape (n, 2)
        Centres, m.
    radius, mass : numpy.ndarray, shape (n,)
        Circumradii (m) and masses (kg/m).
    gravity_y : float
        Vertical gravity, m/s² (negative).
    contact_i, contact_j, contact_fy : numpy.ndarray
        The contacts of the state (docs/formats.md#state-files): ``j = -1`` is
        the flat support, ``j <= -4`` a polygon of a rough base lying on it
        (both the support here), ``fy`` the vertical force on i.

    Returns
    -------
    dict
        ``particles``; ``height`` (m, the highest ``y + R``); ``width`` (m, the
        extent of the pile's surface profile (:func:`surface_profile`, bins
        of one mean diameter) without gaps around its top: particles that
        rolled away over the bare support are not counted);
        ``flank_left_deg``, ``flank_right_deg`` (:func:`flank_angles`);
        ``mean_coordination``; ``support_reaction_over_weight_minus_1``: the
        vertical force of the support and of a rough base on it on the pile,
        over its weight, minus 1 (0 in static balance without walls).
    """
    n = len(radius)
    x, y = position[:, 0], position[:, 1]
    bin_width = 2.0 * float(np.mean(radius))
    xc, top = surface_profile(x, y, radius, bin_width)
    lo = hi = int(np.nanargmax(top))
    while lo > 0 and np.isfinite(top[lo - 1]):
        lo -= 1
    while hi < len(top) - 1 and np.isfinite(top[hi + 1]):
        hi += 1
    left, right = flank_angles(x, y, radius)
    weight = float(np.sum(mass)) * abs(gravity_y)
    return {
        "particles": int(n),
        "height": float(np.max(y + radius)),
        "width": float(xc[hi] - xc[lo]) + bin_width,
        "flank_left_deg": left,
        "flank_right_deg": right,
        "mean_coordination": mean_coordination(contact_i, contact_j, n),
        "support_reaction_over_weight_minus_1":
            float(np.sum(contact_fy[(contact_j == BODY_SUPPORT) | (contact_j <= BODY_BASE)]))
            / weight - 1.0,
    }
