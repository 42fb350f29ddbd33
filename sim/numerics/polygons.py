"""Hand-made polygons for test scenes: rectangles, diamonds, regular and
elongated polygons, and the :class:`sim.shapes.Shapes` of a list of them.

Corners are counter-clockwise and centred on the centroid, as
:func:`sim.shapes.shapes_from_nodes` requires.
"""

from __future__ import annotations

import numpy as np

from ..polygon import polygon_mass_properties
from ..shapes import shapes_from_nodes


def rectangle(w, h):
    """Corners of a w × h rectangle centred at the origin, counter-clockwise."""
    return np.array([-w / 2, w / 2, w / 2, -w / 2]), np.array([-h / 2, -h / 2, h / 2, h / 2])


def diamond(half_diagonal):
    """A square standing on a corner (corners on the axes)."""
    r = half_diagonal
    return np.array([0.0, r, 0.0, -r]), np.array([-r, 0.0, r, 0.0])


def regular_polygon(n, radius, phase=0.0):
    """Corners of a regular n-gon of circumradius ``radius``."""
    a = phase + 2 * np.pi * np.arange(n) / n
    return radius * np.cos(a), radius * np.sin(a)


def ellipse_polygon(n, semi_a, semi_b):
    """Corners of an n-gon inscribed in the ellipse of semi-axes ``semi_a`` (x), ``semi_b`` (y).

    The corners sit at the parameter angles ``2πk/n``, so the polygon is
    point-symmetric for even ``n`` and centred on its centroid then; for odd
    ``n`` it is shifted to its centroid.
    """
    a = 2 * np.pi * np.arange(n) / n
    x, y = semi_a * np.cos(a), semi_b * np.sin(a)
    return centred(x, y)


def centred(x, y):
    """The polygon ``(x, y)`` shifted so that its area centroid is the origin
    (centroid from :func:`sim.polygon.polygon_mass_properties`)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    _, cx, cy, _ = polygon_mass_properties(x, y)
    return x - cx, y - cy


def shapes_of(*polygons, density=2500.0):
    """:class:`sim.shapes.Shapes` of the given (x, y) corner arrays."""
    counts = np.array([len(p[0]) for p in polygons])
    return shapes_from_nodes(counts, np.concatenate([p[0] for p in polygons]),
                             np.concatenate([p[1] for p in polygons]), density)
