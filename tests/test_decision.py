"""The pre-registered decision (analysis/decision.py) against its page and against scipy.

The rules of docs/reproduction/preregistration.md on records made up for the
purpose (their numbers are chosen so that the rule's answer is known by
reading the page), the pooled scatter and the interval against scipy's
independent implementations, and the registered power checked by drawing
ensembles.
"""

import math

import numpy as np
import pytest
from scipy import linalg, stats

from analysis import decision
from analysis.decision import DECISION, EFFECT, EQUAL_SLOPE_SECONDARY, SECONDARY
from analysis.ensemble_statistics import tost
from analysis.history import row_contrast


def record(arm, seed, flow=0.5, p90=20.0, angle=27.0, **q):
    """A calibration record with the numbers the rules read."""
    quantities = {"angle_deg": angle, **{k: 0.0 for k in DECISION + EQUAL_SLOPE_SECONDARY}, **q}
    return {"arm": arm, "protocol": arm.split()[0], "seed": seed,
            "growth": {"flow_fraction": flow, "flank_p90_deg": p90}, "quantities": quantities}


def arms(**spec):
    """Two piles per arm, each arm's (flow, p90, angle) from ``spec`` (defaults elsewhere)."""
    out = []
    for arm in decision.WEDGE_ARMS + decision.LAYERED_ARMS:
        flow, p90, angle = spec.get(arm.replace(" ", "_"), (0.5, 20.0, 27.0))
        out += [record(arm, s, flow, p90, angle) for s in (1, 2)]
    return out


def test_point_source_is_the_one_that_flows_more():
    assert decision.select_arms(arms(wedge_funnel=(0.9, 20, 27.0)))["point"] == "wedge funnel"
    assert decision.select_arms(arms(wedge_drip=(0.9, 20, 27.0)))["point"] == "wedge drip"
    assert decision.select_arms(arms())["point"] == "wedge drip"          # a tie keeps the drip


def test_layered_control_stays_below_repose_and_flows_least():
    # the point source (drip, flows more) rests at 28 deg: the layered arms must grow below 26 deg
    sel = decision.select_arms(arms(wedge_drip=(0.6, 27, 28.0), layered_top=(0.1, 27.5, 27.0),
                                    layered_rain=(0.3, 18.0, 20.0)))
    assert sel["qualified"] == ["layered rain"] and sel["layered"] == "layered rain"
    both = decision.select_arms(arms(wedge_drip=(0.6, 27, 28.0), layered_top=(0.1, 25.0, 27.0),
                                     layered_rain=(0.3, 18.0, 20.0)))
    assert both["layered"] == "layered top"                               # both below: the calmer one
    edge = decision.select_arms(arms(wedge_drip=(0.6, 27, 28.0), layered_top=(0.1, 26.0, 27.0),
                                     layered_rain=(0.3, 26.01, 20.0)))
    assert edge["qualified"] == ["layered top"]                           # 2 deg below, not less
    none = decision.select_arms(arms(wedge_drip=(0.6, 27, 28.0), layered_top=(0.1, 27.0, 27.0),
                                     layered_rain=(0.3, 26.5, 20.0)))
    assert none["layered"] is None


def test_an_arm_without_piles_is_refused():
    with pytest.raises(ValueError, match="layered rain.*1 calibration piles"):
        decision.select_arms([r for r in arms() if not (r["arm"] == "layered rain" and r["seed"] == 2)])


def test_pooled_sd_is_student_s():
    rng = np.random.default_rng(1)
    a, b = rng.normal(0, 1, 6), rng.normal(3, 2, 6)
    sd, df = decision.pooled_sd(a, b)
    # Student's pooled t: the difference over sd * sqrt(1/6 + 1/6)
    t = stats.ttest_ind(a, b, equal_var=True).statistic
    assert df == 10
    assert (a.mean() - b.mean()) / (sd * math.sqrt(2 / 6)) == pytest.approx(t, rel=1e-12)


def test_registered_size_has_its_power():
    """At the size the rule gives, Welch's test at 5 %/2 finds EFFECT in about 80 % of drawn ensembles,
    and at 3/4 of that size clearly less often."""
    sd = 0.06
    recs = [record("wedge drip", s, **{DECISION[0]: v}) for s, v in enumerate(np.linspace(-sd, sd, 6) * 1.1)]
    recs += [record("layered rain", s, **{DECISION[0]: v}) for s, v in enumerate(np.linspace(-sd, sd, 6) * 1.1)]
    need = decision.piles_required(recs, "wedge drip", "layered rain")
    n, scatter = need["n"], need["sd"]
    rng = np.random.default_rng(44)

    def power(m, reps=4000):
        a = rng.normal(-EFFECT, scatter, (reps, m))
        b = rng.normal(0.0, scatter, (reps, m))
        p = stats.ttest_ind(a, b, axis=1, equal_var=False).pvalue
        return np.mean(p < decision.LEVEL / len(DECISION))

    assert n >= decision.MIN_PILES
    # 4000 draws: the binomial standard error of 0.8 is 0.0063; 0.03 is almost five of them
    assert power(n) == pytest.approx(0.8, abs=0.03)
    assert power(int(0.75 * n)) < 0.75


def decision_records(shift, n=12, seed=3):
    rng = np.random.default_rng(seed)
    out = []
    for arm, mean in (("wedge funnel", shift), ("layered rain", 0.0)):
        for s in range(n):
            q = {DECISION[0]: rng.normal(mean, 0.05), DECISION[1]: rng.normal(mean, 0.09),
                 **{k: rng.normal(0, 1) for k in SECONDARY}, "centre_column": 0.01 * (s % 3)}
            out.append(record(arm, 1001 + s, **q))
    return out


def test_no_verdict_on_a_partial_ensemble():
    recs = decision_records(-0.1)
    with pytest.raises(ValueError, match="11 of the registered 12"):
        decision.verdict(recs[1:], "wedge funnel", "layered rain", 12)


def test_a_clear_minimum_is_found_and_sized():
    out = decision.verdict(decision_records(-0.15), "wedge funnel", "layered rain", 12)
    row = out["decision"][DECISION[0]]
    a = [r["quantities"][DECISION[0]] for r in decision_records(-0.15) if r["arm"] == "wedge funnel"]
    b = [r["quantities"][DECISION[0]] for r in decision_records(-0.15) if r["arm"] == "layered rain"]
    ref = stats.ttest_ind(a, b, equal_var=False)
    assert row["t"] == pytest.approx(ref.statistic, rel=1e-12)
    assert row["p"] == pytest.approx(ref.pvalue, rel=1e-9)
    assert out["finding"] == "minimum" and "stress_column" in out["sentence"]


def test_no_effect_gives_the_bound_of_the_interval():
    recs = decision_records(0.0)
    out = decision.verdict(recs, "wedge funnel", "layered rain", 12)
    a = [r["quantities"][DECISION[0]] for r in recs if r["arm"] == "wedge funnel"]
    b = [r["quantities"][DECISION[0]] for r in recs if r["arm"] == "layered rain"]
    ci = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert out["decision"][DECISION[0]]["ci95"] == pytest.approx((ci.low, ci.high), rel=1e-9)
    assert out["finding"] == "none"
    assert f"{100 * max(-ci.low, 0):.1f} %" in out["sentence"]


def _shaped(arm_effect, slope, angles):
    """Records whose D1 is ``slope * angle`` plus ``arm_effect`` on the point arm, with a
    little scatter that does not depend on either (so the least squares fit is exact in mean)."""
    rng = np.random.default_rng(7)
    out = []
    for arm, base in (("wedge funnel", angles[0]), ("layered rain", angles[1])):
        for seed in range(30):
            angle = base + rng.normal(0.0, 1.5)
            d1 = slope * angle + (arm_effect if arm == "wedge funnel" else 0.0) + rng.normal(0.0, 0.01)
            out.append(record(arm, seed, angle=angle, **{DECISION[0]: d1}))
    return out


def test_a_slope_effect_is_not_read_as_one_of_history():
    """D1 driven by the angle alone, arms 9° apart: the arm-plus-angle fit finds no arm effect
    (within 3 of its standard errors), the slope's coefficient is the one put in, and the
    verdict is flagged as of the sources as built."""
    out = decision.shape_check(_shaped(0.0, -0.006, (28.0, 19.0)), "wedge funnel", "layered rain")
    assert abs(out["arm_effect"]) < 3 * out["arm_se"]
    assert out["slope_effect"] == pytest.approx(-0.006, abs=3 * out["slope_se"])
    assert out["as_built"] and out["angle_diff"] == pytest.approx(9.0, abs=1.0)


def test_a_history_effect_at_equal_slope_is_found_by_the_fit():
    """Arms at one slope, a −5 % arm effect: the fit returns it (within 3 standard errors,
    which are small since arm and angle do not correlate) and the arms compare histories."""
    out = decision.shape_check(_shaped(-0.05, -0.006, (28.0, 28.0)), "wedge funnel", "layered rain")
    assert out["arm_effect"] == pytest.approx(-0.05, abs=3 * out["arm_se"])
    assert out["arm_se"] < 0.01 and not out["as_built"]
    assert abs(out["correlation"]) < 0.5


@pytest.mark.parametrize("shift", [0.0, 0.02, 0.045, -0.06])
def test_equivalence_is_the_90_percent_interval_inside_the_margin(shift):
    """Schuirmann's two one-sided tests at 5 % are equivalent to the 90 % Welch interval lying
    inside ±margin; scipy's interval decides it independently."""
    rng = np.random.default_rng(11)
    a, b = rng.normal(shift, 0.05, 40), rng.normal(0.0, 0.07, 40)
    out = tost(a, b, 0.05)
    ci = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.90)
    assert out["equivalent"] == (ci.low > -0.05 and ci.high < 0.05)
    # at the margin's edge the one-sided p values are those of shifted Welch tests
    assert out["p_low"] == pytest.approx(stats.ttest_ind(a + 0.05, b, equal_var=False,
                                                         alternative="greater").pvalue, rel=1e-9)
    assert out["p_high"] == pytest.approx(stats.ttest_ind(a - 0.05, b, equal_var=False,
                                                          alternative="less").pvalue, rel=1e-9)


@pytest.mark.parametrize("shift, finding", [(-0.08, "history"), (0.0, "shape"), (0.08, "opposite")])
def test_the_equal_slope_outcomes(shift, finding):
    """D1 alone, a 5 % margin, 40 piles per arm at D1's scatter of 0.05: a clear minimum is
    "history", no difference "shape" (the 90 % interval's half width, about 1.65 x 0.011, is
    far inside 5 %), a clear excess "opposite"."""
    recs = decision_records(shift, n=40, seed=5)
    out = decision.verdict(recs, "wedge funnel", "layered rain", 40, family=DECISION[:1], margin=0.05)
    assert out["finding"] == finding
    assert list(out["decision"]) == [DECISION[0]]


def test_too_few_piles_to_tell_is_no_effect_larger_than_the_interval():
    """Eight piles per arm at a scatter of 0.05: neither the test nor the equivalence
    decides, and the sentence bounds the effect by its 95 % interval."""
    recs = decision_records(0.02, n=8, seed=5)
    out = decision.verdict(recs, "wedge funnel", "layered rain", 8, family=DECISION[:1], margin=0.05)
    ci = out["decision"][DECISION[0]]["ci95"]
    assert out["finding"] == "none" and not out["equivalence"]["equivalent"]
    assert f"{100 * max(abs(ci[0]), abs(ci[1])):.1f} %" in out["sentence"]


def test_scaled_windows_cut_piles_of_two_widths_at_the_same_fractions():
    """Two piles whose σ_yy/p_u rows are the same function of x over the half width, one
    twice as wide: the scaled D1 is the same for both (to the grid's sampling), while the
    fixed windows read them differently."""
    def pile(half):
        x = np.arange(-half, half + 1e-9, 0.015)
        ratio = 1.0 - 0.3 * np.exp(-(x / (0.2 * half)) ** 2)       # a dip 20 % of the half width wide
        return {"quantities": {"width": 2 * half},
                "inputs": {"stress_column": {"x": x.tolist(), "sigma_yy": ratio.tolist(),
                                             "p_u": np.ones_like(x).tolist()}}}
    narrow, wide = pile(0.35), pile(0.70)
    assert decision.scaled_stress_column(narrow) == pytest.approx(decision.scaled_stress_column(wide), abs=0.02)
    assert decision.scaled_stress_column(narrow) < -0.1
    fixed = {"centre": 0.03, "shoulder_inner": 0.06, "shoulder_outer": 0.15}
    read = [row_contrast(np.asarray(p["inputs"]["stress_column"]["sigma_yy"]),
                         np.asarray(p["inputs"]["stress_column"]["x"]), fixed) for p in (narrow, wide)]
    assert abs(read[0] - read[1]) > 0.05
    assert math.isnan(decision.scaled_stress_column({"quantities": {"width": 0.7}}))


def _pilot(arm, angle, interior, flow=0.0, n=6):
    return [{"arm": arm, "seed": s, "quantities": {"angle_deg": angle + 0.2 * (s - 2.5)},
             "growth": {"interior_share": interior + 0.01 * (s - 2.5), "flow_fraction": flow}}
            for s in range(n)]


def test_the_control_is_the_steep_enough_layered_arm_nearest_the_funnel_s_slope():
    """Reference 28°: a rain at 26.5° is too flat, one at 27.6° and one at 28.3° qualify
    (both lay their interior down far more than the funnel), the nearer (28.3°) is chosen;
    a steep arm that flows like the funnel does not qualify on its interior."""
    recs = (_pilot("wedge funnel", 28.0, 0.005, 1.0) + _pilot("rain 26", 26.5, 0.7)
            + _pilot("rain 28", 27.6, 0.7) + _pilot("rain 29", 28.3, 0.6, 0.1)
            + _pilot("rain flowing", 28.0, 0.05, 0.9))
    out = decision.pick_control(recs, "wedge funnel", [27.5, 28.5])
    assert out["reference"] == pytest.approx(28.0)
    assert out["qualified"] == ["rain 28", "rain 29"] and out["control"] == "rain 29"
    assert not out["arms"]["rain flowing"]["interior"] and out["arms"]["rain flowing"]["slope"]


def test_a_tie_of_slopes_goes_to_the_arm_that_flows_less():
    recs = (_pilot("wedge funnel", 28.0, 0.005, 1.0) + _pilot("rain a", 27.95, 0.7, 0.2)
            + _pilot("rain b", 28.02, 0.7, 0.05))
    assert decision.pick_control(recs, "wedge funnel", [28.0])["control"] == "rain b"
    flat = _pilot("wedge funnel", 28.0, 0.005, 1.0) + _pilot("rain", 25.0, 0.7)
    assert decision.pick_control(flat, "wedge funnel", [28.0])["control"] is None


def _packed(arm_effect, coefficient, rng, n=30, gap=1.0, spread=0.4):
    """Records whose D1 is ``coefficient * packing`` plus ``arm_effect`` on the point arm,
    the packing `gap` higher on the layered arm (so it goes with the arm), with scatter."""
    out = []
    for arm, base in (("wedge funnel", 0.0), ("layered rain", gap)):
        for seed in range(n):
            packing = base + rng.normal(0.0, spread)
            d1 = coefficient * packing + (arm_effect if arm == "wedge funnel" else 0.0) + rng.normal(0.0, 0.05)
            out.append(record(arm, seed, solid_fraction=packing, **{DECISION[0]: d1}))
    return out


def test_a_covariate_that_goes_with_the_arm_inflates_the_arm_error_as_the_textbook_says():
    """OLS with an intercept: var(b_arm) = s² / (SST_arm (1 − r²)), s² the residual variance
    on n − 3 degrees of freedom; the fit's error and inflation factor obey it to rounding,
    computed here from the residuals of scipy's least squares."""
    recs = _packed(0.05, 0.02, np.random.default_rng(3))
    fit = decision.covariate_fit(recs, "wedge funnel", "layered rain", DECISION[0], "solid_fraction")
    arm = np.array([r["arm"] == "wedge funnel" for r in recs], float)
    cov = np.array([r["quantities"]["solid_fraction"] for r in recs])
    y = np.array([r["quantities"][DECISION[0]] for r in recs])
    x = np.column_stack([np.ones_like(y), arm, cov])
    coef, *_ = linalg.lstsq(x, y)
    s2 = np.sum((y - x @ coef) ** 2) / (y.size - 3)
    r = stats.pearsonr(arm, cov)[0]
    assert fit["correlation"] == pytest.approx(r, rel=1e-12)
    assert fit["inflation"] == pytest.approx(1 / (1 - r * r), rel=1e-12)
    sst = np.sum((arm - arm.mean()) ** 2)
    assert fit["arm_se"] ** 2 == pytest.approx(s2 / (sst * (1 - r * r)), rel=1e-9)
    assert fit["arm_effect"] == pytest.approx(coef[1], rel=1e-9)
    assert fit["effect"] == pytest.approx(coef[2], rel=1e-9)
    assert fit["arms"]["layered rain"][0] - fit["arms"]["wedge funnel"][0] == pytest.approx(1.0, abs=0.3)


def test_the_arm_error_of_a_covariate_fit_is_the_spread_of_its_estimate():
    """Over 400 drawn ensembles with a covariate that goes with the arm (r about −0.8), the
    arm effect is unbiased and its reported standard error is the spread of the estimates:
    the spread of 400 draws is known to about 4 %, so 15 % is more than three of its errors."""
    rng = np.random.default_rng(19)
    fits = [decision.covariate_fit(_packed(0.05, 0.02, rng), "wedge funnel", "layered rain",
                                   DECISION[0], "solid_fraction") for _ in range(400)]
    est = np.array([f["arm_effect"] for f in fits])
    se = np.array([f["arm_se"] for f in fits])
    assert np.mean([f["correlation"] for f in fits]) == pytest.approx(-0.78, abs=0.1)
    assert abs(est.mean() - 0.05) < 4 * est.std() / np.sqrt(est.size)
    assert est.std(ddof=1) == pytest.approx(se.mean(), rel=0.15)
