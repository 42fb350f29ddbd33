"""analysis/rve.py: RVE membership against a brute-force count, with
particles exactly on the RVE's edge (members) and below the support (never)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.rve import membership, rve_area

SIZE = 0.08


@st.composite
def particles(draw):
    """RVE centres and particle centres, many on an edge, some below y = 0."""
    centres = np.array([[0.0, 0.03], [0.05, 0.1], [-0.04, 0.0]])
    n = draw(st.integers(1, 30))
    offsets = st.sampled_from([-SIZE / 2, SIZE / 2, 0.0]) | st.floats(-0.06, 0.06)
    rows = [(draw(st.integers(0, 2)), draw(offsets), draw(offsets)) for _ in range(n)]
    px = np.array([centres[r, 0] + dx for r, dx, _ in rows])
    py = np.array([centres[r, 1] + dy for r, _, dy in rows])
    return centres, px, py


@settings(max_examples=200, deadline=None)
@given(particles())
def test_square_membership_is_inclusive_and_above_the_support(case):
    centres, px, py = case
    W = membership(centres, px, py, "square", SIZE).toarray()
    half = SIZE / 2 * (1 + 1e-12)
    inside = ((np.abs(px[None] - centres[:, :1]) <= half) &
              (np.abs(py[None] - centres[:, 1:]) <= half) & (py[None] >= 0))
    np.testing.assert_array_equal(W, inside.astype(float))


def test_an_edge_particle_belongs_and_one_below_the_support_does_not():
    centres = np.array([[0.0, 0.02]])
    px = np.array([SIZE / 2, 0.0, 0.0, 0.0])
    py = np.array([0.02, 0.02 + SIZE / 2, -1e-4, 0.0])
    W = membership(centres, px, py, "square", SIZE).toarray()
    np.testing.assert_array_equal(W, [[1.0, 1.0, 0.0, 1.0]])
    Wc = membership(centres, px, py, "circle", SIZE).toarray()
    np.testing.assert_array_equal(Wc, [[1.0, 1.0, 0.0, 1.0]])


def test_rve_area_is_clipped_at_the_support():
    assert rve_area(np.array([0.02]), "square", SIZE)[0] == SIZE * (0.02 + SIZE / 2)
    assert rve_area(np.array([0.0]), "circle", SIZE)[0] == pytest.approx(np.pi * (SIZE / 2) ** 2 / 2)
    assert rve_area(np.array([1.0]), "square", SIZE)[0] == SIZE ** 2
