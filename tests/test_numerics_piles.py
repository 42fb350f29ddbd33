"""Numerics of whole piles (analysis/numerics/: pile_precision.py, ensemble_cost.py,
piles_report.py, run_times.py, figures.py; workflow/rules/numerics_piles.smk): the error estimator on
synthetic data with a known dt^p error and seed noise, the 1/sqrt(n) law of
the standard error, the profile-norm and dip-depth definitions on hand-built
profiles, the moduli read at the core, CPU-time files, and (slow) the target
run for real on tiny piles.
"""

import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
import yaml

from analysis.numerics.ensemble_cost import (check_params as check_ensemble_params, core_moduli, dip_depth,
                                    piles_needed, standard_error_curve)
from analysis.numerics.pile_precision import (RESOLVED, check_params, convergence_order, profile_edges, profile_error,
                                     scalar_error)
from analysis.run_times import children_cpu_time
from test_workflow import REPO, copy_workflow, job_counts, snakemake

PILES = {"integrators": ["gear", "verlet"], "dt_factors": [1.0, 0.5], "seeds": [1, 2],
         "reference_integrator": "gear", "bin_width": 0.01, "half_width": 0.05,
         "solid_fraction_window": 0.02, "solid_fraction_height": 0.01, "solid_fraction_half_width": 0.02}
ENSEMBLE = {"core": [0.0, 0.02], "points": 5, "fit": "average", "dip_half_width": 0.01,
            "relative_targets": [0.1, 0.05]}


def _observable(rng, dt, seeds, p, c=30.0, base=30.0, sigma=0.5):
    """Per-seed values of an observable whose mean is base + c dt^p (dt in units of the auto step)."""
    return base + c * dt ** p + sigma * rng.standard_normal(seeds)


@pytest.mark.parametrize("p", [1.0, 2.0])
def test_error_estimator_recovers_a_known_dt_power(p):
    rng = np.random.default_rng(7)
    seeds, ref_dt = 400, 1.0 / 64  # a reference whose own dt^p error is negligible
    ref = _observable(rng, ref_dt, seeds, p)
    dts = np.array([1.0, 0.5, 0.25, 0.125])
    errors, bars = zip(*(scalar_error(_observable(rng, dt, seeds, p), ref) for dt in dts))
    errors, bars = np.array(errors), np.array(bars)
    truth = 30.0 * (dts ** p - ref_dt ** p)
    # the error bar is the combined standard error of two means of 400 seeds with sd 0.5
    assert bars == pytest.approx(0.5 * np.sqrt(2 / seeds), rel=0.15)
    assert np.all(np.abs(errors - truth) < 4 * bars)
    assert convergence_order(dts, errors, bars) == pytest.approx(p, abs=0.15)


def test_unresolved_errors_are_left_out_of_the_order():
    dts = np.array([1.0, 0.5, 0.25, 0.125])
    bars = np.full(4, 0.01)
    errors = np.array([0.8, 0.2, 0.05, 0.015])  # p = 2 down to 0.25; the last is within 2 bars
    assert errors[-1] <= RESOLVED * bars[-1]
    assert convergence_order(dts, errors, bars) == pytest.approx(2.0, abs=1e-9)
    assert np.isnan(convergence_order(dts, np.array([0.8, 0.01, 0.01, 0.01]), bars))


def test_scalar_error_is_nan_without_two_seeds_on_each_side():
    error, bar = scalar_error(np.array([1.0, np.nan]), np.array([2.0, 3.0]))
    assert error == pytest.approx(1.5) and np.isnan(bar)


def test_profile_norm_on_hand_built_profiles():
    ref = np.ones((2, 4))
    # identical seeds: no scatter; the mean differs by 2 in one bin of a profile of norm 2
    assert profile_error(np.array([[1, 1, 1, 3], [1, 1, 1, 3.0]]), ref) == pytest.approx((1.0, 0.0))
    # seeds 1 and 3 in bin 0: mean 2 (distance 1), standard error 1, both over ||ref|| = 2
    assert profile_error(np.array([[1, 1, 1, 1], [3, 1, 1, 1.0]]), ref) == pytest.approx((0.5, 0.5))
    with pytest.raises(ValueError, match="reference base pressure profile is zero"):
        profile_error(ref, np.zeros((2, 4)))


def test_profile_bins_are_symmetric_about_the_axis():
    edges = profile_edges(0.05, 0.02)
    assert edges == pytest.approx([-0.06, -0.04, -0.02, 0, 0.02, 0.04, 0.06])


def test_dip_depth_on_hand_built_profiles():
    x = np.array([-0.03, -0.01, 0.01, 0.03])
    assert dip_depth(x, np.array([2.0, 1.0, 1.0, 2.0]), 0.02) == pytest.approx(0.5)
    assert dip_depth(x, np.array([1.0, 2.0, 2.0, 1.0]), 0.02) == pytest.approx(0.0)  # a peak at the centre
    assert dip_depth(x, np.array([2.0, 1.0, 1.0, 2.0]), 0.04) == pytest.approx(0.25)  # all four bins
    with pytest.raises(ValueError, match=r"numerics.ensemble.dip_half_width = 0.005"):
        dip_depth(x, np.ones(4), 0.005)


def test_standard_error_falls_as_one_over_sqrt_n():
    rng = np.random.default_rng(3)
    sigma, n_max, repeats = 2.0, 10, 4000
    se = np.array([standard_error_curve(rng.normal(5.0, sigma, n_max))[1] for _ in range(repeats)])
    n = np.arange(1, n_max + 1)
    assert np.all(np.isnan(se[:, 0]))  # one pile has no standard error
    # n SE_n^2 is the sample variance, an unbiased estimate of sigma^2 at every n
    assert np.mean(n[1:] * se[:, 1:] ** 2, axis=0) == pytest.approx(np.full(n_max - 1, sigma ** 2), rel=0.05)


def test_piles_needed_from_the_scatter():
    values = np.array([9.0, 11.0])  # mean 10, sd sqrt(2)
    assert piles_needed(values, 0.05) == 8  # (sqrt(2) / 0.5)^2
    assert piles_needed(values, 0.5) == 2  # never fewer than two
    assert piles_needed(np.array([1.0, np.nan]), 0.1) == 0  # undetermined


def _fields(K, G, nx=5, ny=4, spacing=0.01):
    rng = np.random.default_rng(1)
    a = rng.standard_normal((ny, nx, 2, 2)) * 1e-4
    u = 0.5 * (a + np.swapaxes(a, -1, -2))
    s = np.empty_like(u)
    s[..., 0, 0] = (K + G) * u[..., 0, 0] + (K - G) * u[..., 1, 1]
    s[..., 1, 1] = (K - G) * u[..., 0, 0] + (K + G) * u[..., 1, 1]
    s[..., 0, 1] = s[..., 1, 0] = 2 * G * u[..., 0, 1]
    dims = ("y", "x", "i", "j")
    return xr.Dataset({"stress_increment": (dims, s), "strain_increment": (dims, u)},
                      coords={"x": spacing * (np.arange(nx) - nx // 2), "y": spacing * (1 + np.arange(ny))})


@pytest.mark.parametrize("points", [1, 5])
def test_core_moduli_recover_an_isotropic_material(points):
    K, G = core_moduli(_fields(2.0e6, 0.7e6), (0.0, 0.02), points, "average", 3, 1e-12)
    assert (K, G) == pytest.approx((2.0e6, 0.7e6), rel=1e-9)
    with pytest.raises(ValueError, match=r"numerics.ensemble.core = \[0.0, 0.5\]: outside the analysis grid"):
        core_moduli(_fields(2.0e6, 0.7e6), (0.0, 0.5), points, "average", 3, 1e-12)


@pytest.mark.parametrize("change, message", [
    ({"reference_integrator": "verlet", "integrators": ["gear"]}, "numerics.piles.reference_integrator = 'verlet'"),
    ({"seeds": [1]}, r"numerics.piles.seeds = \[1\]: need at least 2"),
    ({"dt_factors": [1.0, 2.0]}, r"numerics.piles.dt_factors = \[1.0, 2.0\]"),
])
def test_bad_pile_settings_are_named(change, message):
    with pytest.raises(ValueError, match=message):
        check_params({**PILES, **change})


@pytest.mark.parametrize("change, message", [
    ({"points": 3}, r"numerics.ensemble.points = 3: must be one of \[1, 5\]"),
    ({"fit": "best"}, "numerics.ensemble.fit = 'best'"),
    ({"relative_targets": [0.1, 1.5]}, "numerics.ensemble.relative_targets"),
])
def test_bad_ensemble_settings_are_named(change, message):
    with pytest.raises(ValueError, match=message):
        check_ensemble_params({**ENSEMBLE, **change})


def test_cpu_time_from_bash_times(tmp_path):
    (tmp_path / "t").write_text("0m0.002s 0m0.001s\n1m2.500s 0m0.500s\n")
    assert children_cpu_time(tmp_path / "t") == pytest.approx(63.0)
    busy = f"{sys.executable} -c 'sum(i * i for i in range(3_000_000))'"
    subprocess.run(["bash", "-c", f"{busy}; times > {tmp_path / 'real'}"], check=True)
    assert 0.05 < children_cpu_time(tmp_path / "real") < 30
    (tmp_path / "bad").write_text("12.5\n")
    with pytest.raises(ValueError, match="not the output of bash 'times'"):
        children_cpu_time(tmp_path / "bad")


CI_CONFIG = REPO / "config" / "numerics_piles_ci.yaml"


def test_dry_run_lists_one_job_per_pile_and_stage(tmp_path):
    root = copy_workflow(tmp_path / "wf")
    cfg = yaml.safe_load(CI_CONFIG.read_text())
    proc = snakemake(root, "-n", "--cores", "1", "--configfile", "config/numerics_piles_ci.yaml",
                     "--replace-workflow-config", "numerics_piles")
    assert proc.returncode == 0, proc.output[-5000:]
    p = cfg["numerics"]["piles"]
    piles = len(p["integrators"]) * len(p["dt_factors"]) * len(p["seeds"])
    counts = job_counts(proc.output)
    assert counts["numerics_pile_pour"] == counts["numerics_pile_relax"] == piles
    assert counts["pour"] == counts["probe"] == len(cfg["protocols"]["wedge"]["seeds"])
    bad = snakemake(root, "-n", "--cores", "1", "--configfile", "config/numerics_piles_ci.yaml",
                    "--replace-workflow-config", "numerics_piles", "--config",
                    "numerics={'piles': {'integrators': ['verlet'], 'reference_integrator': 'gear'}}")
    assert bad.returncode != 0
    assert "numerics.piles.reference_integrator = 'gear' is not in numerics.piles.integrators" in bad.output


@pytest.mark.slow
def test_numerics_piles_target_on_tiny_piles(tmp_path):
    """config/numerics_piles_ci.yaml for real: tiny piles, 2 dt factors, 2 seeds, both integrators."""
    root = copy_workflow(tmp_path / "wf")
    cfg = yaml.safe_load(CI_CONFIG.read_text())
    proc = snakemake(root, "--cores", "2", "--configfile", "config/numerics_piles_ci.yaml",
                     "--replace-workflow-config", "numerics_piles", "--show-failed-logs", timeout=1200)
    assert proc.returncode == 0, proc.output[-20000:]
    p = cfg["numerics"]["piles"]
    with xr.open_dataset(root / "results/numerics_piles_ci/numerics/piles.nc") as ds:
        assert ds.sizes == {"integrator": 2, "dt_factor": 2, "seed": 2, "x": ds.sizes["x"]}
        for attr in ("Conventions", "title", "source", "history", "config"):
            assert ds.attrs[attr]
        assert all("units" in v.attrs and "long_name" in v.attrs for v in ds.variables.values())
        dt = ds["dt"].sel(dt_factor=[1.0, 0.5]).values
        # the rules set the step to the factor times each pile's automatic step
        assert dt[:, 1] == pytest.approx(0.5 * dt[:, 0], rel=1e-12)
        assert np.all(dt[1] > 2 * dt[0])  # verlet's automatic step is the larger
        assert np.all(ds["cpu_time"].values > 0)
        assert np.all(ds["steps"].values * ds["dt"].values == pytest.approx(ds["sim_time"].values, rel=1e-6))
        assert np.all(ds["base_pressure_error"].values[0, -1] == 0)  # the reference against itself
    with xr.open_dataset(root / "results/numerics_piles_ci/numerics/ensemble.nc") as ds:
        assert list(ds["n"].values) == [1, 2]
        assert np.all(ds["compute_time"].values > 0)
    table = (root / "results/numerics_piles_ci/numerics/piles.md").read_text()
    for integ in p["integrators"]:
        for f in p["dt_factors"]:
            assert f"| {integ} | {f:g} |" in table
    for png in ("pile_error.png", "ensemble_error.png"):
        assert (root / "results/numerics_piles_ci/numerics" / png).read_bytes()[:4] == b"\x89PNG"
    again = snakemake(root, "-n", "--cores", "2", "--configfile", "config/numerics_piles_ci.yaml",
                      "--replace-workflow-config", "numerics_piles")
    assert again.returncode == 0 and job_counts(again.output) == {}, again.output


def test_figures_draw_panels_without_finite_values(tmp_path):
    """Tiny piles give NaN angles and moduli; the figures still come out (a note instead of log axes)."""
    from analysis.numerics import ensemble_cost, pile_precision
    from analysis.numerics.figures import ensemble_error_figure, pile_error_figure

    dims = ("integrator", "dt_factor")
    ds = xr.Dataset(coords={"integrator": ["gear", "verlet"], "dt_factor": [1.0, 0.5], "seed": [1, 2]})
    for name in pile_precision.OBSERVABLES:
        ds[f"{name}_error"] = (dims, np.full((2, 2), np.nan), {"units": "1"})
        ds[f"{name}_error_bar"] = (dims, np.full((2, 2), np.nan))
    ds["angle_of_repose_error"][:] = [[0.5, 0.2], [0.4, 0.3]]
    ds["angle_of_repose_error_bar"][:] = 0.1
    ds["cpu_time_mean"] = (dims, np.array([[10.0, 20.0], [3.0, 6.0]]))
    ds.attrs.update(reference_integrator="gear", reference_dt_factor=0.5, n_particles=12, protocol="wedge")
    pile_error_figure(ds, [str(tmp_path / "piles.png")], pile_precision.OBSERVABLES)
    ens = xr.Dataset(coords={"protocol": ["wedge"], "n": [1, 2]})
    for name in ensemble_cost.HEADLINES:
        ens[f"{name}_mean"] = (("protocol", "n"), np.full((1, 2), np.nan))
        ens[f"{name}_se"] = (("protocol", "n"), np.full((1, 2), np.nan))
    ens["cumulative_compute_time"] = (("protocol", "n"), np.array([[5.0, 10.0]]))
    ens.attrs.update(core_x=0.0, core_y=0.01)
    ensemble_error_figure(ens, [str(tmp_path / "ensemble.png")], tuple(ensemble_cost.HEADLINES))
    for png in ("piles.png", "ensemble.png"):
        assert (tmp_path / png).read_bytes()[:4] == b"\x89PNG"
