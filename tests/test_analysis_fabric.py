"""Fabric tensor (Eqs 10–12) of lattices with known contact geometry, and the angle convention."""

import numpy as np
import pytest
from synthetic_states import as_state, hex_lattice, make_state, square_lattice, square_nodes

from analysis.fabric import deviatoric_fraction, fabric_trace, particle_fabric, rve_fabric
from analysis.orientation import axis_angle_difference, axis_angle_from_vertical
from analysis.rve import membership

A = 0.007


def _rve_fabric(st, centre, size=0.06):
    W = membership(np.array([centre]), st.x, st.y, "square", size)
    return rve_fabric(W, particle_fabric(st), st.area)[0]


def test_square_lattice_trace_4_isotropic():
    x, y, c = square_lattice(30, 30, A)
    st = as_state(make_state(x, y, square_nodes(A), c))
    F = particle_fabric(st)
    interior = (x > x.min()) & (x < x.max()) & (y < y.max())
    np.testing.assert_allclose(F[interior], np.broadcast_to(2 * np.eye(2), F[interior].shape), atol=1e-12)
    Fr = _rve_fabric(st, [x.mean(), y.mean()])
    assert fabric_trace(Fr) == pytest.approx(4.0)
    assert deviatoric_fraction(Fr) == pytest.approx(0.0, abs=1e-12)
    assert np.isnan(axis_angle_from_vertical(Fr, "largest"))  # isotropic: no axis


def test_support_contacts_count_in_fabric():
    x, y, c = square_lattice(10, 3, A)
    st = as_state(make_state(x, y, square_nodes(A), c))
    F = particle_fabric(st)
    bottom_interior = (y == y.min()) & (x > x.min()) & (x < x.max())
    assert np.allclose(fabric_trace(F[bottom_interior]), 4.0)  # left, right, above, support


def test_hexagonal_lattice_trace_6_isotropic():
    x, y, c, nodes = hex_lattice(30, 30, A)
    st = as_state(make_state(x, y, nodes, c))
    Fr = _rve_fabric(st, [x.mean(), y.mean()])
    assert fabric_trace(Fr) == pytest.approx(6.0)
    assert deviatoric_fraction(Fr) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(Fr, 3 * np.eye(2), atol=1e-12)


def test_vertical_contacts_only_fully_anisotropic_and_vertical():
    x, y, c = square_lattice(30, 30, A, horizontal=False)
    st = as_state(make_state(x, y, square_nodes(A), c))
    Fr = _rve_fabric(st, [x.mean(), y.mean()])
    assert deviatoric_fraction(Fr) == pytest.approx(1.0)
    assert axis_angle_from_vertical(Fr, "largest") == pytest.approx(0.0, abs=1e-9)
    assert fabric_trace(Fr) == pytest.approx(2.0)


def test_volume_weighting():
    """Particles with 2 and 4 contacts and areas 1:3 give trace (1*2 + 3*4)/4 = 3.5."""
    small, big = square_nodes(A), square_nodes(A * np.sqrt(3))
    # particle 0 at (0, 0.01): support below it and particle 1; particle 1 at (0.02, 0.02): particle 0
    # and three more (support-type) contacts in other directions
    contacts = {"i": [0, 0, 1, 1, 1], "j": [-1, 1, -1, -1, -1],
                "cx": [0.0, 0.01, 0.02, 0.03, 0.02], "cy": [0.005, 0.015, 0.01, 0.02, 0.03]}
    st = as_state(make_state([0.0, 0.02], [0.01, 0.02], [small, big], contacts))
    F = particle_fabric(st)
    assert fabric_trace(F).tolist() == pytest.approx([2.0, 4.0])
    W = membership(np.array([[0.01, 0.05]]), st.x, st.y, "square", 0.2)
    Fr = rve_fabric(W, F, st.area)[0]
    assert fabric_trace(Fr) == pytest.approx((1 * 2 + 3 * 4) / 4)


@pytest.mark.parametrize("deg", [-40.0, -10.0, 0.0, 25.0, 40.0, 89.0])
def test_angle_convention_counter_clockwise_from_vertical(deg):
    """An axis at +deg has its upper end leaning towards -x: direction (-sin, cos)."""
    t = np.radians(deg)
    n = np.array([-np.sin(t), np.cos(t)])
    F = 2 * np.outer(n, n) + 0.5 * np.eye(2)
    assert axis_angle_from_vertical(F, "largest") == pytest.approx(deg, abs=1e-9)
    # a compressive stress along the same axis: most negative eigenvalue
    assert axis_angle_from_vertical(-F, "smallest") == pytest.approx(deg, abs=1e-9)
    assert axis_angle_from_vertical(F, "smallest") == pytest.approx(
        deg - 90 if deg > 0 else deg + 90, abs=1e-9)


def test_axis_angle_difference_folds():
    assert axis_angle_difference(80.0, -80.0) == pytest.approx(-20.0)
    assert axis_angle_difference(-85.0, 85.0) == pytest.approx(10.0)
    assert axis_angle_difference(10.0, 100.0) == pytest.approx(90.0)
