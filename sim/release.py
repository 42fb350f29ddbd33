"""Where a pour releases its particles: the tip and top of the pile, the
target pile of the line source, and whether the release spot is clear.

* **Wedge sequence (point source).**  Particles are released one at a time,
  every ``1/rate`` seconds, at ``x = 0`` plus a uniform jitter of
  ``±jitter``, at ``release_height`` above the current tip of the pile (plus
  the particle's circumradius), moving down at ``release_speed``.
* **Layered sequence (line source).**  The release point is uniform along a
  horizontal line at the same height.  Its length follows the momentary width
  of the pile's top: the horizontal extent (centre ± circumradius) of the
  settled particles whose tops lie within ``top_band`` of the highest one,
  plus ``line_margin`` on each side.  It is also kept within the flanks of a
  triangular pile of slope ``layered_slope_deg`` (20° by default, below the
  angle of repose) whose area is that of all the particles at a solid fraction
  of 0.8: at top height h the line's half-length is at most
  ``(H − h) / tan(slope)`` with H that pile's height.  Over the bare support
  the line spans the full base of that pile, so the first layer covers the
  base of the final pile and every later layer is narrower: the pile grows
  layer by layer without avalanches and its slope stays below the angle of
  repose.

A particle counts as *settled* when its speed is below 0.1 m/s; the tip is the
highest ``y + R`` of settled particles (0 on the bare support).  A release
waits while the release disc (radius ``R`` of the new particle) overlaps a
particle still in flight, so particles never start overlapping.

The release position of particle k comes from a generator seeded with
``(seed, 1, k)``, so a pour resumed from a checkpoint releases the same
particles at the same places as the uninterrupted one.
"""

from __future__ import annotations

import math

import numpy as np

from .config import SimConfig

SETTLED_SPEED = 0.1


def _settled(sim):
    """Mask of the active particles slower than :data:`SETTLED_SPEED`."""
    v = sim.velocity
    return np.hypot(v[:, 0], v[:, 1]) < SETTLED_SPEED


def pile_top(sim):
    """Height of the tip (highest y + R of settled particles; 0 when none)."""
    if sim.n == 0:
        return 0.0
    s = _settled(sim)
    if not s.any():
        return 0.0
    return float(np.max(sim.position[s, 1] + sim.shapes.radius[:sim.n][s]))


def top_width(sim, band):
    """Extent ``(x_left, x_right)`` of the settled particles near the top, or None."""
    if sim.n == 0:
        return None
    s = _settled(sim)
    if not s.any():
        return None
    pos = sim.position[s]
    rad = sim.shapes.radius[:sim.n][s]
    top = pos[:, 1] + rad
    near = top > top.max() - band
    return float(np.min(pos[near, 0] - rad[near])), float(np.max(pos[near, 0] + rad[near]))


def target_pile(shapes, slope_deg):
    """Half base width and height of a triangular pile of all the particles.

    Its area is their total area over a solid fraction of 0.8; its flanks rise
    at ``slope_deg``.
    """
    area = float(np.sum(shapes.area)) / 0.8
    slope = math.tan(math.radians(slope_deg))
    half = math.sqrt(area / slope)
    return half, half * slope


#: Solid fraction below which no pile of polygons packs (:func:`pile_height_bound`);
#: the study's piles pack at about 0.8.
LOOSEST_PACKING = 0.5

#: Slope in degrees above which no flank of a poured pile stands
#: (:func:`pile_height_bound`); the study's angles of repose are 20 to 30°.
STEEPEST_FLANK = 45.0


def pile_height_bound(shapes, walls=None):
    """A height (m) that no pile of these particles reaches.

    The taller of a triangular pile of all the particles at
    :data:`LOOSEST_PACKING` with flanks at :data:`STEEPEST_FLANK` and, between
    side walls, a column as wide as they are apart at that packing.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
    walls : tuple of float, optional
        ``(x_left, x_right)``, m.
    """
    area = float(np.sum(shapes.area)) / LOOSEST_PACKING
    height = math.sqrt(area * math.tan(math.radians(STEEPEST_FLANK)))
    if walls is not None:
        height = max(height, area / (walls[1] - walls[0]))
    return height


def release_point(sim, cfg: SimConfig, protocol, seed, k):
    """Where particle k would be released now, as ``(x, y)``.

    With side walls the point lies at least one circumradius inside them.
    """
    rng = np.random.default_rng([seed, 1, k])
    radius = float(sim.shapes.radius[k])
    top = pile_top(sim)
    y = top + cfg.pour.release_height + radius
    if protocol == "wedge":
        lo, hi = -cfg.pour.jitter, cfg.pour.jitter
    else:
        half, height = target_pile(sim.shapes, cfg.pour.layered_slope_deg)
        bound = max(half * (1.0 - top / height), radius)
        extent = top_width(sim, cfg.pour.top_band)
        lo, hi = (-bound, bound) if extent is None else extent
        lo = max(lo - cfg.pour.line_margin, -bound)
        hi = min(hi + cfg.pour.line_margin, bound)
        if hi <= lo:
            lo, hi = -bound, bound
    if sim.walls is not None:
        lo = min(max(lo, sim.walls[0] + radius), sim.walls[1] - radius)
        hi = max(min(hi, sim.walls[1] - radius), lo)
    return rng.uniform(lo, hi), y


def spot_clear(sim, x, y, radius):
    """Whether a disc of `radius` at (x, y) is clear of every active particle's circumdisc."""
    if sim.n == 0:
        return True
    pos = sim.position
    reach = sim.shapes.radius[:sim.n] + radius
    return bool(np.all(np.hypot(pos[:, 0] - x, pos[:, 1] - y) > reach))


