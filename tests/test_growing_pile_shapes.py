"""workflow/tools/growing_pile_shapes.py: the particles in flight above a
growing pile do not count as its top."""


import numpy as np

from sim.measure import flank_angles

from workflow.tools import growing_pile_shapes as shapes


def test_a_particle_in_flight_is_not_in_contact_and_leaves_the_flanks_alone():
    """A triangle of discs with 30 deg flanks (each disc resting on the one
    below it, the bottom row on the support) and one disc falling above its apex:
    the mask keeps the triangle, whose flanks are 30 deg and whose top is the
    apex, 0.3 m x tan 30 deg, and drops the disc 5 cm above it."""
    r, slope = 0.002, np.tan(np.radians(30.0))
    xs = np.arange(-0.3, 0.3 + 1e-9, 2 * r)
    columns = [(x, y) for x in xs for y in np.arange(r, max(r, (0.3 - abs(x)) * slope) + 1e-12, 2 * r)]
    x, y = np.array(columns).T
    n = len(x) + 1
    x, y = np.append(x, 0.0), np.append(y, y.max() + 0.05)             # the falling disc, last
    radius = np.full(n, r)
    bottom = np.flatnonzero(y[:-1] < 1.5 * r)
    above = np.flatnonzero(y[:-1] >= 1.5 * r)
    contact_i = np.concatenate([bottom, above])
    contact_j = np.concatenate([np.full(len(bottom), -1), above - 1])   # each disc on the one below it
    touching = shapes.in_contact(n, contact_i, contact_j)
    assert touching[:-1].all() and not touching[-1]
    left, right = flank_angles(x[touching], y[touching], radius[touching])
    assert abs(left - 30.0) < 1.5 and abs(right - 30.0) < 1.5
    top = np.max(y[touching] + radius[touching])
    assert abs(top - 0.3 * slope) < 2 * r                               # the apex, not the falling disc
