"""Cambou best-fit displacement gradient (Eqs 3–9): exact for affine fields, refusals flagged."""

import numpy as np
import pytest
from synthetic_states import as_state, displaced, hex_lattice, make_state, square_lattice, square_nodes

from analysis.rve import membership
from analysis.strain import (FLAG_ILL_CONDITIONED, FLAG_TOO_FEW_CONTACTS, best_fit_strain, cambou_gradient,
                             condition_number)

D = 0.007


def _jittered_packing():
    x, y, c, nodes = hex_lattice(24, 24, D, jitter=0.0015, seed=3)
    return make_state(x, y, nodes, c)


def _fit(base, du, size=0.08, min_contacts=10, max_condition=50.0):
    relaxed = as_state(base)
    reduced = as_state(displaced(base, du))
    centres = np.array([[0.08, 0.07], [0.1, 0.09], [0.06, 0.1]])
    W = membership(centres, relaxed.x, relaxed.y, "square", size)
    return best_fit_strain(W, relaxed, reduced, min_contacts, max_condition)


def test_affine_field_recovered_exactly_including_antisymmetric_part():
    base = _jittered_packing()
    # eps_ij = du_j/dx_i, deliberately non-symmetric and with all entries distinct
    eps = np.array([[2.0e-4, -3.0e-4], [0.7e-4, -1.1e-4]])
    r = np.column_stack([base["x"], base["y"]])
    du = r @ eps + np.array([1e-5, -2e-5])  # du_j = r_i eps_ij (+ a rigid translation)
    res = _fit(base, du)
    assert np.all(res["flag"] == 0)
    assert np.all(res["n_contacts"] > 100)
    for g in res["displacement_gradient"]:
        np.testing.assert_allclose(g, eps, rtol=0, atol=1e-12 * np.abs(eps).max() * 1e3)
    # the affine part explains everything: residual at rounding level
    assert np.all(res["residual"] < 1e-8)


def test_index_order_is_du_j_over_dx_i():
    """A pure shear u_x = g*y must appear as eps_yx = du_x/dy = g, eps_xy = 0."""
    base = _jittered_packing()
    g = 1e-4
    du = np.column_stack([g * base["y"], np.zeros(base["y"].size)])
    eps = _fit(base, du)["displacement_gradient"][0]
    assert eps[1, 0] == pytest.approx(g, rel=1e-9)
    assert abs(eps[0, 1]) < 1e-12 and abs(eps[0, 0]) < 1e-12 and abs(eps[1, 1]) < 1e-12


def test_small_rigid_rotation_gives_zero_symmetric_strain():
    base = _jittered_packing()
    th = 1e-5
    du = th * np.column_stack([-base["y"], base["x"]])  # linearised rotation
    res = _fit(base, du)
    for g in res["displacement_gradient"]:
        sym = 0.5 * (g + g.T)
        assert np.abs(sym).max() < 1e-9 * th
        assert g[0, 1] == pytest.approx(th, rel=1e-9)  # du_y/dx
        assert g[1, 0] == pytest.approx(-th, rel=1e-9)  # du_x/dy


def test_non_affine_noise_gives_positive_residual_and_unbiased_gradient():
    base = _jittered_packing()
    rng = np.random.default_rng(1)
    eps = np.array([[1e-4, 0.0], [0.0, 2e-4]])
    r = np.column_stack([base["x"], base["y"]])
    noise = 2e-7 * rng.standard_normal(r.shape)
    res = _fit(base, r @ eps + noise)
    assert np.all((res["residual"] > 0.01) & (res["residual"] < 1))
    # gradient error ~ noise / (RVE size * sqrt(contacts)) << 1e-5
    assert np.abs(res["displacement_gradient"] - eps).max() < 1e-5


def test_branch_vectors_not_spanning_the_plane_are_refused():
    x, y, c = square_lattice(30, 1, D, vertical=False, support=False)  # one row: horizontal contacts only
    base = make_state(x, y, square_nodes(D), c)
    relaxed = as_state(base)
    reduced = as_state(displaced(base, 1e-6 * np.ones((x.size, 2))))
    W = membership(np.array([[0.1, D / 2]]), relaxed.x, relaxed.y, "square", 0.08)
    res = best_fit_strain(W, relaxed, reduced, 2, 1e6)
    assert res["flag"][0] & FLAG_ILL_CONDITIONED
    assert np.isinf(res["condition"][0])
    assert np.all(np.isnan(res["displacement_gradient"][0]))
    assert np.isnan(res["residual"][0])


def test_too_few_contacts_are_refused():
    base = _jittered_packing()
    r = np.column_stack([base["x"], base["y"]])
    res = _fit(base, r * 1e-4, size=0.015, min_contacts=50)
    assert np.all(res["flag"] & FLAG_TOO_FEW_CONTACTS)
    assert np.all(np.isnan(res["displacement_gradient"]))


def test_gradient_solves_the_normal_equations_of_eq6():
    """eps = M^-1 B minimises Z (Eq. 6): compare with a generic least-squares solver."""
    rng = np.random.default_rng(5)
    l = rng.standard_normal((40, 2))
    ddu = rng.standard_normal((40, 2))
    M = l.T @ l
    B = l.T @ ddu
    eps = cambou_gradient(M[None], B[None])[0]
    ref, *_ = np.linalg.lstsq(l, ddu, rcond=None)  # solves l @ eps = ddu, i.e. ddu_j = l_i eps_ij
    np.testing.assert_allclose(eps, ref, rtol=1e-12, atol=1e-14)
    assert condition_number(M[None])[0] == pytest.approx(np.linalg.cond(M), rel=1e-10)
