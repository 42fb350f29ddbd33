"""Free surface of a pile and the depth of RVE centres below it.

The surface height at ``x`` is the highest polygon corner (lab frame) among
corners with ``|x_corner - x| <= window/2``; NaN where no corner is that
close (outside the pile). The depth of an RVE centre is
``surface_height(x) - y`` (negative above the surface).
"""

from __future__ import annotations

import numpy as np

from .states import State


def surface_height(state: State, x: np.ndarray, window: float) -> np.ndarray:
    """Free-surface height (m) above the support at each ``x``."""
    vx, vy, counts = state.world_vertices()
    valid = np.arange(vx.shape[1])[None, :] < counts[:, None]
    px, py = vx[valid], vy[valid]
    order = np.argsort(px)
    px, py = px[order], py[order]
    lo = np.searchsorted(px, np.asarray(x) - window / 2, side="left")
    hi = np.searchsorted(px, np.asarray(x) + window / 2, side="right")
    out = np.full(np.shape(x), np.nan)
    for k in np.flatnonzero(hi > lo):  # loop over grid columns, not particles
        out[k] = py[lo[k]:hi[k]].max()
    return out
