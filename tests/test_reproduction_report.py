"""The report's statistics and verdict numbers.

First the tests of analysis.ensemble_statistics that decide the report (Welch's t at its
degrees of freedom, Holm's correction, the piles for a given power) against
scipy and values worked by hand; then every number of the verdicts of
docs/reproduction.md that workflow/tools/reproduction_numbers.py makes,
recomputed here from the committed per-pile files under docs/reproduction/
and looked for in the report."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml
from scipy import stats

from analysis.decision import primary_tests
from analysis.ensemble_statistics import compare, holm, piles_for_power, t_power, t_threshold, welch
from analysis.invariants import secant_deciles
from workflow.tools import reproduction_numbers as numbers

REPO = Path(__file__).resolve().parents[1]
RECORD = REPO / "docs" / "reproduction"


# --- the statistics -----------------------------------------------------------

def test_welch_is_scipys_unequal_variance_t_test():
    rng = np.random.default_rng(3)
    a, b = rng.normal(0.0, 1.0, 9), rng.normal(1.0, 2.5, 10)
    w = welch(np.append(a, np.nan), b)                  # NaN is left out
    ref = stats.ttest_ind(a, b, equal_var=False)
    assert w["t"] == pytest.approx(ref.statistic)
    assert w["df"] == pytest.approx(ref.df)
    assert w["p"] == pytest.approx(ref.pvalue)
    assert math.isnan(welch([1.0], [1.0, 2.0])["t"])


def test_holm_steps_down_and_keeps_the_adjusted_p_monotone():
    """p = 0.01, 0.04, 0.03, 0.2 (m = 4): sorted 0.01, 0.03, 0.04, 0.2 adjust to
    4 x 0.01 = 0.04, 3 x 0.03 = 0.09, max(0.09, 2 x 0.04) = 0.09, max(0.09, 0.2) = 0.2;
    at 5 % only the first is rejected, where Bonferroni at 0.0125 agrees."""
    adjusted, rejected = holm([0.01, 0.04, 0.03, 0.2])
    assert adjusted == pytest.approx([0.04, 0.09, 0.09, 0.2])
    assert rejected == [True, False, False, False]
    # Holm rejects more than Bonferroni once the first test passes: 0.011 < 0.05 / 4 after 0.001
    adjusted, rejected = holm([0.001, 0.011, 0.5, 0.9, np.nan])
    assert rejected == [True, True, False, False, False] and math.isnan(adjusted[-1])
    assert adjusted[1] == pytest.approx(4 * 0.011)


def test_t_threshold_is_students_quantile_not_the_normal_one():
    assert t_threshold(12.0, 5) == pytest.approx(stats.t.ppf(1 - 0.005, 12.0))
    assert t_threshold(12.0, 5) > 3.0 > stats.norm.ppf(1 - 0.005)


def test_piles_for_power_is_the_smallest_n_reaching_it():
    """Unit scatter, a difference of one SD: the normal rule gives
    2 (1.96 + 0.84)^2 = 15.7; Student's t needs one more pile, 17, and
    the power crosses 80 % between 16 and 17."""
    n = piles_for_power(1.0, 1.0, 1.0)
    assert n == 17
    assert t_power(1.0, 1.0, 1.0, 16) < 0.8 <= t_power(1.0, 1.0, 1.0, 17)
    assert piles_for_power(1.0, 1.0, 1.0, comparisons=5) > n           # family-wise asks more
    assert piles_for_power(1.0, 1.0, 1.0, power=0.5) < n
    assert math.isnan(piles_for_power(np.nan, 1.0, 1.0))
    assert math.isinf(piles_for_power(100.0, 100.0, 0.01, most=1000))


def test_secant_deciles_are_flat_for_a_linear_law_and_rise_for_a_stiffening_one():
    e = np.linspace(1e-4, 3e-4, 100)
    flat, strain = secant_deciles(2e6 * e, e)
    np.testing.assert_allclose(flat, 2e6)
    assert strain[0] == pytest.approx(e[:10].mean())
    rising, _ = secant_deciles(1e10 * e ** 2, e)
    assert np.all(np.diff(rising) > 0)


# --- the report's numbers, from the committed pile files --------------------

def _items(kind):
    return [f"{p}={f}" for p in ("wedge", "layered") for f in sorted(map(str, (RECORD / p).glob(f"seed*.{kind}.nc")))]


@pytest.fixture(scope="module")
def params():
    from analysis.params import resolve_params
    return resolve_params(yaml.safe_load((REPO / "config" / "config.yaml").read_text())["analysis"])


@pytest.fixture(scope="module")
def report():
    """The report with the minus sign of the generated numbers, its lines joined."""
    return " ".join((REPO / "docs" / "reproduction.md").read_text().replace("−", "-").split())


@pytest.fixture(scope="module")
def checks(params):
    from analysis.ensemble import ensemble_fields
    from analysis.invariants import invariants_dataset
    study = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    invariants = {}
    for p in ("wedge", "layered"):
        paths = sorted((RECORD / p).glob("seed*.fields.nc"))
        piles = [xr.open_dataset(f).load() for f in paths]
        ens = ensemble_fields(piles, [f.name for f in paths], params["ensemble"]["slip_strain_ratio"])
        invariants[p] = invariants_dataset(ens, params)
    gravity = float(xr.open_dataset(sorted((RECORD / "wedge").glob("seed*.fields.nc"))[0]).attrs["gravity_relaxed"])
    return numbers.report_checks(_items("fields"), _items("base_pressure"),
                                 sorted(map(str, RECORD.glob("*/seed*.convergence.nc"))), invariants, params,
                                 {"density": study["model"]["density"],
                                  "layered_slope_deg": study["pour"]["layered_slope_deg"], "gravity": gravity})


@pytest.fixture(scope="module")
def tests(params):
    values = numbers.history_values(_items("fields"), _items("base_pressure"), params, [0.045, 0.09, 0.135])
    return {t["name"]: t for t in primary_tests(values, params["history"])}


def test_primary_tests_as_the_report_quotes_them(tests, report):
    """Each primary test's t, df, p, Holm p and verdict, and the piles for 80 % power."""
    for name, t in tests.items():
        quoted = f"t {t['t']:+.2f}, {t['df']:.1f} df"
        assert quoted in report, (name, quoted)
    s, d, g = tests["strain@4.5"], tests["solid_fraction@4.5"], tests["gravity_gap"]
    b, f = tests["base_pressure_column"], tests["stress_fabric"]
    for t in (s, d, g, b):
        assert f"p {t['p']:.4f}" in report or f"p {t['p']:.2f}" in report, t["name"]
    # the verdicts: Holm passes strain, density and gravity; Bonferroni at the Welch df only gravity
    assert s["rejected"] and d["rejected"] and g["rejected"] and not b["rejected"] and not f["rejected"]
    assert abs(s["t"]) < s["t_bonferroni"] and abs(d["t"]) < d["t_bonferroni"] < abs(g["t"])
    for t in (s, d, g, b, f):
        assert f"{t['holm_p']:.3f}" in report or f"{t['holm_p']:.2f}" in report, t["name"]
    for t in (s, d, b):
        assert f"({t['t_bonferroni']:.2f} needed)" in report or f"{t['t_bonferroni']:.2f} its" in report \
            or t is b, t["name"]
    dfs = [t["df"] for t in tests.values()]
    assert f"freedom ({min(dfs):.1f}–{max(dfs):.1f} with" in report
    low = min(t["t_bonferroni"] for t in tests.values())
    high = max(t["t_bonferroni"] for t in tests.values())
    assert f"{low:.2f}–{high:.2f}" in report
    # power: 80 % at a family-wise 5 % for a 5 % difference (2 degrees)
    assert f"{s['n_delta']:.0f} piles per protocol in the strain contrast" in report
    assert f"{b['n_delta']:.0f} in the" in report and f"{b['n_delta']:.0f} piles per protocol" in report
    assert f"{d['n_delta']:.0f} in the density contrast" in report
    assert f"{g['n_delta']:.0f} in the gravity gap" in report and f"difference by {f['n_delta']:.0f}" in report
    assert f"for the measured 7 % {b['n_measured']:.0f}" in report
    assert f"{d['n_measured']:.0f} are needed" in report
    assert f"needs {b['n_delta_single']:.0f} piles per protocol in a single test and {b['n_delta']:.0f} at" in report
    assert f"({b['n_delta_single']:.0f} for one test)" in report and f"{s['n_delta_single']:.0f} for a single" in report


def test_verdict_numbers_are_the_committed_piles(checks, report):
    for key in ("wedge.stress_increment", "layered.stress_increment", "wedge.vertical_stiffness",
                "layered.vertical_stiffness", "wedge.flanks", "layered.flanks", "wedge.fabric_deviator",
                "layered.fabric_deviator", "wedge.fabric_axis", "layered.fabric_axis", "wedge.secant_range",
                "layered.secant_range", "line_source.H", "line_source.tops", "stress_column.sd_ratio",
                "fig1.reference", "fig1.largest_cut", "wedge.secant_ratio_se_from_1",
                "layered.secant_ratio_se_from_1", "wedge.secant_factor", "layered.secant_factor",
                "wedge.secant_piles_strain_min", "layered.secant_piles_strain_min", "wedge.decile_strain_min",
                "wedge.stiffness_strain_min", "layered.stiffness_strain_min"):
        assert checks[key] in report, (key, checks[key])
    for p in ("wedge", "layered"):
        assert checks[f"{p}.stress_column.sd"] in report and checks[f"{p}.base_pressure_column.sd"] in report
        assert f"{checks[f'{p}.secant_rises'].split()[0]} of 9" in report
        assert checks[f"{p}.trace_strain_max"] in report
    ratio = checks["wedge.secant_piles"].split("ratio ")[1]
    assert f"factor {ratio}" in report
    assert f"{checks['layered.secant_piles'].split('ratio ')[1]} (layered" in report
    assert f"at most {checks['surface_gap'].split(' (')[0]} apart" in report
    assert f"would need {checks['stress_column.piles']} " in report or f"need {checks['stress_column.piles']}" in report
    assert checks["base_pressure_column.piles"] in report
    assert f"difference is {checks['stress_column.diff'].split(',')[0]} (t {checks['stress_column.diff'].split('= ')[1].split(' (')[0]}" in report
    for size in ("6", "8", "10"):
        line = checks[f"fig1.{size}"]
        sigma = line.split("σ_yy ")[1].split(" %")[0]
        assert f"{sigma} % at {size} cm" in report, (size, sigma)
    assert checks["fig1.8"].split(" particles")[0] in report
    assert "largest " + checks["fig1.8"].split("(largest ")[1].split(" %")[0] + " %" in report


def test_growth_and_out_of_sample_numbers_are_the_committed_records(report):
    """The growing layered piles (growing_piles.jsonl) and the variant's
    wedge − layered strain contrast (its table, rebuilt by make reproduction)."""
    study = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    rows = [json.loads(line) for line in (RECORD / "growing_piles.jsonl").read_text().splitlines() if line.strip()]
    crossings, drops, flanks = [], [], []
    for seed in (9, 10):
        with xr.open_dataset(RECORD / "layered" / f"seed{seed}.base_pressure.nc") as bp:
            area = float(bp["weight"].values[0]) / (study["model"]["density"] * 9.81) / 0.8
        h = math.sqrt(area * math.tan(math.radians(study["pour"]["layered_slope_deg"])))
        mine = [r for r in rows if f"seed{seed}_" in r["state"] and r["stage"] == "checkpoint"]
        crossings.append(next(r["particles"] for r in mine if r["height"] > h))
        drops += [a["height"] - b["height"] for a, b in zip(mine, mine[1:])]
        flanks += [(r["flank_left_deg"] + r["flank_right_deg"]) / 2 for r in mine]
    assert f"at {crossings[0]} and {crossings[1]} of the 3500" in report
    assert f"up to {100 * max(drops):.1f} cm" in report
    assert f"between {min(flanks):.0f}° and {max(flanks):.0f}°" in report
    variant = (RECORD / "variants" / "support_friction_0.9.md").read_text()

    def cell(start, column):
        row = next(line for line in variant.splitlines() if line.startswith(start))
        diff, se = row.split(" | ")[column].split(" (")[0].split(" ± ")
        return f"{100 * float(diff):+.1f} ± {100 * float(se):.1f} %"

    for start in ("| strain u_yy centre/shoulders", "| base pressure centre/shoulders against",
                  "| solid fraction centre/shoulders", "| gravity scaling"):
        assert cell(start, 2) in report, start                 # the variant's wedge − layered
    assert cell("| strain u_yy centre/shoulders", 1) in report   # the study's, over the 18 piles


def test_history_means_the_report_quotes_are_the_committed_piles(params, report):
    """The per-protocol means ± SE and the differences of the verdict table."""
    values = numbers.history_values(_items("fields"), _items("base_pressure"), params, [0.045, 0.09, 0.135])
    for name in ("strain@4.5", "base_pressure_column", "solid_fraction@4.5", "stress_fabric",
                 "base_pressure", "centre_column"):
        a = [v.get(name, np.nan) for v in values["wedge"]]
        b = [v.get(name, np.nan) for v in values["layered"]]
        c = compare(a, b)
        for m, se in (c["a"][:2], c["b"][:2], (c["diff"], c["se"])):
            cell = numbers._history_cell(name, m, se)
            if m == c["diff"] and name not in ("strain@4.5", "base_pressure_column", "solid_fraction@4.5"):
                continue                                # the difference is quoted for these only
            if name == "stress_fabric":                 # quoted as "-3.20° ± 0.48°"
                cell = f"{m:.2f}° ± {se:.2g}°"
            if name == "centre_column":                 # quoted as "carry 21.5 ± 2.1 % ... less"
                cell = cell.lstrip("+-")
            assert cell in report, (name, cell)
    for name, spec in (("gravity_yy", "wedge"), ("gravity_xx", "wedge"), ("gravity_yy", "layered"),
                       ("gravity_xx", "layered")):
        m = np.mean([v[name] for v in values[spec]])
        assert f"{100 * m:.1f} %" in report, (name, spec)


def test_checks_survive_windows_without_a_valid_rve(params):
    """The smoke study's small piles (tests/test_workflow.py runs make reproduction
    over them) may hold no valid RVE in a window and no base pressure: the checks
    then give NaN there, not an error."""
    import copy
    from analysis.ensemble import ensemble_fields
    from analysis.invariants import invariants_dataset
    far = copy.deepcopy(params)
    far["history"].update(shoulder_inner=0.55, shoulder_outer=0.6)    # off every pile
    paths = {p: sorted((RECORD / p).glob("seed*.fields.nc"))[:2] for p in ("wedge", "layered")}
    fields = [f"{p}={f}" for p, fs in paths.items() for f in fs]
    invariants = {p: invariants_dataset(ensemble_fields([xr.open_dataset(f).load() for f in fs]), far)
                  for p, fs in paths.items()}
    out = numbers.report_checks(fields, [], sorted(map(str, RECORD.glob("layered/seed1.convergence.nc"))),
                                invariants, far, {"density": 2500.0, "layered_slope_deg": 20.0, "gravity": 9.81})
    assert out["wedge.stress_column"] == "+nan ± nan %" and out["line_source.H"] == "nan–nan cm"
    assert out["fig1.reference"] == "12 cm"
