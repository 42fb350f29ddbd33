"""Where a pour releases its particles: the tip and top of the pile, the
target pile of the line source, the source's rate, speed and height
(:func:`source`), and whether the release spot is clear.

* **Wedge sequence (point source), ``point_source: drip``** (the default).
  Particles are released one at a time, every ``1/rate`` seconds, at ``x = 0``
  plus a uniform jitter of ``±jitter``, at ``release_height`` above the
  current tip of the pile (plus the particle's circumradius), moving down at
  ``release_speed``.
* **Wedge sequence, ``point_source: funnel``.**  A 2D hopper outlet of
  ``outlet_width`` mean particle diameters d (:func:`mean_diameter`), held
  ``outlet_height`` diameters above the rising top of the heap, its flowing
  layer included (:func:`heap_top`), and never in its own stream
  (:func:`above_stream`): the outlet sets the flux,
  that of the 2D Beverloo law (:func:`beverloo_rate`), and the release speed,
  that of the slowest stream that carries it (:func:`stream_speed`); the
  outlet is cut into :func:`outlet_slots` columns one largest particle wide,
  particle k falling in column ``k mod slots`` at a uniform place inside it.
  ``rate``, ``release_height``, ``release_speed`` and ``jitter`` are unused.
* **Layered sequence (line source), ``line_source: top``** (the default).
  The release point is uniform along a horizontal line at the same height.
  Its length follows the momentary width
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
* **Layered sequence, ``line_source: rain``.**  A rain over the plateau of the
  same target pile, growing layer by layer: the line spans the horizontal
  section of the target pile at the height where its lower part holds the
  particles released so far (:func:`rain_half_width`), whatever the pile's
  measured top, so the line narrows at the speed that builds flanks of
  ``layered_slope_deg``.

* **Layered sequence, ``line_source: table``.**  A rain, uniform over the
  whole of a table ``|x| <= W`` at every release (:func:`table_half_width`,
  from ``table_slope_deg``), as sand through a sieve as wide as the base: the
  particles that land on the plateau stay and lay it down in layers, those
  that land on a flank run down it, and a particle whose centre passes the
  table's edge has left it and is removed (parked by :mod:`sim.pour`), so the
  flanks end at the edge at the angle of repose.

A particle counts as *settled* when its speed is below 0.1 m/s and it touches
a particle or a body (:func:`touching`): one released slower than that is
still falling, and counted as settled it would raise the tip, and the next
release, above itself.  The tip is the highest ``y + R`` of settled particles
(0 on the bare support).  A release
waits while the release disc (radius ``R`` of the new particle) overlaps a
particle still in flight, so particles never start overlapping.

The release position of particle k comes from a generator seeded with
``(seed, 1, k)``, so a pour resumed from a checkpoint releases the same
particles at the same places as the uninterrupted one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import SimConfig

SETTLED_SPEED = 0.1

#: Solid fraction of the target pile of the line source and of the bulk
#: leaving the funnel (:func:`beverloo_rate`); the study's piles pack at about 0.8.
PILE_PACKING = 0.8

#: Discharge coefficient C and shape coefficient k of the 2D Beverloo law
#: (:func:`beverloo_rate`): C = 1.03 for slot orifices (Nedderman, *Statics and
#: kinematics of granular materials*, CUP 1992, ch. 10), k = 1.5 (Beverloo,
#: Leniger & van de Velde, Chem. Eng. Sci. 15, 260, 1961).
BEVERLOO_C = 1.03
BEVERLOO_K = 1.5


def _settled(sim):
    """Mask of the active particles slower than :data:`SETTLED_SPEED` that touch
    a particle or a body (:func:`touching`)."""
    v = sim.velocity
    return (np.hypot(v[:, 0], v[:, 1]) < SETTLED_SPEED) & touching(sim)


def pile_top(sim, among=None):
    """Height of the tip: the highest y + R of the settled particles (0 when
    none), of those `among` (a mask, default all: a table's pile leaves out
    the particles parked off the table, :func:`on_table`)."""
    if sim.n == 0:
        return 0.0
    s = _settled(sim) if among is None else _settled(sim) & among
    if not s.any():
        return 0.0
    return float(np.max(sim.position[s, 1] + sim.shapes.radius[:sim.n][s]))


def touching(sim):
    """Mask of the active particles in contact with a particle or a body (support, walls)."""
    return sim.touching()


def heap_top(sim, on):
    """Height of the heap's top, its flowing layer included: the highest
    ``y + R`` of the particles `on` the heap (:func:`touching`; 0 when none),
    so that a particle falling free from the source does not count."""
    if not on.any():
        return 0.0
    return float(np.max(sim.position[:sim.n][on, 1] + sim.shapes.radius[:sim.n][on]))


def above_stream(sim, free, x, y, radius):
    """Height (≥ `y`) at which a disc of `radius` at `x` lies above every
    `free` particle (not touching anything) whose circumdisc spans `x` within
    `radius`: the outlet never releases into its own stream when the heap's
    top, and with it the outlet, drops by a contact lost."""
    pos = sim.position[:sim.n]
    reach = sim.shapes.radius[:sim.n] + radius
    below = free & (np.abs(pos[:, 0] - x) < reach)
    if not below.any():
        return y
    return max(y, float(np.max(pos[below, 1] + reach[below])))


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

    Its area is their total area over a solid fraction of
    :data:`PILE_PACKING`; its flanks rise at ``slope_deg``.
    """
    area = float(np.sum(shapes.area)) / PILE_PACKING
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


@dataclass(frozen=True)
class Source:
    """What a pour's source does, whatever the pile.

    Attributes
    ----------
    rate : float
        Releases per second.
    speed : float
        Downward speed of a released particle, m/s.
    elevation : float
        Height of the release point above the tip of the pile (plus the
        particle's circumradius), m.
    origin : tuple of str
        The settings that give rate, speed and elevation, for messages.
    """

    rate: float
    speed: float
    elevation: float
    origin: tuple


def mean_diameter(shapes):
    """Mean circumdiameter d of the particles (m), the unit of the funnel's settings."""
    return 2.0 * float(np.mean(shapes.radius))


def beverloo_rate(shapes, outlet_width, gravity):
    """Particles per second through a 2D outlet, by the 2D Beverloo law.

    The mass flux per unit time of a slot of width D in a plane is
    ``W = C ρ_b sqrt(g) (D − k d)^{3/2}`` (Beverloo et al. 1961; the 2D form
    of Nedderman 1992, ch. 10), with ``ρ_b`` the bulk density (particle
    density times :data:`PILE_PACKING`), C = :data:`BEVERLOO_C` and
    k = :data:`BEVERLOO_K`.  Divided by the mean particle mass, it is
    ``C φ sqrt(g) (D − k d)^{3/2} / ā`` particles per second.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
    outlet_width : float
        D in mean diameters d (:func:`mean_diameter`), more than k.
    gravity : float
        g, m/s².
    """
    d = mean_diameter(shapes)
    return (BEVERLOO_C * PILE_PACKING * math.sqrt(gravity)
            * ((outlet_width - BEVERLOO_K) * d) ** 1.5 / float(np.mean(shapes.area)))


def outlet_slots(shapes, outlet_width):
    """Number of columns, each as wide as the largest particle, across the outlet (at least 1)."""
    width = outlet_width * mean_diameter(shapes)
    return max(1, int(width // (2.0 * float(np.max(shapes.radius)))))


def stream_speed(shapes, outlet_width, rate):
    """Release speed (m/s) of the funnel's stream: the slowest at which it carries `rate`.

    Particle k falls in column ``k mod slots`` (:func:`outlet_slots`), so a
    column receives a particle every ``slots / rate`` seconds; moving at
    ``2 R_max rate / slots`` its predecessor (accelerated by gravity since)
    is more than a largest diameter below when it comes, and the release
    never waits for a clear spot in the free stream.
    """
    return 2.0 * float(np.max(shapes.radius)) * rate / outlet_slots(shapes, outlet_width)


def funnel(cfg: SimConfig, protocol):
    """Whether a pour of `protocol` under `cfg` pours from the funnel."""
    return protocol == "wedge" and cfg.pour.point_source == "funnel"


def source(cfg: SimConfig, shapes, protocol, gravity):
    """The :class:`Source` of a pour of `protocol`: the funnel's
    (:func:`beverloo_rate`, :func:`stream_speed`, ``outlet_height`` d) for a
    wedge pour with ``pour.point_source: funnel``, else ``rate``,
    ``release_speed`` and ``release_height`` as set."""
    p = cfg.pour
    if funnel(cfg, protocol):
        rate = beverloo_rate(shapes, p.outlet_width, gravity)
        speed = stream_speed(shapes, p.outlet_width, rate)
        elevation = p.outlet_height * mean_diameter(shapes)
        return Source(rate, speed, elevation,
                      (f"the Beverloo rate {rate:.4g}/s of pour.outlet_width = "
                       f"{p.outlet_width!r} diameters",
                       f"pour.outlet_width = {p.outlet_width!r} diameters (its stream falls at {speed:.3g} m/s)",
                       f"pour.outlet_height = {p.outlet_height!r} diameters ({elevation:.3g} m)"))
    return Source(p.rate, p.release_speed, p.release_height,
                  (f"pour.rate = {p.rate!r}/s", f"pour.release_speed = {p.release_speed!r} m/s",
                   f"pour.release_height = {p.release_height!r} m"))


def table_half_width(shapes, slope_deg):
    """Half-width W of the table of ``line_source: table`` (m).

    The half base of a triangular pile with flanks at `slope_deg` holding
    half the area of all the particles at a solid fraction of
    :data:`PILE_PACKING` (:func:`target_pile` of half of them).  A rain over
    the table sheds what lands on the flanks, so with the pile's flanks at
    the slope θ the plateau catches ``2 (W − h / tan θ)`` of the rain per unit
    length at height h, which is exactly ``dA/dh`` of the pile's area A(h):
    the plateau rises at the rain's rate, and the pile reaches its apex when
    ``2 W H``, twice its area, has been released.
    """
    return target_pile(shapes, slope_deg)[0] / math.sqrt(2.0)


def table(cfg: SimConfig, shapes, protocol):
    """The half-width of the table of a pour of `protocol` under `cfg` with
    the particles `shapes` (:func:`table_half_width`) for ``line_source:
    table``, else None."""
    if protocol != "layered" or cfg.pour.line_source != "table":
        return None
    return table_half_width(shapes, cfg.pour.table_slope_deg)


def on_table(sim, half_width):
    """Mask of the active particles whose centre lies on the table ``|x| <= half_width``."""
    return np.abs(sim.position[:, 0]) <= half_width


def rain_half_width(shapes, slope_deg, k):
    """Half-length of the rain's line when particle k is released (m).

    The target pile (:func:`target_pile`, half base L, height H) filled up to
    height h holds the fraction ``f = 1 − (1 − h/H)²`` of its area, and its
    section there is ``L (1 − h/H)`` wide on each side: released over
    ``L sqrt(1 − f_k)``, with ``f_k`` the area of particles 0 to k−1 over
    that of all, the particles fill the target pile from the base up, each
    layer on the plateau of the one before.
    """
    half, _ = target_pile(shapes, slope_deg)
    area = shapes.area
    filled = float(np.sum(area[:k])) / float(np.sum(area))
    return half * math.sqrt(max(1.0 - filled, 0.0))


def _point_span(sim, cfg: SimConfig, k):
    """Horizontal range ``(lo, hi)`` of the point source for particle k."""
    p = cfg.pour
    if p.point_source == "drip":
        return -p.jitter, p.jitter
    width = p.outlet_width * mean_diameter(sim.shapes)
    slots = outlet_slots(sim.shapes, p.outlet_width)
    left = -0.5 * width + (k % slots) * width / slots
    room = max(0.5 * width / slots - float(sim.shapes.radius[k]), 0.0)
    centre = left + 0.5 * width / slots
    return centre - room, centre + room


def _line_span(sim, cfg: SimConfig, k, top):
    """Horizontal range ``(lo, hi)`` of the line source for particle k under a tip at `top`."""
    p = cfg.pour
    radius = float(sim.shapes.radius[k])
    if p.line_source == "table":
        half = table_half_width(sim.shapes, p.table_slope_deg)
        return -half, half
    if p.line_source == "rain":
        half = max(rain_half_width(sim.shapes, p.layered_slope_deg, k), radius)
        return -half, half
    half, height = target_pile(sim.shapes, p.layered_slope_deg)
    bound = max(half * (1.0 - top / height), radius)
    extent = top_width(sim, p.top_band)
    lo, hi = (-bound, bound) if extent is None else extent
    lo = max(lo - p.line_margin, -bound)
    hi = min(hi + p.line_margin, bound)
    if hi <= lo:
        lo, hi = -bound, bound
    return lo, hi


#: Places a line source draws for one particle before it waits for a clear
#: spot (:func:`release_point`): a line lays its particles anywhere along it,
#: so a spot taken by a particle still falling is a cost, not physics.
LINE_DRAWS = 8


def release_point(sim, cfg: SimConfig, protocol, seed, k, draws=1):
    """Where particle k would be released now: ``draws`` candidates ``(x, y)``
    to try in order, the first one drawn from a generator seeded with
    ``(seed, 1, k)`` and draw ``a > 0`` from one seeded with ``(seed, 1, k, a)``.

    With side walls the point lies at least one circumradius inside them.
    """
    radius = float(sim.shapes.radius[k])
    on = touching(sim) if funnel(cfg, protocol) else None
    half = table(cfg, sim.shapes, protocol)
    top = (heap_top(sim, on) if on is not None
           else pile_top(sim, None if half is None else on_table(sim, half)))
    elevation = source(cfg, sim.shapes, protocol, float(np.hypot(*sim.gravity))).elevation
    y = top + elevation + radius
    lo, hi = _point_span(sim, cfg, k) if protocol == "wedge" else _line_span(sim, cfg, k, top)
    if sim.walls is not None:
        lo = min(max(lo, sim.walls[0] + radius), sim.walls[1] - radius)
        hi = max(min(hi, sim.walls[1] - radius), lo)
    points = []
    for a in range(draws):
        x = np.random.default_rng([seed, 1, k] if a == 0 else [seed, 1, k, a]).uniform(lo, hi)
        points.append((x, y if on is None else above_stream(sim, ~on, x, y, radius)))
    return points


def spot_clear(sim, x, y, radius):
    """Whether a disc of `radius` at (x, y) is clear of every active particle's circumdisc."""
    if sim.n == 0:
        return True
    pos = sim.position
    reach = sim.shapes.radius[:sim.n] + radius
    return bool(np.all(np.hypot(pos[:, 0] - x, pos[:, 1] - y) > reach))


