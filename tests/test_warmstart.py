"""The warm-started narrow phase (sim/warmstart.py) against the general kernel and shapely.

The witnesses are a speed-up, never an approximation: whatever witness a pair
carries (the right one, a stale one, random numbers), the warm-started kernel
either declines or returns the general kernel's contact geometry to rounding,
and a separating edge is only accepted where the polygons do not overlap.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from shapely.geometry import Polygon

from sim.geometry import OUT_SIZE, make_scratch, polygon_overlap, world_corners
from sim.shapes import make_shapes
from sim.warmstart import (axis_separates, find_axis, find_crossings,
                           overlap_from_crossings)

SHAPES = make_shapes(np.random.default_rng(11), 40)
SIZE = 2.0 * float(np.mean(SHAPES.radius))
EPS = 1e-9 * SIZE
SCRATCH = make_scratch(32)


@njit
def _warm(x, y, a0, a1, b0, b1, ca, cb, eps, out, cross):
    return overlap_from_crossings(x, y, a0, a1, b0, b1, ca[0], ca[1], cb[0], cb[1], eps, out,
                                  cross, 0)


@njit
def _witness(x, y, a0, a1, b0, b1, out, cross):
    find_crossings(x, y, a0, a1, b0, b1, out, cross, 0)


@njit
def _separates(x, y, a0, a1, b0, b1, axis):
    return axis_separates(x, y, a0, a1, b0, b1, axis)


@njit
def _axis(x, y, a0, a1, b0, b1):
    return find_axis(x, y, a0, a1, b0, b1)


def _pair(ia, ib, theta_a, theta_b, distance, direction):
    """World corners of shapes ia and ib, b's centre at ``distance`` from a's (m)."""
    def corners(k, x, y, theta):
        off = SHAPES.node_offset
        return world_corners(SHAPES.node_x[off[k]:off[k + 1]], SHAPES.node_y[off[k]:off[k + 1]],
                             x, y, theta)

    ca = np.array([0.0, 0.0])
    cb = distance * np.array([np.cos(direction), np.sin(direction)])
    ax, ay = corners(ia, *ca, theta_a)
    bx, by = corners(ib, *cb, theta_b)
    x = np.concatenate([ax, bx])
    y = np.concatenate([ay, by])
    return x, y, len(ax), ca, cb


def _general(x, y, na, ca, cb):
    out = np.full(OUT_SIZE, np.nan)
    hit = polygon_overlap(x[:na].copy(), y[:na].copy(), x[na:].copy(), y[na:].copy(), ca[0],
                          ca[1], cb[0], cb[1], EPS, out, SCRATCH)
    return hit, out


def _assert_same_contact(warm, general):
    """Area, contact points and normal agree to rounding (relative to the particle size)."""
    assert warm[0] == pytest.approx(general[0], rel=1e-9, abs=1e-12 * SIZE ** 2)
    np.testing.assert_allclose(warm[1:7], general[1:7], rtol=0, atol=1e-12 * SIZE)
    np.testing.assert_allclose(warm[7:9], general[7:9], rtol=0, atol=1e-9)
    assert warm[9] == pytest.approx(general[9], rel=0, abs=1e-12 * SIZE)


pairs = st.tuples(st.integers(0, 39), st.integers(0, 39), st.floats(0, 2 * np.pi),
                  st.floats(0, 2 * np.pi), st.floats(0.5, 1.05), st.floats(0, 2 * np.pi))


@settings(max_examples=150, deadline=None)
@given(pairs)
def test_witness_of_a_contact_reproduces_the_general_kernel(pair):
    """The witness found from a contact gives back that contact, to rounding (and shapely's area)."""
    ia, ib, ta, tb, dist, direction = pair
    x, y, na, ca, cb = _pair(ia, ib, ta, tb, dist * SIZE, direction)
    hit, general = _general(x, y, na, ca, cb)
    if not hit:
        return
    cross = np.full((1, 4), -1, np.int64)
    _witness(x, y, 0, na, na, len(x), general, cross)
    warm = np.full(OUT_SIZE, np.nan)
    if _warm(x, y, 0, na, na, len(x), ca, cb, EPS, warm, cross):
        _assert_same_contact(warm, general)
        exact = Polygon(np.c_[x[:na], y[:na]]).intersection(Polygon(np.c_[x[na:], y[na:]]))
        assert warm[0] == pytest.approx(exact.area, rel=1e-9, abs=1e-12 * SIZE ** 2)
    else:
        # only deep or degenerate overlaps are left to the general kernel
        assert general[0] > 0.05 * SIZE ** 2 or general[9] < 0.05 * SIZE


@settings(max_examples=150, deadline=None)
@given(pairs, st.lists(st.integers(0, 7), min_size=4, max_size=4))
def test_any_witness_either_declines_or_is_right(pair, witness):
    """A stale or arbitrary witness never yields a wrong overlap."""
    ia, ib, ta, tb, dist, direction = pair
    x, y, na, ca, cb = _pair(ia, ib, ta, tb, dist * SIZE, direction)
    cross = np.array([witness], np.int64)
    warm = np.full(OUT_SIZE, np.nan)
    if _warm(x, y, 0, na, na, len(x), ca, cb, EPS, warm, cross):
        hit, general = _general(x, y, na, ca, cb)
        assert hit
        _assert_same_contact(warm, general)


@settings(max_examples=150, deadline=None)
@given(pairs, st.integers(0, 15))
def test_a_separating_edge_is_accepted_only_where_there_is_no_overlap(pair, axis):
    ia, ib, ta, tb, dist, direction = pair
    x, y, na, ca, cb = _pair(ia, ib, ta, tb, dist * SIZE, direction)
    k, own = axis >> 1, axis & 1
    if k >= (na if own else len(x) - na):
        return
    if _separates(x, y, 0, na, na, len(x), axis):
        assert not _general(x, y, na, ca, cb)[0]
        assert Polygon(np.c_[x[:na], y[:na]]).intersection(
            Polygon(np.c_[x[na:], y[na:]])).area == pytest.approx(0.0, abs=1e-20)


@settings(max_examples=100, deadline=None)
@given(pairs)
def test_apart_polygons_get_a_separating_edge(pair):
    """Two polygons that do not touch always have a separating edge (convexity), which is found."""
    ia, ib, ta, tb, dist, direction = pair
    x, y, na, ca, cb = _pair(ia, ib, ta, tb, (dist + 1.0) * SIZE, direction)
    pa = Polygon(np.c_[x[:na], y[:na]])
    pb = Polygon(np.c_[x[na:], y[na:]])
    if pa.distance(pb) < 1e-6 * SIZE:
        return
    axis = _axis(x, y, 0, na, na, len(x))
    assert axis >= 0
    assert _separates(x, y, 0, na, na, len(x), axis)


def test_a_sliding_contact_keeps_its_witness_until_a_corner_passes():
    """Sliding b along a's edge: the witness of step k serves step k + 1 until the
    crossing moves to another edge; every accepted step matches the general kernel."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * SIZE
    tri = np.array([[0.0, 0.0], [0.3, -0.2], [0.3, 0.2]]) * SIZE  # corner (0,0) points left
    cross = np.full((1, 4), -1, np.int64)
    accepted = declined = 0
    for s in np.linspace(0.05, 1.5, 300):  # the contact ends at s = 1.26
        b = tri + np.array([0.98 * SIZE, s * SIZE * 0.8])
        x = np.concatenate([square[:, 0], b[:, 0]])
        y = np.concatenate([square[:, 1], b[:, 1]])
        ca = square.mean(axis=0)
        cb = b.mean(axis=0)
        hit, general = _general(x, y, 4, ca, cb)
        warm = np.full(OUT_SIZE, np.nan)
        if _warm(x, y, 0, 4, 4, 7, ca, cb, EPS, warm, cross):
            accepted += 1
            assert hit
            _assert_same_contact(warm, general)
        elif hit:
            declined += 1
            _witness(x, y, 0, 4, 4, 7, general, cross)
        else:
            cross[0, 0] = -1
    assert accepted > 240  # the witness holds for almost every step in contact
    assert 2 <= declined <= 4  # first contact; the crossing passes the corner (1, 1)
