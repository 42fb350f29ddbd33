"""The general fit with the support stretch (analysis.probes.general_fit_dataset):
on a synthetic anisotropic material of known Mandel stiffness C, probed as a
linear pile is (every gravity probe's strain a combination of the two
responses to g_y and g_x), the six constants are recovered only when the
stretch is among the probes: the gravity probes alone have a singular
design at m = 1 and m = 5 (condition_gravity > 1e10, not identified, no
RVE with six_constants), with the stretch every pile's fit and the
ensemble's are C with condition numbers below the threshold, and the
stiffest axis, the anisotropy and their comparison with the fabric and
stress axes are those of C."""

import numpy as np
import pytest
import xarray as xr
from synthetic_states import GRAVITY_PROBES, PROBE_SHAPES, mandel_stress

from analysis import general_elastic as ge
from analysis.params import parse_params
from analysis.probes import SIX_CONSTANTS_MAX_CONDITION, general_fit_dataset

RNG = np.random.default_rng(27)
NY, NX = 3, 4


def pile(c, seed, stretch):
    """One pile's probe file: the gravity probes (and the stretch) of a linear
    material, each pile and RVE with its own amplitude, plus restored."""
    amp = 1.0 + 0.2 * RNG.normal(size=(NY, NX, 1, 1))
    strains = {name: amp * (dy * PROBE_SHAPES["y"] + dx * PROBE_SHAPES["x"])
               for name, (dy, dx) in GRAVITY_PROBES.items()}
    if stretch:
        strains["stretched"] = amp * PROBE_SHAPES["stretched"] * (1.0 + 0.1 * RNG.normal())
    strains["restored"] = 0.1 * strains["reduced"]
    probes = list(strains)
    strain = np.array([strains[p] for p in probes])
    stress = mandel_stress(c, strain)
    stress[probes.index("restored")] = 0.0
    dims = ("probe", "y", "x", "i", "j")
    return xr.Dataset({"stress_increment": (dims, stress), "strain_increment": (dims, strain)},
                      coords={"probe": probes, "y": 0.01 * np.arange(NY), "x": 0.01 * np.arange(NX),
                              "i": ["x", "y"], "j": ["x", "y"]}, attrs={"protocol": "wedge", "seed": str(seed)})


def test_the_six_constants_are_recovered_only_with_the_stretch():
    q = np.linalg.qr(RNG.normal(size=(3, 3)))[0]
    c = q @ np.diag([3.0e6, 1.2e6, 0.5e6]) @ q.T                  # anisotropic, no symmetry axis along x or y
    params = parse_params('{"moduli": {"min_points": 3}}')
    known = ge.stiffness_axes(c)
    ensemble = xr.Dataset({"fabric_orientation": (("y", "x"), np.full((NY, NX), known["axis_deg"] - 10.0)),
                           "stress_orientation": (("y", "x"), np.full((NY, NX), known["axis_deg"] + 85.0))})

    gravity_only = general_fit_dataset([pile(c, s, False) for s in range(4)], params)
    assert gravity_only.attrs["other_probes"] == "" and gravity_only.attrs["gravity_probes"] == "reduced tiltp05 tiltm05"
    for m in (1, 5):
        inner = gravity_only.sel(points=m).isel(y=1, x=slice(1, 3))
        assert (inner["condition"].values > 1e10).all() and (inner["condition_gravity"].values > 1e10).all()
        assert (inner["general_flag"].values & ge.GENERAL_NOT_IDENTIFIED).all()
        assert int(gravity_only["six_constants"].sum()) == 0 and int(gravity_only["six_constants_piles"].sum()) == 0

    ds = general_fit_dataset([pile(c, s, True) for s in range(4)], params, ensemble)
    assert ds.attrs["other_probes"] == "stretched" and ds.attrs["loading_probes"] == "reduced tiltp05 tiltm05 stretched"
    assert list(ds["pile"].values) == [f"wedge seed {s}" for s in range(4)]
    for m in (1, 5):
        fit = ds.sel(points=m)
        inner = fit.isel(y=1, x=slice(1, 3)) if m == 5 else fit
        assert (inner["condition_gravity"].values > 1e10).all()          # the gravity probes still pin five
        assert (inner["condition"].values <= SIX_CONSTANTS_MAX_CONDITION).all()
        assert (inner["condition_pile"].values <= SIX_CONSTANTS_MAX_CONDITION).all()
        assert (inner["six_constants"].values == 1).all() and (inner["six_constants_piles"].values == 4).all()
        np.testing.assert_allclose(inner["stiffness"].values, np.broadcast_to(c, inner["stiffness"].shape), rtol=1e-8)
        assert float(np.nanmax(inner["stiffness_sem"].values)) <= 1e-8 * np.abs(c).max()
        np.testing.assert_allclose(inner["axis_deg"].values, known["axis_deg"])
        np.testing.assert_allclose(inner["axis_deg_pile"].values, known["axis_deg"])
        np.testing.assert_allclose(inner["soft_axis_deg"].values, known["soft_axis_deg"])
        np.testing.assert_allclose(inner["anisotropy"].values, known["anisotropy"], rtol=1e-8)
        assert float(np.nanmax(inner["axis_deg_sem"].values)) == 0.0
        np.testing.assert_allclose(inner["axis_to_fabric_deg"].values, 10.0, atol=1e-9)
        np.testing.assert_allclose(inner["axis_to_stress_deg"].values, 95.0 - 180.0, atol=1e-9)   # folded


def test_the_axis_standard_error_folds_axes_half_a_turn_apart():
    """Two piles whose stiffest axes are 89 and -89 degrees, 2 degrees apart
    across the horizontal: the standard error over piles is that of +-1
    degree about the ensemble's axis, not of +-89."""
    base = np.diag([3.0e6, 1.0e6, 0.8e6])                           # stiffest along x: 90 degrees
    piles = []
    for k, beta in enumerate((-1.0, 1.0)):
        b = np.radians(beta)
        r = np.array([[np.cos(b), -np.sin(b)], [np.sin(b), np.cos(b)]])
        rot = np.array([[r[0, 0] ** 2, r[0, 1] ** 2, np.sqrt(2) * r[0, 0] * r[0, 1]],
                        [r[1, 0] ** 2, r[1, 1] ** 2, np.sqrt(2) * r[1, 0] * r[1, 1]],
                        [np.sqrt(2) * r[0, 0] * r[1, 0], np.sqrt(2) * r[0, 1] * r[1, 1],
                         r[0, 0] * r[1, 1] + r[0, 1] * r[1, 0]]])
        piles.append(pile(rot @ base @ rot.T, k, True))
    ds = general_fit_dataset(piles, parse_params('{"moduli": {"min_points": 3}}'))
    fit = ds.sel(points=1)
    axes = fit["axis_deg_pile"].values
    assert np.allclose(np.abs(axes), 89.0, atol=0.5) and (np.sign(axes[0]) != np.sign(axes[1])).all()
    assert float(np.nanmax(fit["axis_deg_sem"].values)) == pytest.approx(1.0, abs=0.5)
