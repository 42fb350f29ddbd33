"""Elastic fits (Eqs 16–22): recovery of known moduli, refusal of degenerate data, formulas checked
against a numerical rotation of the 2D cubic stiffness tensor."""

import numpy as np
import pytest

from analysis.elastic import (FIT_DEGENERATE, FIT_INSUFFICIENT_POINTS, FITS, POINTS, cubic_engineering_moduli,
                              cubic_moduli_from_compliances, fit_all, fit_cubic_compliances, fit_cubic_moduli,
                              fit_isotropic_compliances, fit_isotropic_moduli, gather_points, youngs_modulus_2d,
                              youngs_modulus_isotropic)

K0, G0 = 1.0e6, 0.4e6
L1, L2, L3 = 1.2e6, 0.3e6, 0.2e6
M = 400
STRAIN = 1e-4


def _stress(u, l1, l2, l3):
    s = np.empty_like(u)
    s[..., 0, 0] = l1 * u[..., 0, 0] + l2 * u[..., 1, 1]
    s[..., 1, 1] = l2 * u[..., 0, 0] + l1 * u[..., 1, 1]
    s[..., 0, 1] = s[..., 1, 0] = 2 * l3 * u[..., 0, 1]
    return s


def _sym(rng, shape, scale):
    a = rng.standard_normal(shape + (2, 2)) * scale
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def test_isotropic_moduli_recovered_from_noisy_stress():
    rng = np.random.default_rng(0)
    u = _sym(rng, (M,), STRAIN)
    noise_sd = 1.0  # N/m, about 1% of the stresses
    sig = _stress(u, K0 + G0, K0 - G0, G0) + _sym(rng, (M,), noise_sd)
    K, G, flag = fit_isotropic_moduli(sig, u)
    assert flag == 0
    tr = u[:, 0, 0] + u[:, 1, 1]
    # K = <T t>/(2<t^2>): noise in T (sd of the trace noise) propagates as sd/(2 sqrt(M <t^2>))
    sd_T = np.sqrt(2) * noise_sd
    sd_K = sd_T / (2 * np.sqrt(np.sum(tr**2)))
    assert abs(K - K0) < 5 * sd_K
    d = u[:, 0, 0] - u[:, 1, 1]
    sd_G = sd_T / (2 * np.sqrt(np.sum(d**2) + 4 * np.sum(u[:, 0, 1] ** 2)))
    assert abs(G - G0) < 5 * sd_G


def test_isotropic_compliances_recovered_from_noisy_strain():
    rng = np.random.default_rng(1)
    sig = _sym(rng, (M,), 100.0)
    # invert the isotropic law: tr u = tr s / (2K), deviatoric u = dev s / (2G)
    tr = sig[:, 0, 0] + sig[:, 1, 1]
    u = (sig - 0.5 * tr[:, None, None] * np.eye(2)) / (2 * G0) + 0.5 * tr[:, None, None] * np.eye(2) / (2 * K0)
    noise_sd = 1e-6  # about 1% of the strains
    u_noisy = u + _sym(rng, (M,), noise_sd)
    K, G, flag = fit_isotropic_compliances(sig, u_noisy)
    assert flag == 0
    # a = 1/(2K) = <t T>/<T^2>; sd(a) = sd_t / sqrt(sum T^2); sd(K) = 2 K^2 sd(a)
    sd_a = np.sqrt(2) * noise_sd / np.sqrt(np.sum(tr**2))
    assert abs(K - K0) < 5 * 2 * K0**2 * sd_a
    D = sig[:, 0, 0] - sig[:, 1, 1]
    sd_b = np.sqrt(2) * noise_sd / np.sqrt(np.sum(D**2) + 4 * np.sum(sig[:, 0, 1] ** 2))
    assert abs(G - G0) < 5 * 2 * G0**2 * sd_b


def test_cubic_moduli_recovered_by_both_methods():
    rng = np.random.default_rng(2)
    u = _sym(rng, (M,), STRAIN)
    sig = _stress(u, L1, L2, L3)
    # noiseless: both methods exact
    l1, l2, l3, f = fit_cubic_moduli(sig, u)
    assert f == 0 and (l1, l2, l3) == pytest.approx((L1, L2, L3), rel=1e-10)
    s1, s2, s3, f = fit_cubic_compliances(sig, u)
    assert f == 0
    c1, c2, c3, f = cubic_moduli_from_compliances(s1, s2, s3)
    assert f == 0 and (c1, c2, c3) == pytest.approx((L1, L2, L3), rel=1e-10)
    # noisy stress (1%): modulus fit unbiased, error ~ noise / (strain sqrt(M))
    noisy = sig + _sym(rng, (M,), 1.0)
    l1, l2, l3, f = fit_cubic_moduli(noisy, u)
    tol = 5 * np.sqrt(2) * 1.0 / (STRAIN * np.sqrt(M))  # generous bound for every combination
    assert abs(l1 - L1) < tol and abs(l2 - L2) < tol and abs(l3 - L3) < tol


def test_isotropic_data_give_isotropic_cubic_fit():
    rng = np.random.default_rng(3)
    u = _sym(rng, (50,), STRAIN)
    sig = _stress(u, K0 + G0, K0 - G0, G0)
    l1, l2, l3, _ = fit_cubic_moduli(sig, u)
    e = cubic_engineering_moduli(l1, l2, l3)
    assert e["G_p"] == pytest.approx(G0) and e["G_b"] == pytest.approx(G0)
    assert e["bulk_modulus_cubic"] == pytest.approx(K0)
    assert e["E_p"] == pytest.approx(youngs_modulus_2d(K0, G0)) and e["E_b"] == pytest.approx(e["E_p"])


def _voigt_stiffness(C):
    """3x3 matrix mapping (u_xx, u_yy, 2u_xy) to (s_xx, s_yy, s_xy) from the 4th-order tensor."""
    idx = [(0, 0), (1, 1), (0, 1)]
    return np.array([[C[a + b] for b in idx] for a in idx])


def _cubic_tensor(l1, l2, l3):
    C = np.zeros((2, 2, 2, 2))
    C[0, 0, 0, 0] = C[1, 1, 1, 1] = l1
    C[0, 0, 1, 1] = C[1, 1, 0, 0] = l2
    C[0, 1, 0, 1] = C[0, 1, 1, 0] = C[1, 0, 0, 1] = C[1, 0, 1, 0] = l3
    return C


def _rotate(C, deg):
    t = np.radians(deg)
    R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    return np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, C)


def _young_along_x(C):
    S = np.linalg.inv(_voigt_stiffness(C))
    return 1.0 / S[0, 0]


@pytest.mark.parametrize("l1,l2,l3", [(1.2e6, 0.3e6, 0.2e6), (2.0, 0.5, 1.25), (1.0, -0.2, 0.9)])
def test_engineering_moduli_against_rotated_stiffness(l1, l2, l3):
    C = _cubic_tensor(l1, l2, l3)
    Cb = _rotate(C, 45.0)  # the bisector frame
    e = cubic_engineering_moduli(l1, l2, l3)
    assert e["E_p"] == pytest.approx(_young_along_x(C), rel=1e-12)
    assert e["E_b"] == pytest.approx(_young_along_x(Cb), rel=1e-12)
    assert e["G_p"] == pytest.approx(C[0, 1, 0, 1], rel=1e-12)
    assert e["G_b"] == pytest.approx(Cb[0, 1, 0, 1], rel=1e-12)
    assert e["E_av"] == pytest.approx(0.5 * (e["E_p"] + e["E_b"]))
    assert e["G_av"] == pytest.approx(0.5 * (e["G_p"] + e["G_b"]))
    assert e["bulk_modulus_cubic"] == pytest.approx(0.5 * (Cb[0, 0, 0, 0] + Cb[0, 0, 1, 1]), rel=1e-12)
    # the paper's printed E_b = l1 + l2 agrees with the rotated stiffness only if l3 = (l1 + l2)/2
    if not np.isclose(l3, 0.5 * (l1 + l2)):
        assert e["E_b_paper"] != pytest.approx(_young_along_x(Cb), rel=1e-3)
    assert e["E_av_paper"] == pytest.approx(0.5 * (e["E_p"] + e["E_b_paper"]))


def test_paper_E_b_coincides_when_lambda3_equals_K():
    l1, l2 = 1.5, 0.5
    e = cubic_engineering_moduli(l1, l2, 0.5 * (l1 + l2))
    assert e["E_b"] == pytest.approx(e["E_b_paper"])


def test_isotropic_young_formulas():
    # paper: E = 3G - G^2/K; equals the 2D 4KG/(K+G) only for K = G
    assert youngs_modulus_isotropic(2.0, 1.0) == pytest.approx(2.5)
    assert youngs_modulus_2d(2.0, 1.0) == pytest.approx(8 / 3)
    assert youngs_modulus_isotropic(1.0, 1.0) == pytest.approx(youngs_modulus_2d(1.0, 1.0))
    C = _cubic_tensor(K0 + G0, K0 - G0, G0)
    for deg in (0.0, 17.0, 45.0):
        assert youngs_modulus_2d(K0, G0) == pytest.approx(_young_along_x(_rotate(C, deg)), rel=1e-12)
    assert np.isnan(youngs_modulus_isotropic(0.0, 1.0))


def test_degenerate_data_refused_with_flags_never_inf():
    rng = np.random.default_rng(4)
    sig = _sym(rng, (5,), 100.0)
    zero = np.zeros((5, 2, 2))
    for fit in (fit_isotropic_moduli, fit_cubic_moduli):
        *vals, flag = fit(sig, zero)  # all-zero strain
        assert flag & FIT_DEGENERATE and all(np.isnan(v) for v in vals)
    for fit in (fit_isotropic_compliances, fit_cubic_compliances):
        *vals, flag = fit(zero, _sym(rng, (5,), 1e-4))  # all-zero stress
        assert flag & FIT_DEGENERATE and all(np.isnan(v) for v in vals)
    # compliances fitted to zero strain are 0: the moduli 1/0 must be NaN, not inf
    s1, s2, s3, f = fit_cubic_compliances(sig, zero)
    l1, l2, l3, f2 = cubic_moduli_from_compliances(s1, s2, s3)
    assert f2 & FIT_DEGENERATE and np.isnan(l1) and np.isnan(l3)
    K, G, f3 = fit_isotropic_compliances(sig, zero)
    assert f3 & FIT_DEGENERATE and np.isnan(K) and np.isnan(G)
    # no shear stress at all: s3 undetermined, the rest of the cubic fit is refused as a whole
    noshear = sig.copy()
    noshear[:, 0, 1] = noshear[:, 1, 0] = 0
    *vals, f4 = fit_cubic_compliances(noshear, _sym(rng, (5,), 1e-4))
    assert f4 & FIT_DEGENERATE and np.isnan(vals[2])
    # NaN samples: too few valid points
    bad = sig.copy()
    bad[1:] = np.nan
    *vals, f5 = fit_isotropic_moduli(bad, _sym(rng, (5,), 1e-4), min_points=3)
    assert f5 & FIT_INSUFFICIENT_POINTS and all(np.isnan(v) for v in vals)


def test_fit_all_on_a_grid_points_and_average():
    rng = np.random.default_rng(6)
    ny, nx = 6, 7
    u = _sym(rng, (ny, nx), STRAIN)
    sig = _stress(u, L1, L2, L3)
    sig[0, 0] = np.nan  # a masked RVE
    res = fit_all(sig, u, min_points=3)
    assert res["lambda1"].shape == (len(FITS), len(POINTS), ny, nx)
    # m = 5 on exact cubic data: every valid point recovers the moduli
    m5 = res["lambda3"][:, 1]
    valid = np.isfinite(m5)
    assert valid.sum() > 0.8 * valid.size
    np.testing.assert_allclose(m5[valid], L3, rtol=1e-9)
    # m = 1 uses one sample: the masked point is NaN and flagged
    assert np.isnan(res["bulk_modulus"][0, 0, 0, 0])
    assert res["isotropic_mask_reason"][0, 0, 0, 0] & FIT_INSUFFICIENT_POINTS
    avg = res["E_av"][2]
    np.testing.assert_allclose(avg, 0.5 * (res["E_av"][0] + res["E_av"][1]), equal_nan=True)
    assert not np.isinf(np.concatenate([v.ravel() for k, v in res.items() if v.dtype.kind == "f"])).any()


def test_gather_points_neighbours():
    f = np.arange(12.0).reshape(3, 4)[:, :, None, None] * np.ones((1, 1, 2, 2))
    g = gather_points(f, 5)
    assert g.shape == (3, 4, 5, 2, 2)
    assert sorted(g[1, 1, :, 0, 0].tolist()) == sorted([5.0, 9.0, 1.0, 6.0, 4.0])
    assert np.isnan(g[0, 0, :, 0, 0]).sum() == 2


def _isotropic_pile(rng, K, G, shape=(3, 4)):
    """Per-RVE strain increments (from `rng`) and the stress increments of an
    isotropic medium."""
    u = rng.standard_normal(shape + (2, 2)) * 1e-4
    u = 0.5 * (u + np.swapaxes(u, -1, -2))
    tr = (u[..., 0, 0] + u[..., 1, 1])[..., None, None]
    return K * tr * np.eye(2) + 2 * G * (u - 0.5 * tr * np.eye(2)), u


@pytest.mark.parametrize("method", ["pile_fits", "bootstrap"])
def test_fit_uncertainty_is_the_spread_of_the_piles_moduli(method):
    """Each pile exactly isotropic with its own K and G: the per-pile fits are
    exact, so their standard error is that of the moduli themselves; equal
    piles have none."""
    from analysis.elastic import fit_uncertainty

    rng = np.random.default_rng(7)
    K = np.array([3.0e6, 3.3e6, 2.8e6, 3.1e6])
    G = np.array([1.0e6, 1.2e6, 0.9e6, 1.1e6])
    # the same strains in every pile: a resampled mean is the field of the mean moduli
    piles = [_isotropic_pile(np.random.default_rng(7), k, g) for k, g in zip(K, G)]
    sigma = np.stack([p[0] for p in piles])
    u = np.stack([p[1] for p in piles])
    out = fit_uncertainty(sigma, u, method, min_points=1, rtol=1e-12, samples=400, seed=1)
    if method == "pile_fits":
        np.testing.assert_allclose(out["bulk_modulus"], np.std(K, ddof=1) / 2, rtol=1e-9)
        np.testing.assert_allclose(out["shear_modulus"], np.std(G, ddof=1) / 2, rtol=1e-9)
    else:   # resampled means: of the order of the standard error
        assert np.all((out["bulk_modulus"] > 0.3 * np.std(K, ddof=1) / 2) &
                      (out["bulk_modulus"] < 2.0 * np.std(K, ddof=1) / 2))
    one = _isotropic_pile(rng, 3e6, 1e6)
    same = fit_uncertainty(np.stack([one[0]] * 3), np.stack([one[1]] * 3), method, 1, 1e-12,
                           samples=50)
    np.testing.assert_allclose(same["bulk_modulus"], 0.0, atol=1e-6)


def test_moduli_dataset_holds_the_fit_of_the_mean_and_the_spread_of_the_piles():
    import xarray as xr

    from analysis.elastic import moduli_dataset
    from analysis.netcdf import tensor_coords, var
    from analysis.params import resolve_params

    K = np.array([3.0e6, 3.4e6, 2.6e6])
    G = np.array([1.0e6, 1.1e6, 0.9e6])
    coords = {"y": var("y", [0.03, 0.045, 0.06], "y", "m"),
              "x": var("x", [-0.015, 0.0, 0.015, 0.03], "x", "m"), **tensor_coords()}
    piles = []
    for k, g in zip(K, G):
        sigma, u = _isotropic_pile(np.random.default_rng(3), k, g)
        pile = xr.Dataset(coords=coords)
        pile["stress_increment"] = var(("y", "x", "i", "j"), sigma, "dsigma", "N m-1")
        pile["strain_increment"] = var(("y", "x", "i", "j"), u, "u", "1")
        piles.append(pile)
    ensemble = (sum(piles) / len(piles)).assign_attrs(n_seeds=3, protocol="wedge")
    ds = moduli_dataset(ensemble, piles, resolve_params({"moduli": {"min_points": 1}}))
    assert ds["bulk_modulus"].dims == ("fit", "points", "y", "x")
    np.testing.assert_allclose(ds["bulk_modulus"].values, K.mean(), rtol=1e-9)
    np.testing.assert_allclose(ds["shear_modulus"].values, G.mean(), rtol=1e-9)
    np.testing.assert_allclose(ds["bulk_modulus_sem"].values, np.std(K, ddof=1) / np.sqrt(3),
                               rtol=1e-9)
    assert ds.attrs["n_seeds"] == 3 and ds.attrs["uncertainty_method"] == "pile_fits"


def test_per_pile_fits_leave_out_a_pile_where_it_slipped():
    """Four exactly isotropic piles; the fourth slipped at one RVE (its strain
    there 100 times its elastic size, its stress increment unchanged). The
    standard error of K there (m = 1) is that of the three other piles' K; at
    the other RVEs that of all four."""
    import xarray as xr

    from analysis.elastic import moduli_dataset
    from analysis.netcdf import tensor_coords, var
    from analysis.params import resolve_params

    K = np.array([3.0e6, 3.4e6, 2.6e6, 3.1e6])
    coords = {"y": var("y", [0.03, 0.045, 0.06], "y", "m"),
              "x": var("x", [-0.015, 0.0, 0.015, 0.03], "x", "m"), **tensor_coords()}
    piles = []
    for k in K:
        sigma, u = _isotropic_pile(np.random.default_rng(5), k, 1e6)
        pile = xr.Dataset(coords=coords)
        pile["stress_increment"] = var(("y", "x", "i", "j"), sigma, "dsigma", "N m-1")
        pile["strain_increment"] = var(("y", "x", "i", "j"), u, "u", "1")
        piles.append(pile)
    piles[3]["strain_increment"].values[1, 2] *= 100.0
    ensemble = (sum(piles[:3]) / 3).assign_attrs(n_seeds=4, protocol="wedge")
    params = resolve_params({"moduli": {"min_points": 1}, "ensemble": {"slip_strain_ratio": 10.0}})
    sem = moduli_dataset(ensemble, piles, params)["bulk_modulus_sem"].sel(points=1).values
    kept = np.ones(sem.shape[1:], bool)
    kept[1, 2] = False
    np.testing.assert_allclose(sem[:, 1, 2], np.std(K[:3], ddof=1) / np.sqrt(3), rtol=1e-9)
    np.testing.assert_allclose(sem[:, kept], np.std(K, ddof=1) / 2, rtol=1e-9)


# ---------------------------------------------------------------- conditioning and masks (issue 27)
def _hooke(u, K, G):
    """Isotropic 2D Hooke's law: tr σ = 2K tr u, dev σ = 2G dev u."""
    tr = (u[..., 0, 0] + u[..., 1, 1])[..., None, None]
    return K * tr * np.eye(2) + 2 * G * (u - 0.5 * tr * np.eye(2))


def _grid_strains(rng, shape=(5, 6)):
    """Strain increments of an unloaded pile: u_yy about 2e-4, u_xx 0.5e-4, every
    mode excited at every RVE (|u_xy| 0.3–0.6e-4, random sign), so that the
    one-sample (m = 1) fits are well posed."""
    u = np.zeros(shape + (2, 2))
    u[..., 0, 0] = 0.5 * STRAIN * (1 + 0.3 * rng.standard_normal(shape))
    u[..., 1, 1] = 2.0 * STRAIN * (1 + 0.3 * rng.standard_normal(shape))
    u[..., 0, 1] = u[..., 1, 0] = STRAIN * rng.uniform(0.3, 0.6, shape) * rng.choice([-1, 1], shape)
    return u


def test_a_noisy_isotropic_material_is_recovered_well_conditioned_and_kept():
    """Stress increments from Hooke's law with known K, G plus 0.5 % noise:
    every fit (both methods and their average, m = 1 and 5) recovers K and G,
    its condition number is that of the material, max(K, G)/min(K, G) = 2.5,
    and nothing is masked; the cubic fit of the same data is the isotropic
    limit (λ1 = K + G, λ2 = K − G, λ3 = G), positive definite with the same
    condition number."""
    from analysis.elastic import FIT_ILL_CONDITIONED

    rng = np.random.default_rng(11)
    u = _grid_strains(rng)
    sig = _hooke(u, K0, G0)
    sig = sig + _sym(rng, u.shape[:2], 0.005 * np.abs(sig).mean())
    res = fit_all(sig, u, min_points=3, max_condition=10.0)
    for law in ("isotropic", "cubic"):
        fitted = res[f"{law}_mask_reason"][:, 1] & ~FIT_INSUFFICIENT_POINTS   # m = 5 at the grid's corners: 3 points
        assert np.all(fitted == 0) and np.all(res[f"{law}_mask_reason"][:, 0] == 0), law
    np.testing.assert_allclose(res["bulk_modulus"], K0, rtol=0.05)
    np.testing.assert_allclose(res["shear_modulus"], G0, rtol=0.05)
    np.testing.assert_allclose(res["isotropic_condition"], K0 / G0, rtol=0.1)
    five = np.s_[:, 1]                                    # m = 5: the cubic modes have 5 samples each
    np.testing.assert_allclose(res["lambda1"][five], K0 + G0, rtol=0.05)
    np.testing.assert_allclose(res["lambda3"][five], G0, rtol=0.1)
    np.testing.assert_allclose(res["cubic_condition"][five], K0 / G0, rtol=0.2)
    assert not np.any(res["cubic_mask_reason"] & FIT_ILL_CONDITIONED)


def test_the_condition_number_is_the_ratio_of_the_mode_stiffnesses():
    """κ of a fit is max/min of |2K|, |2G| (isotropic) and of |λ1 + λ2|,
    |λ1 − λ2|, |2λ3| (cubic), the eigenvalues of the Mandel stiffness."""
    from analysis.elastic import fit_quality
    from analysis.general_elastic import cubic_stiffness, isotropic_stiffness

    kappa, _ = fit_quality(isotropic_stiffness(np.array([1e6, 1e6]), np.array([2e5, -5e4])))
    np.testing.assert_allclose(kappa, [5.0, 20.0])
    l1, l2, l3 = np.array([1.2e6, 1.0e6, 1.0e6]), np.array([0.3e6, 0.99e6, -0.3e6]), np.array([0.2e6, 0.4e6, 0.4e6])
    modes = np.abs(np.stack([l1 + l2, l1 - l2, 2 * l3]))
    kappa, _ = fit_quality(cubic_stiffness(l1, l2, l3))
    np.testing.assert_allclose(kappa, modes.max(0) / modes.min(0), rtol=1e-12)
    kappa, reason = fit_quality(np.full((3, 3), np.nan))
    assert np.isnan(kappa) and reason == 0


def test_orthogonal_deviatoric_stress_and_strain_are_ill_conditioned_and_masked():
    """The deviatoric stress increment turned by 90° against the deviatoric
    strain in the (u_xx − u_yy, 2u_xy) plane: <(σxx−σyy)(uxx−uyy)> + 4<σxy uxy> = 0,
    so the fit of moduli gives G = 0 (K stays exact) and that of compliances
    1/(2G) = 0: the condition number K/|G| is unbounded and every isotropic fit
    is masked, at m = 1 and at m = 5."""
    from analysis.elastic import FIT_DEGENERATE, FIT_ILL_CONDITIONED

    rng = np.random.default_rng(12)
    u = _grid_strains(rng)
    tr = (u[..., 0, 0] + u[..., 1, 1])[..., None, None]
    d, e = u[..., 0, 0] - u[..., 1, 1], u[..., 0, 1]
    sig = K0 * tr * np.eye(2) + np.zeros_like(u)
    sig[..., 0, 0] += 2 * G0 * (-2 * e) / 2                 # σxx − σyy = 2G (−2 u_xy)
    sig[..., 1, 1] -= 2 * G0 * (-2 * e) / 2
    sig[..., 0, 1] = sig[..., 1, 0] = G0 * d                # 2σxy = 2G (u_xx − u_yy)
    D, S = sig[..., 0, 0] - sig[..., 1, 1], sig[..., 0, 1]
    np.testing.assert_allclose(D * d + 4 * S * e, 0.0, atol=1e-12 * K0 * STRAIN ** 2)
    res = fit_all(sig, u, min_points=3, max_condition=10.0)
    iso = res["isotropic_mask_reason"]
    tried = (iso & FIT_INSUFFICIENT_POINTS) == 0
    assert np.all(iso[tried] & (FIT_ILL_CONDITIONED | FIT_DEGENERATE))
    modulus = FITS.index("modulus")                            # fit of moduli: G ~ 0, K/|G| unbounded
    assert np.all(iso[modulus][tried[modulus]] & FIT_ILL_CONDITIONED)
    assert np.all(res["isotropic_condition"][modulus][tried[modulus]] > 1e6)
    compliance = FITS.index("compliance")                      # fit of compliances: 1/(2G) = 0
    assert np.all(iso[compliance][tried[compliance]] & (FIT_ILL_CONDITIONED | FIT_DEGENERATE))
    assert np.all(np.isnan(res["bulk_modulus"])) and np.all(np.isnan(res["youngs_modulus"]))


def test_s1_close_to_s2_is_ill_conditioned_and_masked():
    """At m = 1 the cubic fit of compliances is exact: s1 − s2 = (u_xx − u_yy)/(σxx − σyy).
    A normal deviatoric strain 1e-3 of the elastic one (its stress and strain
    nearly decorrelated) gives s1 ≈ s2 and λ1 − λ2 = 1/(s1 − s2) 1000 times too
    large: λ1 and G_av become spikes unless the fit is masked as ill-conditioned;
    with exactly no normal deviatoric strain, s1 = s2 and the inversion of
    Eq. 20 is degenerate."""
    from analysis.elastic import FIT_DEGENERATE, FIT_ILL_CONDITIONED

    rng = np.random.default_rng(13)
    u = _grid_strains(rng)
    sig = _stress(u, L1, L2, L3)
    mean = 0.5 * (u[..., 0, 0] + u[..., 1, 1])
    for scale, bit in ((1e-3, FIT_ILL_CONDITIONED), (0.0, FIT_DEGENERATE)):
        v = u.copy()
        half = 0.5 * scale * (u[..., 0, 0] - u[..., 1, 1])
        v[..., 0, 0], v[..., 1, 1] = mean + half, mean - half
        at = (FITS.index("compliance"), POINTS.index(1))
        loose = fit_all(sig, v, max_condition=np.inf)["G_av"][at]
        res = fit_all(sig, v, max_condition=10.0)
        reason = res["cubic_mask_reason"][at]
        assert np.all(reason & bit) and np.all(np.isnan(res["G_av"][at])) and np.all(np.isnan(res["lambda1"][at]))
        if scale:
            assert np.all(res["cubic_condition"][at] > 100)
            assert np.nanmin(np.abs(loose)) > 50 * L1                       # the spike the mask removes


def test_a_negative_modulus_is_masked_as_not_positive_definite():
    """Exact data of unstable laws are fitted exactly and well conditioned, and
    still masked, as not positive definite: isotropic G < 0; cubic λ3 < 0; cubic
    λ2 > λ1 > 0 (both positive, yet λ1 − λ2 < 0). A positive definite law with
    λ2 < 0 (a negative Poisson ratio, λ1 > |λ2|) is kept."""
    from analysis.elastic import FIT_ILL_CONDITIONED, FIT_NOT_POSITIVE

    rng = np.random.default_rng(14)
    u = _grid_strains(rng)
    one = np.s_[:, 0]                                     # m = 1: every RVE has its point
    res = fit_all(_hooke(u, K0, -0.3e6), u, max_condition=10.0)
    assert np.all(res["isotropic_mask_reason"][one] == FIT_NOT_POSITIVE)
    np.testing.assert_allclose(res["isotropic_condition"][one], K0 / 0.3e6, rtol=1e-9)
    assert np.all(np.isnan(res["shear_modulus"][one]))
    for (l1, l2, l3), bad in (((L1, L2, -L3), True), ((L2, L1, L3), True), ((1.0e6, -0.3e6, 0.4e6), False)):
        r = fit_all(_stress(u, l1, l2, l3), u, max_condition=10.0)
        assert not np.any(r["cubic_mask_reason"][one] & FIT_ILL_CONDITIONED)
        if bad:
            assert np.all(r["cubic_mask_reason"][one] == FIT_NOT_POSITIVE) and np.all(np.isnan(r["lambda1"][one]))
        else:
            assert np.all(r["cubic_mask_reason"][one] == 0)
            np.testing.assert_allclose(r["lambda2"][one], l2, rtol=1e-9)


def _piles_dataset(K, G, seed=3):
    """Per-pile fields of exactly isotropic piles of moduli ``K[k]`` and ``G[k]`` (arrays over (y, x) or scalars)."""
    import xarray as xr

    from analysis.netcdf import tensor_coords, var

    coords = {"y": var("y", [0.03, 0.045, 0.06], "y", "m"),
              "x": var("x", [-0.015, 0.0, 0.015, 0.03], "x", "m"), **tensor_coords()}
    piles = []
    for n, (k, g) in enumerate(zip(K, G)):
        u = _sym(np.random.default_rng(seed), (3, 4), STRAIN)
        sigma = _hooke(u, np.asarray(k)[..., None, None], np.asarray(g)[..., None, None])
        pile = xr.Dataset(coords=coords, attrs={"seed": n + 1})
        pile["stress_increment"] = var(("y", "x", "i", "j"), sigma, "dsigma", "N m-1")
        pile["strain_increment"] = var(("y", "x", "i", "j"), u, "u", "1")
        piles.append(pile)
    return piles


def test_the_mean_over_piles_leaves_out_masked_piles_and_is_masked_where_most_fail():
    """Four isotropic piles; one has G < 0 at RVE (0, 1), three have it at RVE
    (2, 3). Where one fails, the mean over piles and its standard error are those
    of the other three; where three fail, too few piles are valid
    (few_valid_piles) and the fit of the ensemble mean is not positive definite."""
    from analysis.elastic import FIT_FEW_PILES, FIT_NOT_POSITIVE, moduli_dataset
    from analysis.params import resolve_params

    G = [np.full((3, 4), g) for g in (1.0e6, 1.2e6, 0.9e6, 1.1e6)]
    K = [3.0e6] * 4
    G[3][0, 1] = -0.5e6
    for k in (0, 1, 2):
        G[k][2, 3] = -0.4e6
    piles = _piles_dataset(K, G)
    ensemble = (sum(piles) / 4).assign_attrs(n_seeds=4, protocol="wedge")
    ds = moduli_dataset(ensemble, piles, resolve_params({"moduli": {"min_points": 1}})).sel(fit="modulus", points=1)
    g = np.array([1.0e6, 1.2e6, 0.9e6])
    assert ds["shear_modulus_pile_mean"].values[0, 1] == pytest.approx(g.mean(), rel=1e-9)
    assert ds["shear_modulus_sem"].values[0, 1] == pytest.approx(np.std(g, ddof=1) / np.sqrt(3), rel=1e-9)
    assert ds["isotropic_n_piles"].values[0, 1] == 3
    assert ds["isotropic_mask_reason_piles"].values[3, 0, 1] == FIT_NOT_POSITIVE
    assert ds["isotropic_mask_reason_pile_mean"].values[2, 3] == FIT_FEW_PILES
    assert np.isnan(ds["shear_modulus_pile_mean"].values[2, 3]) and np.isnan(ds["bulk_modulus_sem"].values[2, 3])
    # the ensemble mean's G = (3 (−0.4) + 1.1)/4 = −0.025e6: not positive definite (and ill-conditioned)
    assert ds["isotropic_mask_reason"].values[2, 3] & FIT_NOT_POSITIVE and np.isnan(ds["bulk_modulus"].values[2, 3])
    ok = np.ones((3, 4), bool)
    ok[0, 1] = ok[2, 3] = False
    np.testing.assert_allclose(ds["shear_modulus_pile_mean"].values[ok], 1.05e6, rtol=1e-9)
    assert np.all(ds["isotropic_n_piles"].values[ok] == 4)


def test_fig4_draws_no_masked_value_and_labels_only_drawn_heights(tmp_path, monkeypatch):
    """Fig. 4 of piles whose top row is unstable in every pile: no line holds a
    value of a masked RVE, the top row has no legend entry, and the shared
    scale is set by the values drawn."""
    from analysis import figures
    from analysis.elastic import moduli_dataset
    from analysis.params import resolve_params

    G = [np.full((3, 4), g) for g in (1.0e6, 1.2e6, 0.9e6)]
    for g in G:
        g[2] = -0.5e6
    piles = _piles_dataset([3.0e6] * 3, G)
    mod = moduli_dataset((sum(piles) / 3).assign_attrs(n_seeds=3, protocol="wedge"), piles,
                         resolve_params({"moduli": {"min_points": 1}}))
    drawn = {}
    monkeypatch.setattr(figures, "save", lambda fig, outputs, dpi=150: drawn.setdefault("fig", fig))
    figures.fig_moduli(mod, [0.03, 0.045, 0.06], [str(tmp_path / "f.png")])
    ax = drawn["fig"].axes[0]                                   # isotropic K
    labels = ax.get_legend_handles_labels()[1]
    assert [lab.split(" (")[0] for lab in labels] == ["y = 3.0 cm", "y = 4.5 cm"]
    masked = mod["isotropic_mask_reason_pile_mean"].sel(fit="modulus", points=1).values != 0
    assert masked[2].all() and not masked[:2].any()
    iso = mod.sel(fit="modulus", points=1)
    kept = np.concatenate([iso[name].values[:2].ravel() for name in ("bulk_modulus", "bulk_modulus_pile_mean")])
    drawn_values = []
    for line in ax.get_lines():
        y = np.asarray(line.get_ydata(), float)
        y = y[np.isfinite(y) & (y != 0)]                        # the zero line left out
        assert np.all(np.isin(np.round(y), np.round(kept))), "a value of no kept RVE is drawn"
        drawn_values.append(y)
    assert np.concatenate(drawn_values).size == 2 * 2 * 4       # two rows, mean over piles and ensemble fit
    everything = [np.asarray(line.get_ydata(), float) for a in drawn["fig"].axes for line in a.get_lines()]
    top = max(np.nanmax(y) for y in everything if np.isfinite(y).any())
    lo, hi = ax.get_ylim()
    assert drawn["fig"].axes[5].get_ylim() == (lo, hi)         # one scale for all panels
    assert lo <= 0 and top < hi < 1.25 * top
