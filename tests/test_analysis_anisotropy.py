"""All six constants of one pile and the paper's moduli of any law (analysis.anisotropy).

* The paper's moduli of a Mandel stiffness: of a cubic law, the values worked
  out by hand from the paper's expressions (E_b from the stiffness rotated by
  45°); of an isotropic law K, 4KG/(K + G) and G in every direction; a cubic
  law turned by 45° swaps the axes' and the bisectors' moduli.
* A synthetic pile of a linear anisotropic material with a known stiffness
  in each RVE, softer by 30 % in the centre columns, probed by the gravity
  reduction, two tilts (strains in two shapes only, as in a linear pile) and
  the stretch: every core RVE pins all six constants, the general law's
  moduli are those of the known C, the Voigt stiffness given as 2 C is twice
  as stiff in every modulus with the same axis, and every modulus of the
  general law has the centre contrast −0.3.
* An isotropic material: the isotropic, cubic and general laws fitted to the
  same samples, and the reduction's laws, are one law (every ratio 1): the
  choice of law cannot matter there.
"""

import numpy as np
import pytest
import xarray as xr
from synthetic_states import linear_probe_pile

from analysis import general_elastic as ge
from analysis.anisotropy import MODULI, engineering_moduli, pile_anisotropy, pile_summary
from analysis.params import parse_params

RNG = np.random.default_rng(2027)
X = np.round(np.arange(-0.18, 0.1801, 0.015), 6)    # the grid's columns: centre, shoulders and beyond
Y = np.array([0.015, 0.03, 0.045, 0.06])
CENTRE_SOFTENING = 0.3


def rotation(deg):
    """Mandel rotation of a stiffness by ``deg`` (counter-clockwise): ``C' = R C Rᵀ``."""
    b = np.radians(deg)
    r = np.array([[np.cos(b), -np.sin(b)], [np.sin(b), np.cos(b)]])
    return np.array([[r[0, 0] ** 2, r[0, 1] ** 2, np.sqrt(2) * r[0, 0] * r[0, 1]],
                     [r[1, 0] ** 2, r[1, 1] ** 2, np.sqrt(2) * r[1, 0] * r[1, 1]],
                     [np.sqrt(2) * r[0, 0] * r[1, 0], np.sqrt(2) * r[0, 1] * r[1, 1],
                      r[0, 0] * r[1, 1] + r[0, 1] * r[1, 0]]])


def test_the_paper_moduli_of_a_cubic_law_are_its_expressions_worked_by_hand():
    # lambda1 = 3, lambda2 = 1, lambda3 = 0.5 (units of 1e6 N/m)
    out = engineering_moduli(ge.cubic_stiffness(3.0e6, 1.0e6, 0.5e6))
    by_hand = {"K": 2.0e6, "E_p": (9.0 - 1.0) / 3.0 * 1e6, "E_b": 4 * 0.5 * 4.0 / (4.0 + 1.0) * 1e6,
               "G_p": 0.5e6, "G_b": 1.0e6}
    by_hand["E_av"] = 0.5 * (by_hand["E_p"] + by_hand["E_b"])
    by_hand["G_av"] = 0.5 * (by_hand["G_p"] + by_hand["G_b"])
    for k, v in by_hand.items():
        assert float(out[k]) == pytest.approx(v, rel=1e-12), k


def test_an_isotropic_law_has_the_same_moduli_along_axes_and_bisectors():
    K, G = 2.0e6, 0.7e6
    out = engineering_moduli(ge.isotropic_stiffness(K, G))
    assert float(out["K"]) == pytest.approx(K, rel=1e-12)
    for k in ("E_p", "E_b", "E_av"):
        assert float(out[k]) == pytest.approx(4 * K * G / (K + G), rel=1e-12)
    for k in ("G_p", "G_b", "G_av"):
        assert float(out[k]) == pytest.approx(G, rel=1e-12)


def test_turning_a_cubic_law_by_45_degrees_swaps_axes_and_bisectors():
    c = ge.cubic_stiffness(3.0e6, 1.0e6, 0.5e6)
    turned = rotation(45.0) @ c @ rotation(45.0).T
    a, b = engineering_moduli(c), engineering_moduli(turned)
    for p, q in (("E_p", "E_b"), ("G_p", "G_b")):
        assert float(b[p]) == pytest.approx(float(a[q]), rel=1e-9)
        assert float(b[q]) == pytest.approx(float(a[p]), rel=1e-9)
    for k in ("K", "E_av", "G_av"):
        assert float(b[k]) == pytest.approx(float(a[k]), rel=1e-9)


def test_a_known_anisotropic_pile_is_recovered_with_its_centre_softer_by_30_per_cent():
    q = np.linalg.qr(RNG.normal(size=(3, 3)))[0]
    c = q @ np.diag([3.0e6, 1.2e6, 0.5e6]) @ q.T                   # no symmetry axis along x or y
    centre = np.abs(X) <= 0.03 + 1e-9
    c_field = np.broadcast_to(c, (len(Y), len(X), 3, 3)) * np.where(centre, 1 - CENTRE_SOFTENING, 1.0)[
        None, :, None, None]
    params = parse_params('{"moduli": {"min_points": 3}}')
    pile = pile_anisotropy(*linear_probe_pile(c_field, X, Y, RNG), params)
    known = engineering_moduli(c)
    axes = ge.stiffness_axes(c)
    fit = pile.sel(points=1)
    assert (fit["six_constants"].values == 1).all()
    for k in MODULI:
        expected = known[k] * np.where(centre, 1 - CENTRE_SOFTENING, 1.0)
        np.testing.assert_allclose(fit[f"general_{k}"].values, np.broadcast_to(expected, (len(Y), len(X))),
                                   rtol=1e-8)
        np.testing.assert_allclose(fit[f"voigt_{k}"].values, 2.0 * fit[f"general_{k}"].values, rtol=1e-8)

    s = pile_summary(pile, params, points=1)
    core = (np.abs(X) <= 0.15 + 1e-9).sum() * (Y <= 0.135).sum()
    assert s["core_fitted@1"] == core and s["six_share@1"] == 1.0
    assert s["condition_gravity@1"] > 1e10                            # the gravity probes pin five
    assert s["condition@1"] <= 10.0
    assert s["anisotropy"] == pytest.approx(float(axes["anisotropy"]), rel=1e-8)
    assert s["abs_axis_to_fabric"] == pytest.approx(10.0, abs=1e-9)
    assert s["abs_axis_to_stress"] == pytest.approx(85.0, abs=1e-9)
    assert s["voigt_anisotropy"] == pytest.approx(float(axes["anisotropy"]), rel=1e-8)
    assert s["voigt_axis_to_fit"] == pytest.approx(0.0, abs=1e-9)
    for k in MODULI:
        assert s[f"voigt/general:{k}"] == pytest.approx(2.0, rel=1e-8)
        assert s[f"centre:general_{k}"] == pytest.approx(-CENTRE_SOFTENING, rel=1e-8)


def test_on_an_isotropic_material_every_law_is_the_same_law():
    c = ge.isotropic_stiffness(2.0e6, 0.7e6)
    c_field = np.broadcast_to(c, (len(Y), len(X), 3, 3)).copy()
    params = parse_params('{"moduli": {"min_points": 3}}')
    pile = pile_anisotropy(*linear_probe_pile(c_field, X, Y, RNG), params)
    for m in (1, 5):
        s = pile_summary(pile, params, points=m)
        assert s[f"six_share@{m}"] == 1.0
        assert all(s[f"stable:{law}"] == 1.0 for law in ("isotropic", "cubic", "voigt"))
        pairs = ["isotropic/general", "cubic/general", "cubic/isotropic"]
        if m == 5:          # the reduction alone has one sample per point: fitted at m = 5 only
            pairs += ["reduced_isotropic/general", "reduced_cubic/general", "reduced_cubic/reduced_isotropic"]
            for k in MODULI:                            # the Voigt stiffness was given as 2 C
                assert s[f"voigt/reduced_isotropic:{k}"] == pytest.approx(2.0, rel=1e-8)
        for pair in pairs:
            for k in MODULI:
                assert s[f"{pair}:{k}"] == pytest.approx(1.0, rel=1e-8), (m, pair, k)
