"""Seed averages: means, standard errors and counts against numpy; NaN handling; grid checks;
pile-RVEs left out where a pile slipped under the probe (analysis.ensemble.slip_strain_ratio)."""

import numpy as np
import pytest
import xarray as xr

from analysis.__main__ import main
from analysis.ensemble import ensemble_fields, slipped
from analysis.errors import InputError, ParamError
from analysis.fields import PROBE_RESPONSE, derived_fields
from analysis.netcdf import tensor_coords, var
from analysis.params import resolve_params


def _pile(rng, ny=4, nx=5, nan_at=None, x_shift=0.0):
    coords = {"y": var("y", 0.015 * (1 + np.arange(ny)), "y", "m"),
              "x": var("x", x_shift + 0.015 * (np.arange(nx) - 2), "x", "m"), **tensor_coords()}
    ds = xr.Dataset(coords=coords)
    for name in ("stress", "stress_reduced", "stress_increment", "displacement_gradient", "strain_increment",
                 "fabric"):
        a = rng.standard_normal((ny, nx, 2, 2))
        if name != "displacement_gradient":
            a = 0.5 * (a + np.swapaxes(a, -1, -2))
        if name == "fabric":
            a = a * 0.1 + 2 * np.eye(2)
        if nan_at is not None:
            a[nan_at] = np.nan
        ds[name] = var(("y", "x", "i", "j"), a, name, "1")
    ds["n_particles"] = var(("y", "x"), rng.integers(80, 200, (ny, nx)), "n", "1")
    ds["solid_fraction"] = var(("y", "x"), rng.uniform(0.7, 0.9, (ny, nx)), "sf", "1")
    ds["mask_reason"] = var(("y", "x"), np.zeros((ny, nx), np.int32), "mask", "1")
    ds["surface_height"] = var("x", rng.uniform(0.2, 0.3, nx), "h", "m")
    derived_fields(ds)
    ds.attrs.update({"rve_shape": "square", "rve_size": 0.08, "seed": "0"})
    return ds


def test_mean_sem_count_against_numpy_with_nans():
    rng = np.random.default_rng(0)
    piles = [_pile(rng), _pile(rng, nan_at=(1, 2)), _pile(rng, nan_at=(1, 2)), _pile(rng, nan_at=(0, 0))]
    ens = ensemble_fields(piles)
    assert ens.attrs["n_seeds"] == 4
    assert ens["stress"].attrs["cell_methods"] == "seed: mean"
    for name in ("stress", "strain_increment", "solid_fraction", "n_particles", "surface_height"):
        st = np.stack([p[name].values.astype(float) for p in piles])
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(st, axis=0)
            cnt = np.sum(np.isfinite(st), axis=0)
            sem = np.nanstd(st, axis=0, ddof=1) / np.sqrt(cnt)
        np.testing.assert_allclose(ens[name].values, mean, rtol=1e-12)
        np.testing.assert_allclose(ens[f"{name}_sem"].values, sem, rtol=1e-12)
        np.testing.assert_array_equal(ens[f"{name}_count"].values, cnt)
    # at (1, 2) only two piles count
    assert int(ens["stress_count"].values[1, 2, 0, 0]) == 2
    mean12 = 0.5 * (piles[0]["stress"].values[1, 2] + piles[3]["stress"].values[1, 2])
    np.testing.assert_allclose(ens["stress"].values[1, 2], mean12)


def test_all_nan_gives_nan_and_single_value_has_no_sem():
    rng = np.random.default_rng(1)
    piles = [_pile(rng, nan_at=(0, 0)) for _ in range(3)]
    piles[0]["stress"].values[2, 2] = np.nan
    piles[1]["stress"].values[2, 2] = np.nan
    ens = ensemble_fields(piles)
    assert np.all(np.isnan(ens["stress"].values[0, 0])) and np.all(ens["stress_count"].values[0, 0] == 0)
    assert np.all(ens["stress_count"].values[2, 2] == 1) and np.all(np.isnan(ens["stress_sem"].values[2, 2]))
    assert np.all(np.isfinite(ens["stress"].values[2, 2]))


def _axis_from_vertical(t, which):
    """Angle (deg) from +y, counter-clockwise, in (-90, 90], of the principal axis
    of the largest (``which = -1``) or smallest (0) eigenvalue, by numpy's eigh."""
    _, vec = np.linalg.eigh(0.5 * (t + np.swapaxes(t, -1, -2)))
    v = vec[..., :, which]
    ang = np.degrees(np.arctan2(-v[..., 0], v[..., 1]))  # +y turned by ang is v
    ang = (ang + 90.0) % 180.0 - 90.0
    return np.where(ang == -90.0, 90.0, ang)


def test_derived_fields_recomputed_from_mean_tensors():
    """Each derived field of the ensemble is that of the seed-mean tensors, by hand:
    the trace and (l_max - l_min) / (l_max + l_min) of the mean fabric from
    numpy's eigenvalues; the axes of the mean fabric, stress increment and
    strain (largest eigenvalue) and of the mean stress (smallest: most
    compressive) from its eigenvectors; the stress-fabric angle their
    difference.  None but the (linear) trace is the seed average of the
    per-pile values."""
    rng = np.random.default_rng(2)
    piles = [_pile(rng) for _ in range(3)]
    ens = ensemble_fields(piles)
    mean = {k: np.mean([p[k].values for p in piles], axis=0)
            for k in ("fabric", "stress", "stress_increment", "strain_increment")}
    lam = np.linalg.eigvalsh(mean["fabric"])
    stress_axis = _axis_from_vertical(mean["stress"], 0)
    fabric_axis = _axis_from_vertical(mean["fabric"], -1)
    hand = {
        "fabric_trace": lam[..., 0] + lam[..., 1],
        "fabric_deviatoric_fraction": (lam[..., 1] - lam[..., 0]) / (lam[..., 1] + lam[..., 0]),
        "fabric_orientation": fabric_axis,
        "stress_orientation": stress_axis,
        "stress_increment_orientation": _axis_from_vertical(mean["stress_increment"], -1),
        "strain_orientation": _axis_from_vertical(mean["strain_increment"], -1),
        "stress_fabric_angle": (stress_axis - fabric_axis + 90.0) % 180.0 - 90.0,
    }
    for name, value in hand.items():
        got = ens[name].values
        if name in ("fabric_trace", "fabric_deviatoric_fraction"):
            np.testing.assert_allclose(got, value, rtol=1e-10, err_msg=name)
        else:  # axis angles: equal modulo 180 degrees
            np.testing.assert_allclose((got - value + 90.0) % 180.0 - 90.0, 0.0, atol=1e-8,
                                       err_msg=name)
            assert np.all((-90.0 < got) & (got <= 90.0)), name
        if name != "fabric_trace":  # the trace is linear: the same either way
            off = got - np.mean([p[name].values for p in piles], axis=0)
            assert np.max(np.abs((off + 90.0) % 180.0 - 90.0)) > 1e-2 * np.max(np.abs(value)), name
        assert f"{name}_sem" in ens


def test_different_grids_are_refused():
    rng = np.random.default_rng(3)
    with pytest.raises(InputError, match="x grid"):
        ensemble_fields([_pile(rng), _pile(rng, x_shift=0.001)], ["a.nc", "b.nc"])
    other = _pile(rng)
    other.attrs["rve_size"] = 0.1
    with pytest.raises(InputError, match="rve_size"):
        ensemble_fields([_pile(rng), other], ["a.nc", "b.nc"])


def test_standard_errors_of_derived_fields_come_from_the_per_seed_values():
    rng = np.random.default_rng(4)
    piles = [_pile(rng) for _ in range(5)]
    ens = ensemble_fields(piles)
    for name in ("fabric_trace", "fabric_deviatoric_fraction"):
        st = np.stack([p[name].values for p in piles])
        np.testing.assert_allclose(ens[f"{name}_sem"].values,
                                   np.std(st, axis=0, ddof=1) / np.sqrt(len(piles)), rtol=1e-12)
    # an angle's spread is taken about the mean axis, folded into (-90, 90] deg
    same = [_pile(np.random.default_rng(5)) for _ in range(3)]
    np.testing.assert_allclose(ensemble_fields(same)["stress_orientation_sem"].values, 0.0, atol=1e-9)
    assert np.all(ens["stress_orientation_sem"].values > 0.0)


# --- slips under the probe ----------------------------------------------------

SLIP = [(0, 1), (2, 3), (3, 4)]  # RVEs (y, x) where the last pile slipped


def _elastic_pile(rng, slip_at=(), factor=100.0):
    """A pile with strain increments of the elastic size (1e-4, within a factor
    of about 3 of each other) and, at ``slip_at``, ``factor`` times larger
    probe responses (strain, displacement gradient, stress increment)."""
    ds = _pile(rng)
    scale = {"strain_increment": 1e-4, "displacement_gradient": 1e-4, "stress_increment": 1.0,
             "stress_reduced": 1.0}
    for name, s in scale.items():
        a = s * (1.0 + 0.3 * rng.standard_normal(ds[name].shape))
        for at in slip_at:
            a[at] *= factor
        ds[name].values[...] = a
    derived_fields(ds)
    return ds


def _mean_sem(piles, name):
    """Mean, standard error (ddof=1) and count over ``piles`` with numpy alone."""
    st = np.stack([p[name].values for p in piles])
    return st.mean(axis=0), st.std(axis=0, ddof=1) / np.sqrt(len(piles)), len(piles)


def test_a_slipped_pile_is_left_out_of_the_probe_response_there_and_only_there():
    rng = np.random.default_rng(10)
    piles = [_elastic_pile(rng) for _ in range(3)] + [_elastic_pile(rng, slip_at=SLIP)]
    ens = ensemble_fields(piles, slip_strain_ratio=10.0)
    at = np.zeros((4, 5), bool)
    at[tuple(zip(*SLIP))] = True
    for name in ("strain_increment", "stress_increment", "displacement_gradient", "stress_reduced"):
        kept_mean, kept_sem, _ = _mean_sem(piles[:3], name)
        all_mean, all_sem, _ = _mean_sem(piles, name)
        np.testing.assert_allclose(ens[name].values[at], kept_mean[at], rtol=1e-12)
        np.testing.assert_allclose(ens[f"{name}_sem"].values[at], kept_sem[at], rtol=1e-12)
        np.testing.assert_allclose(ens[name].values[~at], all_mean[~at], rtol=1e-12)
        np.testing.assert_allclose(ens[f"{name}_sem"].values[~at], all_sem[~at], rtol=1e-12)
        np.testing.assert_array_equal(ens[f"{name}_count"].values[..., 0, 0], np.where(at, 3, 4))
    # the derived orientation of the strain counts the kept piles; the stress at full gravity all four
    np.testing.assert_array_equal(ens["strain_orientation_count"].values, np.where(at, 3, 4))
    np.testing.assert_allclose(ens["stress"].values, _mean_sem(piles, "stress")[0], rtol=1e-12)
    np.testing.assert_array_equal(ens["slip_left_out"].values, at.astype(int))
    assert ens.attrs["slip_left_out_total"] == len(SLIP)
    assert ens.attrs["slip_left_out_per_seed"] == f"0,0,0,{len(SLIP)}"


def test_the_standard_error_counts_only_the_piles_kept():
    """At an RVE where one pile slipped and another is masked, one pile is
    left: its value is the mean, and there is no standard error."""
    rng = np.random.default_rng(11)
    piles = [_elastic_pile(rng) for _ in range(2)] + [_elastic_pile(rng, slip_at=[(1, 1)])]
    piles[0]["strain_increment"].values[1, 1] = np.nan
    ens = ensemble_fields(piles, slip_strain_ratio=10.0)
    np.testing.assert_allclose(ens["strain_increment"].values[1, 1], piles[1]["strain_increment"].values[1, 1])
    assert np.all(ens["strain_increment_count"].values[1, 1] == 1)
    assert np.all(np.isnan(ens["strain_increment_sem"].values[1, 1]))
    assert int(ens["slip_left_out"].values[1, 1]) == 1 and ens.attrs["slip_left_out_total"] == 1


def test_without_a_threshold_every_pile_counts_and_clean_piles_are_untouched():
    rng = np.random.default_rng(12)
    clean = [_elastic_pile(rng) for _ in range(3)]
    slipping = clean + [_elastic_pile(rng, slip_at=SLIP)]
    plain = ensemble_fields(slipping, slip_strain_ratio=None)
    mean, sem, _ = _mean_sem(slipping, "strain_increment")
    np.testing.assert_allclose(plain["strain_increment"].values, mean, rtol=1e-12)
    np.testing.assert_allclose(plain["strain_increment_sem"].values, sem, rtol=1e-12)
    assert plain.attrs["slip_left_out_total"] == 0 and not plain["slip_left_out"].values.any()
    robust, off = ensemble_fields(clean), ensemble_fields(clean, slip_strain_ratio=None)
    assert robust.attrs["slip_left_out_total"] == 0
    present = [name for name in PROBE_RESPONSE if name in off]
    assert len(present) == 6  # all but strain_residual, which _pile has not
    for name in present:
        np.testing.assert_array_equal(robust[name].values, off[name].values)


def test_slipped_compares_the_strain_magnitude_with_the_pile_median():
    """|u| = |a| for u = diag(a, 0); the median of the finite RVEs is 1e-4."""
    a = np.array([[1.0, 1.0, 1.0], [1.0, 9.9, 10.1], [np.nan, -10.5, 1.0]]) * 1e-4
    u = np.zeros(a.shape + (2, 2))
    u[..., 0, 0] = a
    np.testing.assert_array_equal(slipped(u, 10.0), [[False] * 3, [False, False, True], [False, True, False]])
    assert not slipped(u, None).any()
    assert not slipped(np.full((2, 2, 2, 2), np.nan), 10.0).any()


@pytest.mark.parametrize("value,allowed", [(-1.0, "> 1"), (1, "> 1"), (0.5, "> 1"),
                                           (float("nan"), "finite number or null"),
                                           ("ten", "finite number or null"), (True, "finite number or null"),
                                           ([10], "finite number or null")])
def test_bad_slip_ratio_is_refused_naming_setting_value_and_what_is_allowed(value, allowed):
    with pytest.raises(ParamError) as err:
        resolve_params({"ensemble": {"slip_strain_ratio": value}})
    assert "analysis.ensemble.slip_strain_ratio" in str(err.value)
    assert repr(value) in str(err.value) and allowed in str(err.value)


def test_the_command_line_refuses_a_bad_slip_ratio_before_reading(capsys):
    rc = main(["ensemble", "--fields", "missing.nc", "--out", "x.nc",
               "--params", '{"ensemble": {"slip_strain_ratio": -2}}'])
    err = capsys.readouterr().err
    assert rc == 2 and "analysis.ensemble.slip_strain_ratio = -2 must be > 1" in err
