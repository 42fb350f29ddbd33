"""The step-error table's rule (analysis/step_error.py, docs/reproduction/step_error_plan.md).

The paired bias and its interval are checked against scipy's own Student-t
interval; the rule's two verdicts (a cell resolved beyond a quarter of the
scatter, the cheapest admissible step) on cases whose answer is known by
construction; and the tool, end to end, on records made from the decision's
own piles with a known bias added.
"""

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from analysis.step_error import Cell, choose_step, paired_bias
from workflow.tools import step_error as tool
from workflow.tools._records import read_registration

REPO = Path(__file__).resolve().parents[1]
PLAN = REPO / "config" / "step_error.yaml"


def test_paired_bias_is_scipys_t_interval():
    """Bias, SE and half-width are those of the paired differences' one-sample t interval."""
    rng = np.random.default_rng(7)
    ref = {s: float(v) for s, v in zip(range(6), rng.normal(0.0, 1.0, 6))}
    cand = {s: ref[s] + 0.3 + float(e) for s, e in zip(range(6), rng.normal(0.0, 0.5, 6))}
    pool = rng.normal(0.0, 2.0, 40)
    c = paired_bias(cand, ref, pool)
    d = np.array([cand[s] - ref[s] for s in range(6)])
    lo, hi = stats.t.interval(0.95, 5, loc=d.mean(), scale=stats.sem(d))
    assert c.n == 6 and c.bias == pytest.approx(d.mean())
    assert c.half_width == pytest.approx((hi - lo) / 2)
    assert c.scatter == pytest.approx(np.std(pool, ddof=1))
    assert c.pairing == pytest.approx(np.std(d, ddof=1) / np.std(pool, ddof=1))
    assert c.bound == pytest.approx((abs(d.mean()) + (hi - lo) / 2) / np.std(pool, ddof=1))


def test_only_seeds_in_both_with_finite_values_pair():
    """A seed poured at one step only, or not measured (NaN), is no pair."""
    c = paired_bias({1: 1.0, 2: 2.0, 3: math.nan, 4: 5.0}, {1: 0.0, 2: 1.5, 3: 0.0, 5: 0.0}, [0.0, 1.0, 2.0])
    assert c.n == 2 and c.bias == pytest.approx(0.75)


def test_a_cell_fails_only_when_its_interval_lies_beyond_a_quarter():
    """A constant shift of 0.3 σ (no noise: the interval is the point) fails; 0.2 σ does not;
    a shift of 2 σ buried in noise of 3 σ per pair is not resolved with six pairs."""
    pool = [-1.0, 1.0] * 20                                   # σ = 1.0127
    sigma = np.std(pool, ddof=1)
    ref = {s: 0.0 for s in range(6)}
    eps = [1e-9, -1e-9] * 3
    assert paired_bias({s: 0.3 * sigma + eps[s] for s in range(6)}, ref, pool).fails(0.25)
    assert not paired_bias({s: 0.2 * sigma + eps[s] for s in range(6)}, ref, pool).fails(0.25)
    noisy = {s: 2 * sigma + 3 * sigma * v for s, v in enumerate([-1.5, 1.5, -1.0, 1.0, -0.5, 0.5])}
    c = paired_bias(noisy, ref, pool)
    assert c.bias == pytest.approx(2 * sigma) and not c.fails(0.25) and c.bound > 2


def test_choose_step_takes_the_cheapest_admissible_below_the_reference():
    """Incomplete or failing candidates are passed over; a candidate dearer than the reference never wins."""
    ok, bad = Cell(6, 0.0, 0.1, 0.2, 1.0, 1.0), Cell(6, 1.0, 0.01, 0.02, 1.0, 0.1)
    cells = {"a": [ok], "b": [ok], "c": [bad], "d": [ok]}
    cost = {"a": 90.0, "b": 70.0, "c": 50.0, "d": 40.0}
    chosen, reasons = choose_step(cost, 110.0, {"a": (12, 12), "b": (12, 12), "c": (12, 12), "d": (11, 12)},
                                  cells, 0.25)
    assert chosen == "b" and "d: not admissible, 11 of its 12 piles completed" in reasons
    assert choose_step({"a": 120.0}, 110.0, {"a": (12, 12)}, {"a": [ok]}, 0.25)[0] is None


def test_the_tool_finds_a_bias_put_into_copies_of_the_decision_piles(tmp_path):
    """Candidate records made from the reference's seeds 2001-2006: D1 shifted by 2 σ at one step
    (it must fail there), unchanged at the others; the cheapest unbiased step is chosen."""
    reg = read_registration(PLAN)
    ref_folder = REPO / reg["reference"]["records"]
    refs = [json.loads(p.read_text()) for p in sorted(ref_folder.glob("*.json"))]
    sigma = np.std([r["quantities"]["stress_column"] for r in refs if r["arm"] == "wedge funnel"], ddof=1)
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    cost = {"verlet 0.8": 0.6, "verlet 1.0": 0.5, "gear 1.0": 1.8}
    for k, (arm, spec) in enumerate(reg["arms"].items()):
        for seed in reg["seeds"]:
            (r,) = [r for r in refs if r["arm"] == spec["reference"] and r["seed"] == seed]
            r = json.loads(json.dumps(r))
            r.update(arm=arm, settings=spec["settings"], commit=head)
            if spec["step"] == "verlet 1.0" and spec["reference"] == "wedge funnel":
                r["quantities"]["stress_column"] += 2 * sigma
            r["cpu_s"]["total"] *= cost[spec["step"]]
            r["quantities"]["width"] += 1e-9 * (k + 1)        # each a pile of its own, not a copy
            (tmp_path / f"{arm.replace(' ', '_')}-seed{seed}.json").write_text(json.dumps(r))
    text = tool.page(PLAN, tmp_path)
    assert "verlet 1.0: not admissible, 1 cell(s)" in text
    assert "**The step chosen: verlet 0.8**" in text
    assert "gear 1.0: admissible" in text and text.count(" **fails** |") == 1
