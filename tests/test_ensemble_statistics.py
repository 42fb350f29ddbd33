"""Statistics over an ensemble of piles (analysis/ensemble_statistics.py) worked by hand
and against scipy: the difference of two sets with its power (against a Monte Carlo of the
test it sizes), the Welch family with Holm's correction, differences paired by seed, a
variant of one pile against the study, and the exact rank test.  Welch, Holm and the
power of the t test that decide the report: test_reproduction_report.py."""

import numpy as np
import pytest
from scipy import stats

from analysis.ensemble_statistics import (against_reference, bonferroni_z, compare, detection_factor, holm,
                                          paired_difference, rank_test, t_threshold, welch, welch_family)


def test_compare_gives_the_difference_its_standard_error_and_z_worked_by_hand():
    c = compare([1.0, 2.0, 3.0], [5.0, 6.0, 7.0, np.nan])
    se = np.hypot(1 / np.sqrt(3), 1 / np.sqrt(3))
    assert c["diff"] == -4.0 and c["se"] == pytest.approx(se) and c["z"] == pytest.approx(-4 / se)
    assert c["a"][3] == 3 and c["b"][3] == 3
    assert c["mdd_2se"] == pytest.approx(2 * se)
    # sd 1 in both: 4 (1 + 1) / 0.05^2 = 3200 piles put 5 % at 2 SE
    assert c["n_2se"][0.05] == 3200


def test_detection_factor_and_bonferroni_are_the_normal_quantiles():
    assert detection_factor() == pytest.approx(1.959964 + 0.841621, abs=1e-5)
    assert bonferroni_z(5) == pytest.approx(2.575829, abs=1e-5)   # 0.05 / 5 two-sided


def test_the_piles_the_power_figure_asks_for_do_see_the_effect_four_times_in_five():
    rng = np.random.default_rng(0)
    sd, delta = 0.12, 0.05
    n = int(compare(rng.normal(0, sd, 2000), rng.normal(0, sd, 2000))["n_power"][delta])
    assert 80 < n < 120       # (2.80 0.12 / 0.05)^2 x 2 = 90, from the estimated SDs
    hits = 0
    for _ in range(2000):
        a, b = rng.normal(delta, sd, n), rng.normal(0.0, sd, n)
        hits += abs(compare(a, b)["z"]) > 1.96
    assert hits / 2000 == pytest.approx(0.80, abs=0.04)


def test_the_welch_family_is_welch_per_statistic_with_holm_over_them():
    rng = np.random.default_rng(5)
    samples = {k: (rng.normal(shift, 1.0, 9), rng.normal(0.0, 1.5, 11)) for k, shift in
               (("big", 2.0), ("small", 0.4), ("none", 0.0))}
    rows = welch_family(samples)
    assert list(rows) == ["big", "small", "none"]
    adjusted, rejected = holm([welch(*samples[k])["p"] for k in rows])
    for (k, (a, b)), p, rej in zip(samples.items(), adjusted, rejected):
        r = rows[k]
        scipy = stats.ttest_ind(a, b, equal_var=False)
        assert r["t"] == pytest.approx(scipy.statistic) and r["p"] == pytest.approx(scipy.pvalue)
        assert r["diff"] == pytest.approx(a.mean() - b.mean())
        assert r["se"] == pytest.approx(np.hypot(a.std(ddof=1) / 3, b.std(ddof=1) / np.sqrt(11)))
        low, high = scipy.confidence_interval(0.95)
        assert r["ci95"] == pytest.approx((low, high))
        assert r["t_family"] == pytest.approx(t_threshold(r["df"], 3))
        assert (r["p_holm"], r["rejected"]) == (pytest.approx(p), rej)
        assert r["a"][3] == 9 and r["b"][3] == 11
    assert rows["big"]["rejected"] and not rows["none"]["rejected"]


def test_differences_paired_by_seed_use_the_seeds_both_sets_hold():
    new = {1: 1.5, 2: 2.5, 3: 4.0, 7: 100.0}
    old = {1: 1.0, 2: 2.0, 3: 3.0, 9: -100.0}
    m, se, sd, n = paired_difference(new, old)
    assert (m, n) == (pytest.approx(2.0 / 3.0), 3)
    assert sd == pytest.approx(np.std([0.5, 0.5, 1.0], ddof=1)) and se == pytest.approx(sd / np.sqrt(3))
    assert paired_difference({1: 1.0}, {2: 1.0})[3] == 0


def test_one_variant_pile_borrows_the_studys_scatter():
    study = [1.0, 2.0, 3.0, 4.0]
    one = against_reference([5.0], study)
    sd = np.std(study, ddof=1)
    assert one["single"] and one["diff"] == pytest.approx(2.5)
    assert one["se"] == pytest.approx(np.hypot(sd / 2, sd))            # the study's SE and SD
    two = against_reference([5.0, 7.0], study)
    assert not two["single"] and two["se"] == pytest.approx(np.hypot(sd / 2, np.sqrt(2) / np.sqrt(2)))


def test_the_rank_test_is_the_exact_mann_whitney_p():
    # two values below eight: the most extreme of C(10, 2) = 45 orderings, either way
    assert rank_test([0.0, 0.1], [1.0 + i for i in range(8)]) == pytest.approx(2 / 45)
    assert rank_test([1.0, np.nan, 4.0], [2.0, 3.0]) == pytest.approx(1.0)
    assert np.isnan(rank_test([], [1.0]))
