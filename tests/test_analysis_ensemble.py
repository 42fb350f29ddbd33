"""Seed averages: means, standard errors and counts against numpy; NaN handling; grid checks."""

import numpy as np
import pytest
import xarray as xr

from analysis.ensemble import ensemble_fields
from analysis.errors import InputError
from analysis.fields import derived_fields
from analysis.netcdf import tensor_coords, var


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


def test_derived_fields_recomputed_from_mean_tensors():
    rng = np.random.default_rng(2)
    piles = [_pile(rng) for _ in range(3)]
    ens = ensemble_fields(piles)
    F = np.mean([p["fabric"].values for p in piles], axis=0)
    np.testing.assert_allclose(ens["fabric_trace"].values, F[..., 0, 0] + F[..., 1, 1])
    assert "fabric_orientation_sem" in ens and "stress_fabric_angle_sem" in ens


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
