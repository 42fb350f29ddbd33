"""The orientation's cosine and sine (sim.rotation) against numpy's libm."""

import math

import numpy as np
import pytest
from numba import njit

from sim.rotation import REDUCTION_LIMIT, cos_sin


@njit(cache=True)
def _cos_sin_many(theta):
    c = np.empty_like(theta)
    s = np.empty_like(theta)
    for i in range(theta.size):
        c[i], s[i] = cos_sin(theta[i])
    return c, s


def _ulps(ours, reference):
    return np.abs(ours - reference) / np.spacing(np.abs(reference))


@pytest.mark.parametrize("scale", [1.0, 10.0, 1000.0])
def test_within_one_ulp_of_libm_where_particles_turn(scale):
    theta = np.random.default_rng(1).uniform(-scale, scale, 400_000)
    c, s = _cos_sin_many(theta)
    assert _ulps(c, np.cos(theta)).max() <= 1.0
    assert _ulps(s, np.sin(theta)).max() <= 1.0
    # most values (84–92 % of these) are libm's to the last bit
    assert np.mean(c == np.cos(theta)) > 0.8
    assert np.mean(s == np.sin(theta)) > 0.8


def test_within_half_an_ulp_of_one_up_to_the_reduction_limit():
    theta = np.random.default_rng(2).uniform(-REDUCTION_LIMIT, REDUCTION_LIMIT, 400_000)
    c, s = _cos_sin_many(theta)
    assert np.abs(c - np.cos(theta)).max() <= 2.0 ** -53
    assert np.abs(s - np.sin(theta)).max() <= 2.0 ** -53
    assert np.abs(c * c + s * s - 1.0).max() <= 4 * 2.0 ** -53


def test_quadrant_boundaries_and_exact_values():
    # at the edges of the reduction's quadrants (odd multiples of π/4) and
    # on the axes, where the quadrant decides the signs
    k = np.arange(-40, 41)
    edges = k * (math.pi / 4)
    theta = np.concatenate([edges, np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf)])
    c, s = _cos_sin_many(theta)
    assert _ulps(c, np.cos(theta))[np.abs(np.cos(theta)) > 1e-3].max() <= 1.0
    assert _ulps(s, np.sin(theta))[np.abs(np.sin(theta)) > 1e-3].max() <= 1.0
    assert np.abs(c - np.cos(theta)).max() <= 2.0 ** -53
    assert np.abs(s - np.sin(theta)).max() <= 2.0 ** -53
    assert cos_sin(0.0) == (1.0, 0.0)
    assert cos_sin(1e-300) == (1.0, 1e-300)


def test_beyond_the_limit_and_non_finite_angles_are_libms():
    theta = np.array([REDUCTION_LIMIT * 1.01, -1e10, 3e300])
    c, s = _cos_sin_many(theta)
    np.testing.assert_array_equal(c, np.cos(theta))
    np.testing.assert_array_equal(s, np.sin(theta))
    c, s = _cos_sin_many(np.array([np.nan, np.inf, -np.inf]))
    assert np.isnan(c).all() and np.isnan(s).all()
