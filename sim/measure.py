"""Macroscopic observables of a pile: surface profile, angle of repose, coordination.

These are cheap numpy reductions over a state, used for progress lines, run
summaries and the numerical-accuracy study.
"""

from __future__ import annotations

import numpy as np


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


def angle_of_repose(x, y, radius, bin_width=None, band=(0.15, 0.75)):
    """Mean slope angle of the two flanks of a pile, in degrees.

    The surface profile (:func:`surface_profile`) is cut to heights between
    ``band[0]`` and ``band[1]`` of the pile height (leaving out the rounded
    tip and the foot), a straight line is fitted to each flank (left of the
    highest bin, right of it) and the mean of the two angles is returned.

    Returns
    -------
    float
        Angle in degrees, or NaN when a flank has fewer than 3 bins.
    """
    if len(x) < 10:
        return float("nan")
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
            return float("nan")
        slope = np.polyfit(xs[sel], ts[sel], 1)[0]
        angles.append(np.degrees(np.arctan(abs(slope))))
    return float(np.mean(angles))


def mean_coordination(contact_i, contact_j, n):
    """Mean number of particle–particle contacts per particle (support excluded)."""
    pair = contact_j >= 0
    if n == 0:
        return float("nan")
    return 2.0 * float(np.count_nonzero(pair)) / n
