"""Stress (Eq. 2) against hand computations, and the balance laws on a static heap."""

import numpy as np
import pytest
from synthetic_states import as_state, displaced, make_state, square_nodes, step_pyramid

from analysis.balance import balance_report, enforce, love_sum_rule, net_contact_force
from analysis.errors import BalanceError
from analysis.params import DEFAULTS
from analysis.rve import membership, rve_area
from analysis.stress import particle_stress, particle_stress_moment, rve_stress

A = 0.01


def _two_squares():
    """Two squares side by side, pushed together with force P, resting on the support.

    Particle 0 at (0, a/2), particle 1 at (a, a/2). Contact 0: i=0, j=1 at
    (a/2, a/2), force on particle 0 = (-P, 0.3P) (compression plus friction).
    Support contacts at (0, 0) and (a, 0) with forces (0.2P, N0), (-0.2P, N1).
    """
    P = 2.0
    contacts = {"i": [0, 0, 1], "j": [1, -1, -1], "cx": [A / 2, 0.0, A], "cy": [A / 2, 0.0, 0.0],
                "fx": [-P, 0.2 * P, -0.2 * P], "fy": [0.3 * P, 5.0, 7.0]}
    return make_state([0.0, A], [A / 2, A / 2], square_nodes(A), contacts), P


def test_particle_stress_moment_by_hand():
    s, P = _two_squares()
    st = as_state(s)
    m = particle_stress_moment(st)
    # particle 0: branch (a/2, 0) with force (-P, 0.3P); branch (0, -a/2) with force (0.2P, 5)
    exp0 = np.outer([A / 2, 0], [-P, 0.3 * P]) + np.outer([0, -A / 2], [0.2 * P, 5.0])
    # particle 1: branch (-a/2, 0) with force (P, -0.3P) (the negative); branch (0, -a/2) with (-0.2P, 7)
    exp1 = np.outer([-A / 2, 0], [P, -0.3 * P]) + np.outer([0, -A / 2], [-0.2 * P, 7.0])
    np.testing.assert_allclose(m[0], exp0, atol=1e-15)
    np.testing.assert_allclose(m[1], exp1, atol=1e-15)
    np.testing.assert_allclose(particle_stress(st)[0], exp0 / A**2)
    # compression along x is negative, as in the contract
    assert m[0][0, 0] < 0 and m[1][0, 0] < 0


def test_rve_stress_is_sum_over_members_divided_by_rve_area():
    s, P = _two_squares()
    st = as_state(s)
    m = particle_stress_moment(st)
    size = 0.05
    centres = np.array([[A / 2, 0.1], [0.0, 0.1], [A / 2, 0.01]])
    W = membership(centres, st.x, st.y, "square", size)
    sig = rve_stress(W, m, rve_area(centres[:, 1], "square", size))
    # RVE 0: both particles, full square (0.075 .. 0.125 is above... no: it spans y 0.075-0.125 -> empty)
    assert np.all(sig[0] == 0)
    # RVE 2 (centre y = 0.01): both particles inside; clipped to y >= 0: V = size * (0.01 + size/2)
    V = size * (0.01 + size / 2)
    np.testing.assert_allclose(sig[2], (m[0] + m[1]) / V, rtol=1e-12)
    # equals the volume-weighted sum of Eq. 2 particle stresses over V
    ps = particle_stress(st)
    np.testing.assert_allclose(sig[2], (A**2 * ps[0] + A**2 * ps[1]) / V, rtol=1e-12)


def test_rve_area_clipped_at_support():
    assert rve_area(np.array([1.0]), "square", 0.08)[0] == pytest.approx(0.0064)
    assert rve_area(np.array([0.0]), "square", 0.08)[0] == pytest.approx(0.0032)
    assert rve_area(np.array([1.0]), "circle", 0.08)[0] == pytest.approx(np.pi * 0.04**2)
    assert rve_area(np.array([0.0]), "circle", 0.08)[0] == pytest.approx(np.pi * 0.04**2 / 2)
    assert rve_area(np.array([-0.05]), "circle", 0.08)[0] == pytest.approx(0.0)
    # a disc whose centre is r/2 above the support: cap of height r/2 cut off
    r = 0.04
    d = r / 2
    cap = r * r * np.arccos(d / r) - d * np.sqrt(r * r - d * d)
    assert rve_area(np.array([d]), "circle", 2 * r)[0] == pytest.approx(np.pi * r * r - cap)


def test_static_heap_support_reaction_and_love_sum_rule():
    s = step_pyramid(41, A, slope=0.8, gravity=9.81)
    st = as_state(s)
    M = st.mass.sum()
    g = 9.81
    # per-particle balance is exact by construction
    net = net_contact_force(st) + st.mass[:, None] * np.array([0, -g])
    assert np.abs(net).max() < 1e-12 * st.mass.max() * g
    assert st.force_y[st.support].sum() == pytest.approx(M * g, rel=1e-12)
    lhs, rhs = love_sum_rule(st)
    y_cm = st.mass @ st.y / M
    # support contact points lie on y = 0, so sum_p sum_c x_y f_y = -M g y_cm exactly
    assert lhs[1, 1] == pytest.approx(-M * g * y_cm, rel=1e-12)
    np.testing.assert_allclose(lhs, rhs, atol=1e-12 * M * g * y_cm)
    # hand value for the columns: each column of h squares contributes -(a/2) m g h^2
    m = st.mass[0]
    heights = np.bincount(np.round((st.x - st.x.min()) / A).astype(int))
    assert lhs[1, 1] == pytest.approx(-(A / 2) * m * g * np.sum(heights.astype(float) ** 2), rel=1e-12)
    rep = balance_report(st, DEFAULTS["checks"])
    assert rep["passed"], rep["failures"]


def test_balance_checks_fail_loudly_when_forces_do_not_balance():
    s = step_pyramid(21, A, slope=0.8)
    s["force_y"] = s["force_y"] * np.where(s["contact_j"] < 0, 0.9, 1.0)  # support carries 10% too little
    rep = balance_report(as_state(s, "bad.nc"), DEFAULTS["checks"])
    assert not rep["passed"]
    with pytest.raises(BalanceError, match="support_reaction_rtol"):
        enforce([rep])


def test_reduced_gravity_state_is_checked_against_its_own_gravity():
    s = step_pyramid(21, A, slope=0.8, gravity=9.81)
    r = displaced(s, np.zeros((s["x"].size, 2)), force_scale=0.9, gravity=9.81 * 0.9)
    assert balance_report(as_state(r), DEFAULTS["checks"])["passed"]
    r["attrs"]["gravity"] = 9.81  # forces of 0.9 g but claimed gravity g
    assert not balance_report(as_state(r), DEFAULTS["checks"])["passed"]


def test_gravity_vector_attributes_are_used_when_present():
    s = step_pyramid(21, A, slope=0.8, gravity=9.81)
    s["attrs"].update(gravity_x=0.0, gravity_y=-9.81)
    assert balance_report(as_state(s), DEFAULTS["checks"])["passed"]
    s["attrs"].update(gravity_x=2.0, gravity_y=-9.6)  # tilted gravity the forces do not balance
    rep = balance_report(as_state(s), DEFAULTS["checks"])
    assert not rep["passed"] and rep["support_horizontal_rel"] == pytest.approx(
        2.0 * as_state(s).mass.sum() / (as_state(s).mass.sum() * np.hypot(2.0, 9.6)))
