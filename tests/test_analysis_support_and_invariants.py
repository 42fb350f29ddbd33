"""Base pressure (forces on the support), invariants (Sect. 6), convergence data and figures."""

import numpy as np
import pytest
import xarray as xr
from synthetic_states import as_state, displaced, make_state, square_nodes, step_pyramid

from analysis.base_pressure import base_pressure_dataset, combine_base_pressure, support_force_density
from analysis.errors import InputError
from analysis.convergence import convergence_dataset
from analysis.figures import fig_base_pressure, fig_convergence
from analysis.invariants import invariants_dataset
from analysis.netcdf import tensor_coords, var
from analysis.params import resolve_params

A = 0.006


def test_support_forces_integrate_to_the_weight_and_sign_of_shear():
    s = step_pyramid(61, A, slope=0.6)
    # friction from the support pushes particles towards the axis: force_x < 0 for x > 0
    sup = s["contact_j"] < 0
    s["force_x"] = np.where(sup, -np.sign(s["contact_x"]) * 0.1, 0.0)
    st = as_state(s)
    params = resolve_params({"base_pressure": {"x_min": -0.3, "x_max": 0.3, "bin_width": 0.012}})
    ds = base_pressure_dataset([st, st], params)
    w = params["base_pressure"]["bin_width"]
    M = st.mass.sum()
    assert ds["normal_force_density"].sum() * w == pytest.approx(M * 9.81, rel=1e-12)
    right = ds["x"].values > 0.01
    assert np.all(ds["shear_force_density"].values[right & (ds["normal_force_density"].values > 0)] > 0)
    # hand value in one bin: columns of h squares push with h m g each
    n, _ = support_force_density(st, np.array([-A / 2, A / 2]))  # one bin holding the central column
    h0 = np.sum(np.abs(st.x) < A / 2)
    assert n[0] * A == pytest.approx(h0 * st.mass[0] * 9.81)
    # identical piles: zero standard error
    assert np.allclose(ds["normal_force_density_sem"].values, 0)


def test_ensemble_of_per_pile_files_equals_the_ensemble_of_their_states():
    """The workflow keeps one base_pressure file per pile and combines them; the
    result must be the ensemble computed from the states themselves: mean and
    standard error over the piles, each pile still integrating to its weight."""
    params = resolve_params({"base_pressure": {"x_min": -0.3, "x_max": 0.3, "bin_width": 0.012}})
    states = []
    for seed, (n, slope) in enumerate([(41, 0.6), (51, 0.5), (61, 0.7)]):
        s = step_pyramid(n, A, slope=slope)
        s["attrs"]["seed"] = seed
        states.append(as_state(s))
    piles = [base_pressure_dataset([st], params) for st in states]
    combined = combine_base_pressure(piles, ["a", "b", "c"], params)
    direct = base_pressure_dataset(states, params)
    for v in direct.data_vars:
        np.testing.assert_array_equal(combined[v].values, direct[v].values, err_msg=v)
    assert combined.attrs["n_seeds"] == 3
    w = params["base_pressure"]["bin_width"]
    per_pile = combined["normal_force_density_per_seed"].sum("x").values * w
    np.testing.assert_allclose(per_pile, [st.mass.sum() * 9.81 for st in states], rtol=1e-12)
    other = resolve_params({"base_pressure": {"x_min": -0.3, "x_max": 0.3, "bin_width": 0.02}})
    with pytest.raises(InputError, match="b: its x bins differ"):
        combine_base_pressure([piles[0], base_pressure_dataset([states[1]], other)], ["a", "b"], params)


def _ens(ts, tu, depth):
    ny, nx = depth.shape
    coords = {"y": var("y", np.arange(ny) * 0.01, "y", "m"), "x": var("x", np.arange(nx) * 0.01, "x", "m"),
              **tensor_coords()}
    si = np.zeros((ny, nx, 2, 2))
    si[..., 0, 0] = si[..., 1, 1] = ts / 2
    ui = np.zeros((ny, nx, 2, 2))
    ui[..., 0, 0] = ui[..., 1, 1] = tu / 2
    return xr.Dataset({"stress_increment": var(("y", "x", "i", "j"), si, "s", "N m-1"),
                       "strain_increment": var(("y", "x", "i", "j"), ui, "u", "1"),
                       "depth": var(("y", "x"), depth, "d", "m")}, coords=coords)


def test_invariants_recover_a_constant_bulk_modulus():
    K = 2.0e5
    depth = np.linspace(0.005, 0.2, 40).reshape(8, 5)
    tu = 1e-3 * depth  # strain grows with depth
    ts = 2 * K * tu + 3.0  # affine: differential 2K, secant differs
    ds = invariants_dataset(_ens(ts, tu, depth), resolve_params({"invariants": {"depth_bin": 0.02}}))
    kd = ds["differential_bulk_modulus"].values
    assert np.nanmax(np.abs(kd - K)) < 1e-6 * K
    ks = ds["secant_bulk_modulus"].values
    ok = np.isfinite(ks)
    np.testing.assert_allclose(ks[ok], ds["mean_trace_stress_increment"].values[ok] /
                               (2 * ds["mean_trace_strain_increment"].values[ok]))
    assert int(ds["n_rve"].sum()) == 40


def test_invariants_zero_strain_slope_is_nan_not_inf():
    depth = np.linspace(0.005, 0.2, 40).reshape(8, 5)
    ds = invariants_dataset(_ens(np.ones_like(depth), np.zeros_like(depth), depth), resolve_params({}))
    assert not np.isinf(ds["differential_bulk_modulus"].values).any()
    assert not np.isinf(ds["secant_bulk_modulus"].values).any()


def test_convergence_dataset_and_figures(tmp_path):
    s = step_pyramid(61, A, slope=0.6)
    du = np.column_stack([1e-6 * s["x"], 2e-5 * s["y"]])
    relaxed, reduced = as_state(s), as_state(displaced(s, du, 0.9, 0.9 * 9.81))
    params = resolve_params({"convergence": {"points": [[0.0, 0.05], [0.03, 0.04]], "sizes": [0.01, 0.03, 0.06]}})
    ds = convergence_dataset(relaxed, reduced, params)
    assert ds["stress"].dims == ("rve_size", "point", "i", "j")
    n = ds["n_particles"].values
    assert np.all(np.diff(n, axis=0) >= 0)  # bigger RVEs hold more particles
    # strain of an affine field is exact at every size with a well-conditioned fit
    ok = ds["strain_flag"].values == 0
    assert ok.sum() >= 3
    np.testing.assert_allclose(ds["displacement_gradient"].values[ok][:, 1, 1], 2e-5, rtol=1e-9)
    fig_convergence(ds, [str(tmp_path / "c.png"), str(tmp_path / "c.pdf")])
    bp = base_pressure_dataset([relaxed], params)
    fig_base_pressure({"wedge": bp, "layered": bp}, [str(tmp_path / "b.png")])
    assert (tmp_path / "c.png").stat().st_size > 1000 and (tmp_path / "c.pdf").exists()
    assert (tmp_path / "b.png").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.png", "c.pdf", "c.png"]
