"""sim/measure.py: the angle of repose and the coordination number printed in
every run summary, against piles and contact lists of known answer."""

import numpy as np
import pytest

from sim.measure import angle_of_repose, mean_coordination, surface_profile


def triangle_pile(slope_deg, half_width=0.2, radius=2e-3, rng=None):
    """Discs filling a triangle of the given flank slope (a row every radius)."""
    rng = rng or np.random.default_rng(0)
    height = half_width * np.tan(np.radians(slope_deg))
    xs, ys = np.meshgrid(np.arange(-half_width, half_width, radius),
                         np.arange(radius, height, radius))
    inside = ys <= height * (1 - np.abs(xs) / half_width)
    x, y = xs[inside], ys[inside]
    x = x + rng.uniform(-0.1, 0.1, x.size) * radius
    return x, y, np.full(x.size, radius)


@pytest.mark.parametrize("slope", [20.0, 33.0, 40.0])
def test_angle_of_repose_of_a_triangular_pile_is_its_slope(slope):
    x, y, r = triangle_pile(slope)
    assert angle_of_repose(x, y, r) == pytest.approx(slope, abs=1.0)


def test_an_asymmetric_pile_gives_the_mean_of_its_flanks():
    x, y, r = triangle_pile(30.0)
    left = x < 0
    # stretch the left flank to half its slope
    y2 = np.where(left, y * 0.5, y)
    expected = 0.5 * (30.0 + np.degrees(np.arctan(0.5 * np.tan(np.radians(30.0)))))
    assert angle_of_repose(x, y2, r) == pytest.approx(expected, abs=1.0)


def test_too_few_particles_give_nan_not_a_number():
    x, y, r = triangle_pile(30.0)
    assert np.isnan(angle_of_repose(x[:9], y[:9], r[:9]))
    assert np.isnan(angle_of_repose(np.zeros(20), np.zeros(20), np.full(20, 1e-3)))


def test_surface_profile_is_the_highest_top_per_bin():
    x = np.array([0.001, 0.002, 0.011, 0.031])
    y = np.array([0.0, 0.004, 0.002, 0.001])
    centres, top = surface_profile(x, y, np.full(4, 1e-3), 0.01)
    np.testing.assert_allclose(centres, [0.005, 0.015, 0.025, 0.035])
    np.testing.assert_allclose(top[[0, 1, 3]], [0.005, 0.003, 0.002])
    assert np.isnan(top[2])


def test_coordination_counts_particle_pairs_twice_and_ignores_bodies():
    i = np.array([0, 0, 1, 2, 3])
    j = np.array([1, 2, 2, -1, -2])
    assert mean_coordination(i, j, 4) == pytest.approx(2 * 3 / 4)
    assert np.isnan(mean_coordination(i[:0], j[:0], 0))


def test_pile_summary_of_a_lattice_triangle():
    """A triangle of discs with 25° flanks on a support that carries its weight."""
    from sim.measure import pile_summary
    r = 1e-3
    slope = np.radians(25.0)
    xs, ys = [], []
    for row in range(40):
        y = r + row * r * np.sqrt(3.0)
        half = (0.2 - y) / np.tan(slope)
        x = np.arange(-half, half + 1e-12, 2 * r)
        xs.append(x)
        ys.append(np.full(len(x), y))
    pos = np.column_stack([np.concatenate(xs), np.concatenate(ys)])
    n = len(pos)
    radius = np.full(n, r)
    mass = np.full(n, 2e-3)
    base = np.flatnonzero(pos[:, 1] < 1.5 * r)
    fy = np.full(len(base), mass.sum() * 9.81 / len(base))
    out = pile_summary(pos, radius, mass, -9.81, base, np.full(len(base), -1), fy)
    assert out["particles"] == n
    assert out["height"] == pytest.approx(pos[:, 1].max() + r)
    # the profile's bins are one diameter wide: the width is known to a bin
    assert out["width"] == pytest.approx(np.ptp(pos[:, 0]) + 2 * r, abs=2 * r)
    assert out["flank_left_deg"] == pytest.approx(25.0, abs=1.5)
    assert out["flank_right_deg"] == pytest.approx(25.0, abs=1.5)
    assert out["support_reaction_over_weight_minus_1"] == pytest.approx(0.0, abs=1e-12)
    assert out["mean_coordination"] == 0.0
    # a particle that rolled far away over the bare support is not part of the width
    stray = pile_summary(np.vstack([pos, [1.0, r]]), np.append(radius, r),
                         np.append(mass, 2e-3), -9.81, base, np.full(len(base), -1), fy)
    assert stray["width"] == pytest.approx(out["width"])


def test_pile_summary_counts_the_rough_base_as_the_support():
    """A pile on a rough base rests on its polygons (``contact_j`` = -4 - b,
    docs/formats.md#state-files), with a few particles between them on the flat
    support: the reaction is the sum of both, the weight in static balance
    (issue 59, item 3: the base's contacts were left out, -1.0 of the weight).
    Walls (-2, -3) are no support."""
    from sim.measure import pile_summary
    n, r, m = 6, 1e-3, 2e-3
    pos = np.column_stack([np.arange(n) * 2 * r, np.full(n, 3 * r)])
    weight = n * m * 9.81
    i = np.array([0, 1, 2, 3, 4, 5, 5])
    j = np.array([-4, -5, -1, -6, -7, -9, -2])
    fy = np.array([0.2, 0.2, 0.1, 0.2, 0.2, 0.1, 0.5]) * weight
    out = pile_summary(pos, np.full(n, r), np.full(n, m), -9.81, i, j, fy)
    assert out["support_reaction_over_weight_minus_1"] == pytest.approx(0.0, abs=1e-12)
