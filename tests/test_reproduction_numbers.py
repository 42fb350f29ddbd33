"""The extra probes' numbers of the reproduction report
(workflow/tools/reproduction_numbers.py, analysis.probes) on a small general_moduli file
whose medians, counts and axis angles are known by hand."""


import numpy as np
import xarray as xr

from analysis.general_elastic import GENERAL_FLAGS
from analysis.orientation import axis_angle_difference
from analysis.probes import reversibility_by_depth, tilt_asymmetry

from workflow.tools import reproduction_numbers as numbers


def test_the_unsigned_axis_gap_folds_axes_half_a_turn_apart():
    """The angle between two axes that general_fit_summary averages: |axis_angle_difference|."""
    a = np.array([80.0, -80.0, 10.0, 0.0, 45.0])
    b = np.array([-80.0, 80.0, 10.0, 90.0, -45.0])
    np.testing.assert_allclose(np.abs(axis_angle_difference(a, b)), [20.0, 20.0, 0.0, 90.0, 90.0])


def general_file():
    """Two RVEs in a row, m = 1 and 5: at m = 1 the first has too few samples
    and the second is not identified; at m = 5 the first is identified, the
    second not."""
    flag = np.array([[[2, 1]], [[0, 1]]], np.int32)     # (points, y, x): 1 not identified, 2 too few samples
    cond = np.array([[[np.inf, 300.0]], [[12.0, 150.0]]])
    one = np.ones((2, 1, 2))
    return xr.Dataset(
        {"general_flag": (("points", "y", "x"), flag, GENERAL_FLAGS),
         "condition": (("points", "y", "x"), cond),
         "explained_general": (("points", "y", "x"), 0.9 * one), "explained_cubic": (("points", "y", "x"), 0.8 * one),
         "explained_isotropic": (("points", "y", "x"), 0.7 * one),
         "anisotropy": (("points", "y", "x"), np.array([[[np.nan, np.nan]], [[1.5, np.nan]]])),
         "axis_deg": (("points", "y", "x"), np.array([[[np.nan, np.nan]], [[85.0, 10.0]]])),
         "fabric_orientation": (("y", "x"), np.array([[-85.0, 0.0]])),
         "stress_orientation": (("y", "x"), np.array([[55.0, 0.0]])),
         "reversibility": (("y", "x"), np.array([[0.5, 0.9]])),
         "slip_left_out": (("probe", "y", "x"), np.array([[[1, 0]], [[0, 2]]], np.int32))},
        coords={"points": [1, 5], "y": [0.05], "x": [0.0, 0.02], "probe": ["reduced", "tiltp05"]},
        attrs={"n_seeds": 3, "loading_probes": "reduced tiltp05"})


def test_general_fit_lines_count_only_identified_rves():
    lines = numbers.general_fit(general_file())
    assert lines[0] == "3 piles, loading probes reduced tiltp05, slips left out 3 pile-probe-RVEs"
    assert lines[1] == "m = 1: identified and positive definite at 0 of 1 RVEs, median condition number 300"
    assert lines[2] == "m = 5: identified and positive definite at 1 of 2 RVEs, median condition number 81"
    assert "general 0.90, cubic 0.80, isotropic 0.70" in lines[3] and "E_max/E_min 1.5" in lines[3]
    # the second RVE's axis (10°) is not identified: only 85° against −85° (10°) and 55° (30°) count
    assert lines[4] == "mean angle between the stiffness axis and the fabric axis 10.0° over 1 RVEs"
    assert lines[5] == "mean angle between the stiffness axis and the stress axis 30.0° over 1 RVEs"
    assert lines[6].startswith("reversibility 1 − |u(restored)|/|u(reduced)|: median 0.70 (10–90 %: 0.54 – 0.86)")


def test_opposite_tilts_of_a_linear_pile_cancel_and_equal_ones_do_not():
    """Per RVE: opposite increments give 0, equal ones 1, one twice the other
    and opposite 1/3; the probes file of a pile without tilts gives None."""
    plus = np.zeros((1, 3, 2, 2))
    plus[..., 0, 0] = 1.0
    minus = np.stack([-plus[0, 0], plus[0, 0], -2.0 * plus[0, 0]])[None]
    data = np.stack([plus, minus])                                          # (probe, y, x, 2, 2)
    pr = xr.Dataset({"strain_increment": (("probe", "y", "x", "i", "j"), data)},
                    coords={"probe": ["tiltp05", "tiltm05"]})
    np.testing.assert_allclose(tilt_asymmetry(pr, "strain_increment"), [[0.0, 1.0, 1.0 / 3.0]])
    assert tilt_asymmetry(pr.sel(probe=["tiltp05"]), "strain_increment") is None


def test_reversibility_by_depth_counts_from_the_top_filled_rve_of_each_column():
    """Two columns whose tops stand at different heights: depth is measured
    from each column's own top (rows 2.25 cm apart, none on a band's edge),
    and the bands take the right RVEs."""
    y = 0.01 + 0.0225 * np.arange(7)
    rev = np.full((7, 2), np.nan)
    rev[:, 0] = [1.0, 0.98, 0.96, 0.90, 0.8, 0.5, 0.1]   # top at row 6: depths 13.5, 11.25, 9, 6.75, 4.5, 2.25, 0 cm
    rev[:5, 1] = [0.94, 0.98, 0.86, 0.7, 0.2]            # top at row 4: depths 9, 6.75, 4.5, 2.25, 0 cm
    gm = xr.Dataset({"reversibility": (("y", "x"), rev)}, coords={"y": y, "x": [0.0, 0.1]})
    lines = numbers._depth_lines(reversibility_by_depth(gm["reversibility"].values, gm["y"].values))
    # 0-3 cm: 0.5, 0.1, 0.7, 0.2; 3-6 cm: 0.8, 0.86; 6-10 cm: 0.96, 0.90, 0.94, 0.98; over 10 cm: 1.0, 0.98
    assert lines == ["0–3 cm median 0.35 (10 %: 0.13, 4 RVEs)", "3–6 cm median 0.83 (10 %: 0.81, 2 RVEs)",
                     "6–10 cm median 0.95 (10 %: 0.91, 4 RVEs)", "over 10 cm median 0.99 (10 %: 0.98, 2 RVEs)"]


def test_per_pile_reversibility_and_its_standard_error_over_piles(tmp_path):
    """Two piles whose restored strain is 0.2 and 0.5 of the reduction's in
    every RVE (reversibility 0.8 and 0.5): their medians, and the mean 0.65
    with the standard error 0.3 / sqrt(2) / sqrt(2) = 0.15 over the two piles."""
    reduced = np.zeros((2, 3, 2, 2))
    reduced[..., 1, 1] = -1e-4
    reduced[..., 0, 0] = 2e-5
    paths = []
    for seed, back in ((1, 0.2), (2, 0.5)):
        data = np.stack([reduced, back * reduced])                          # (probe, y, x, 2, 2)
        pr = xr.Dataset({"strain_increment": (("probe", "y", "x", "i", "j"), data)},
                        coords={"probe": ["reduced", "restored"]}, attrs={"seed": seed})
        paths.append(tmp_path / f"seed{seed}.probes.nc")
        pr.to_netcdf(paths[-1])
    lines = numbers.per_pile_probes(paths)
    assert lines == ["seed 1: median reversibility 0.80", "seed 2: median reversibility 0.50",
                     "median reversibility, mean over the 2 piles: 0.65 ± 0.15"]


def test_moduli_lines_give_the_share_masked_per_layer_as_counted_from_the_piles():
    """Four exactly isotropic piles (K = 3e6, G = 1e6 N/m) on a 3 × 4 grid,
    made unstable (G < 0) where chosen: pile 0 at two RVEs of the middle row,
    every pile at one RVE of the top row. The isotropic column of the table
    is the share of those RVEs counted here from that choice: for the fit of
    the ensemble mean only the top RVE fails (the middle row's mean G is
    0.7e6), for the piles' own fits 2 and 4 of the 16 pile-RVEs of a row, for
    the mean over piles the top RVE; and the medians are over the RVEs kept."""
    from analysis.elastic import moduli_dataset
    from analysis.netcdf import tensor_coords, var
    from analysis.params import resolve_params

    ny, nx, n = 3, 4, 4
    unstable = np.zeros((n, ny, nx), bool)
    unstable[0, 1, :2] = True
    unstable[:, 2, 3] = True
    y = np.array([0.045, 0.09, 0.135])
    coords = {"y": var("y", y, "y", "m"), "x": var("x", [-0.03, -0.015, 0.0, 0.015], "x", "m"),
              **tensor_coords()}
    rng = np.random.default_rng(4)
    u = 1e-4 * rng.standard_normal((ny, nx, 2, 2))
    u = 0.5 * (u + np.swapaxes(u, -1, -2))
    tr = (u[..., 0, 0] + u[..., 1, 1])[..., None, None]
    piles = []
    for k in range(n):
        G = np.where(unstable[k], -0.2e6, 1.0e6)[..., None, None]
        sigma = 3.0e6 * tr * np.eye(2) + 2 * G * (u - 0.5 * tr * np.eye(2))
        pile = xr.Dataset(coords=coords, attrs={"seed": k + 1})
        pile["stress_increment"] = var(("y", "x", "i", "j"), sigma, "dsigma", "N m-1")
        pile["strain_increment"] = var(("y", "x", "i", "j"), u, "u", "1")
        piles.append(pile)
    ensemble = (sum(piles) / n).assign_attrs(n_seeds=n, protocol="wedge")
    md = moduli_dataset(ensemble, piles, resolve_params({"moduli": {"min_points": 1}}))
    lines = numbers.moduli(md, list(y))

    def pct(count, total):
        return f"{100 * count / total:.0f} %"

    mean_g = 0.25 * np.where(unstable, -0.2e6, 1.0e6).sum(axis=0)
    for row in range(ny):
        ens = pct(np.sum(mean_g[row] <= 0), nx)
        own = pct(unstable[:, row].sum(), n * nx)
        mean = pct(np.sum(unstable[:, row].sum(axis=0) > n / 2), nx)
        cell = next(line for line in lines if line.startswith(f"| {100 * y[row]:.1f} |")).split(" | ")[1]
        assert cell == f"{ens} / {own} / {mean} of {nx}", (row, cell)
    total = next(line for line in lines if line.startswith("| all RVEs |")).split(" | ")[1]
    assert total == f"{pct(1, ny * nx)} / {pct(unstable.sum(), n * ny * nx)} / {pct(1, ny * nx)} of {ny * nx}"
    assert "| K (isotropic, m = 1) | S′ | 3e+06 N/m (11 / 12) | 3e+06 N/m (11 / 12) |" in lines
