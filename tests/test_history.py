"""The construction-history statistics (analysis/history.py) on fields whose
answer is known by construction: a step dip of known depth, a heap of uniform
density (whose column-normalised contrast is zero however peaked its
pressure), stresses scaling with gravity or not, mirrored stress-fabric
tilts and fabric axes.  (The comparison over piles: test_ensemble_statistics.py.)"""

import numpy as np
import pytest
import xarray as xr
from scipy import integrate

from analysis.errors import ParamError
from analysis.history import flank_fabric, pile_history, primary_names, uniform_pile_pressure
from analysis.params import resolve_params

PARAMS = resolve_params({})
H = PARAMS["history"]


def _fields(u_row=None, phi_row=None, angle_row=None, gap=0.0, surface=None):
    """A pile's fields on the study's grid: u_yy, solid fraction, stresses and the
    stress-fabric angle each a function of x alone (the same in every row)."""
    x = np.round(np.arange(-0.6, 0.6 + 1e-9, 0.015), 6)
    y = np.round(np.arange(0.015, 0.36 + 1e-9, 0.015), 6)
    ny, nx = y.size, x.size
    ones = np.ones((ny, nx))
    u = np.zeros((ny, nx, 2, 2))
    u[..., 1, 1] = (u_row(x) if u_row else 2e-4) * ones
    sigma = np.zeros((ny, nx, 2, 2))
    sigma[..., 0, 0] = -300.0 * ones
    sigma[..., 1, 1] = -800.0 * ones
    dsigma = np.zeros_like(sigma)
    dsigma[..., 1, 1] = 0.1 * 800.0          # sigma_yy follows a 10 % reduction of g
    dsigma[..., 0, 0] = 0.1 * 300.0 * (1 + gap)
    ds = xr.Dataset(
        {"strain_increment": (("y", "x", "i", "j"), u),
         "stress": (("y", "x", "i", "j"), sigma),
         "stress_increment": (("y", "x", "i", "j"), dsigma),
         "solid_fraction": (("y", "x"), (phi_row(x) if phi_row else 0.82) * ones),
         "mask_reason": (("y", "x"), np.zeros((ny, nx), np.int32)),
         "stress_fabric_angle": (("y", "x"), (angle_row(x) if angle_row else 0.0) * ones),
         "surface_height": (("x",), surface(x) if surface else np.full(nx, 0.25))},
        coords={"y": y, "x": x, "i": ["x", "y"], "j": ["x", "y"]})
    return ds


def _triangle(height=0.25, half_width=0.5):
    return lambda x: np.where(np.abs(x) < half_width, height * (1 - np.abs(x) / half_width), np.nan)


def _base_pressure(p_of_x, weight):
    edges = np.linspace(-0.6, 0.6, 61)
    x = 0.5 * (edges[1:] + edges[:-1])
    return xr.Dataset({"normal_force_density_per_seed": (("seed", "x"), p_of_x(x)[None, :]),
                       "weight": (("seed",), [weight])}, coords={"x": x, "seed": ["1"]})


def test_a_step_dip_of_known_depth_is_measured_exactly():
    # u_yy 7 % lower within the centre window, flat elsewhere: contrast -0.07 at every layer
    stats = pile_history(_fields(u_row=lambda x: np.where(np.abs(x) <= 0.031, 0.93e-4, 1e-4)),
                         PARAMS, [0.045, 0.09])
    assert stats["strain@4.5"] == pytest.approx(-0.07, abs=1e-12)
    assert stats["strain@9"] == pytest.approx(-0.07, abs=1e-12)
    # a denser centre: solid fraction 0.85 against 0.83
    stats = pile_history(_fields(phi_row=lambda x: np.where(np.abs(x) <= 0.031, 0.85, 0.83)), PARAMS, [0.045])
    assert stats["solid_fraction@4.5"] == pytest.approx(0.85 / 0.83 - 1, abs=1e-12)


def test_columns_outside_both_windows_do_not_count():
    # a bump between centre (3 cm) and shoulders (6 cm) and beyond the shoulders (15 cm) changes nothing
    bump = lambda x: np.where((np.abs(x) > 0.035) & (np.abs(x) < 0.055) | (np.abs(x) > 0.16), 5e-4, 1e-4)
    assert pile_history(_fields(u_row=bump), PARAMS, [0.045])["strain@4.5"] == pytest.approx(0.0, abs=1e-12)


def test_a_slipped_rve_is_left_out_as_in_the_ensembles():
    def slip(x):
        u = np.full(x.shape, 1e-4)
        u[np.argmin(np.abs(x))] = 1e-1        # 1000 times the median: slipped
        return u
    stats = pile_history(_fields(u_row=slip), PARAMS, [0.045])
    assert stats["strain@4.5"] == pytest.approx(0.0, abs=1e-12)


def test_the_uniform_pile_pressure_carries_the_weight_column_by_column():
    x = np.linspace(-0.6, 0.6, 81)
    h = _triangle(0.25, 0.5)(x)
    weight = 2000.0
    pu = uniform_pile_pressure(x, x, h, weight)
    # the centre column of a triangle of base 2L carries W / L (its height over the mean height)
    assert pu[np.argmin(np.abs(x))] == pytest.approx(weight / 0.5, rel=1e-3)
    total, _ = integrate.quad(lambda s: np.interp(s, x, pu), -0.6, 0.6, points=[-0.5, 0.0, 0.5], limit=200)
    assert total == pytest.approx(weight, rel=1e-3)


def test_a_uniform_heap_has_no_column_contrast_though_it_presses_most_at_its_centre():
    weight, half = 2000.0, 0.5
    surface = _triangle(0.25, half)
    hydro = lambda x: weight / half * np.clip(1 - np.abs(x) / half, 0, None)
    stats = pile_history(_fields(surface=surface), PARAMS, [0.045], _base_pressure(hydro, weight))
    # raw contrast: bins at 1, 3 cm against 7, 9, ..., 15 cm of a triangle, worked by hand
    centre = np.mean([1 - 0.01 / half, 1 - 0.03 / half])
    shoulders = np.mean([1 - s / half for s in (0.07, 0.09, 0.11, 0.13, 0.15)])
    assert stats["base_pressure"] == pytest.approx(centre / shoulders - 1, rel=1e-9)
    assert stats["base_pressure"] > 0.1
    assert stats["base_pressure_column"] == pytest.approx(0.0, abs=2e-3)
    assert stats["centre_column"] == pytest.approx(0.0, abs=2e-3)
    # the same heap with 20 % of the load under |x| < 4 cm carried off to the shoulders
    dip = lambda x: hydro(x) * np.where(np.abs(x) < 0.04, 0.8, 1.0)
    stats = pile_history(_fields(surface=surface), PARAMS, [0.045], _base_pressure(dip, weight))
    assert stats["base_pressure_column"] == pytest.approx(-0.2, abs=3e-3)


def test_gravity_scaling_zero_when_both_stresses_follow_g():
    assert pile_history(_fields(), PARAMS, [0.045])["gravity_gap"] == pytest.approx(0.0, abs=1e-12)
    stats = pile_history(_fields(gap=-0.5), PARAMS, [0.045])  # sigma_xx changes half as much
    assert stats["gravity_yy"] == pytest.approx(-0.1)
    assert stats["gravity_xx"] == pytest.approx(-0.05)
    assert stats["gravity_gap"] == pytest.approx(-0.5)


def test_stress_fabric_angle_adds_mirrored_tilts_and_cancels_a_shared_one():
    mirrored = pile_history(_fields(angle_row=lambda x: 4.0 * np.sign(x)), PARAMS, [0.045])
    assert mirrored["stress_fabric"] == pytest.approx(4.0)
    shared = pile_history(_fields(angle_row=lambda x: np.full(x.shape, 4.0)), PARAMS, [0.045])
    assert shared["stress_fabric"] == pytest.approx(0.0, abs=1e-12)


def test_the_flank_fabric_mirrors_the_axis_and_leaves_out_invalid_rves():
    """Axes tilted ±10° by the sign of x add up to 10°; the deviatoric fraction is the
    flanks' mean; an invalid RVE (mask_reason) and the columns off the flanks do not count."""
    ds = _fields()
    x = ds["x"].values
    shape = (ds.sizes["y"], ds.sizes["x"])
    dev = np.where((np.abs(x) > 0.12) & (np.abs(x) < 0.2), 0.3, 0.1) * np.ones(shape)
    dev[0, np.argmin(np.abs(x - 0.15))] = 50.0                     # an invalid RVE on the flank
    mask = np.zeros(shape, np.int32)
    mask[0, np.argmin(np.abs(x - 0.15))] = 1
    ds = ds.assign(fabric_orientation=(("y", "x"), 10.0 * np.sign(x) * np.ones(shape)),
                   fabric_deviatoric_fraction=(("y", "x"), np.where(np.abs(x) > 0.35, 9.0, dev)),
                   mask_reason=(("y", "x"), mask))
    out = flank_fabric(ds, H)
    assert out["fabric_axis_deg"] == pytest.approx(10.0)
    flanks = (np.abs(x) >= H["flank_inner"] - 1e-9) & (np.abs(x) <= H["flank_outer"] + 1e-9)
    rows = ds["y"].values <= H["flank_height"] + 1e-9
    expect = dev[rows][:, flanks][mask[rows][:, flanks] == 0].mean()
    assert out["fabric_deviator"] == pytest.approx(expect)


def test_primary_names_follow_the_primary_height():
    assert primary_names(H)[0] == "strain@4.5"
    assert primary_names({**H, "primary_height": 0.09})[2] == "solid_fraction@9"


@pytest.mark.parametrize("history, words", [
    ({"centre": 0.08}, ["analysis.history", "centre < shoulder_inner < shoulder_outer", "0.08"]),
    ({"flank_inner": 0.4}, ["analysis.history.flank_inner = 0.4", "flank_outer = 0.3"]),
])
def test_windows_out_of_order_are_refused_by_name(history, words):
    with pytest.raises(ParamError) as err:
        resolve_params({"history": history})
    assert all(w in str(err.value) for w in words)


def test_without_a_gravity_probe_only_the_probe_statistics_are_nan():
    """Fields made without a probe hold no stress or strain increment: the statistics read from
    them are NaN, every other is the one the same pile gives with the probe."""
    phi = lambda x: np.where(np.abs(x) <= 0.031, 0.85, 0.83)  # noqa: E731
    probed = _fields(u_row=lambda x: np.where(np.abs(x) <= 0.031, 0.93e-4, 1e-4), phi_row=phi, gap=-0.2)
    bp = _base_pressure(lambda x: 1000.0 * (1 - np.abs(x)), 500.0)
    with_probe = pile_history(probed, PARAMS, [0.045, 0.09], bp)
    without = pile_history(probed.drop_vars(["strain_increment", "stress_increment"]), PARAMS, [0.045, 0.09], bp)
    from_probe = {"strain@4.5", "strain@9", "gravity_xx", "gravity_yy", "gravity_gap"}
    assert with_probe.keys() == without.keys() and from_probe < with_probe.keys()
    for key, value in with_probe.items():
        if key in from_probe:
            assert np.isfinite(value) and np.isnan(without[key]), key
        else:
            assert without[key] == value or np.isnan(value) and np.isnan(without[key]), key
