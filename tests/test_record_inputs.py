"""Every committed pile record that carries the inputs of D1 and D2 gives them back.

A record of the decision piles keeps, beside its scalars, the numbers they are
computed from (``inputs``: D1's grid row and D2's support bins, each with the
pressure of a uniform column, and the windows).  Here D1 and D2 are
recomputed from those numbers alone by the rule as
docs/reproduction/preregistration.md states it, written out in this file,
not by the analysis's code: ``mean(centre) / mean(shoulders) - 1`` of
``sigma_yy / p_u`` (D1), and ``(mean p(centre) / mean p_u(centre)) /
(mean p(shoulders) / mean p_u(shoulders)) - 1`` (D2), windows by ``|x|`` of
the column or bin, NaN values left out of each mean.  Agreement to 1e-9
(relative) says the record's scalars are the ones its inputs give: the same
arithmetic on the same numbers, in another order.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
#: The folders of per-pile records (one JSON object per pile).
FOLDERS = ("decision", "calibration", "levers", "equal_slope", "decision_equal_slope", "decision_equal_slope_3500",
           "step_error", "step_error_limit")
RECORDS = sorted(p for folder in FOLDERS for p in (REPO / "docs" / "reproduction" / folder).rglob("*.json")
                 if "inputs" in json.loads(p.read_text()))


def _in(x, lo, hi):
    ax = np.abs(np.asarray(x, float))
    return (ax >= lo - 1e-9) & (ax <= hi + 1e-9)


def _mean(values):
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return v.mean() if v.size else math.nan


def d1(inputs):
    """D1 from a record's inputs, by the registered rule."""
    row, w = inputs["stress_column"], inputs["windows"]
    ratio = np.asarray(row["sigma_yy"], float) / np.asarray(row["p_u"], float)
    centre = _in(row["x"], 0.0, w["centre"])
    shoulders = _in(row["x"], w["shoulder_inner"], w["shoulder_outer"])
    return _mean(ratio[centre]) / _mean(ratio[shoulders]) - 1.0


def d2(inputs):
    """D2 from a record's inputs, by the registered rule."""
    bins, w = inputs["base_pressure_column"], inputs["windows"]
    p, pu = np.asarray(bins["p"], float), np.asarray(bins["p_u"], float)
    centre = _in(bins["x"], 0.0, w["centre"])
    shoulders = _in(bins["x"], w["shoulder_inner"], w["shoulder_outer"])
    return (_mean(p[centre]) / _mean(pu[centre])) / (_mean(p[shoulders]) / _mean(pu[shoulders])) - 1.0


def test_records_with_inputs_exist():
    """The equal-slope records carry their inputs (an empty list would test nothing)."""
    assert any("equal_slope" in str(p) for p in RECORDS), \
        "no committed record under docs/reproduction/equal_slope/ carries its inputs"


@pytest.mark.parametrize("path", RECORDS, ids=lambda p: str(p.relative_to(REPO / "docs" / "reproduction")))
def test_d1_and_d2_recomputed_from_the_record(path):
    record = json.loads(path.read_text())
    q, inputs = record["quantities"], record["inputs"]
    assert d1(inputs) == pytest.approx(q["stress_column"], rel=1e-9, nan_ok=True)
    assert d2(inputs) == pytest.approx(q["base_pressure_column"], rel=1e-9, nan_ok=True)


def test_a_pile_record_gives_the_inputs_of_its_own_d1_and_d2():
    """analysis.pile_quantities.pile_record, which writes a record's numbers, on a committed
    study pile: its inputs give back its D1 and D2 by the registered rule, and its D1 is the
    study's own (analysis.history.pile_stress_contrasts) of the same fields."""
    import yaml

    from analysis.fields import read_fields
    from analysis.history import pile_stress_contrasts
    from analysis.params import resolve_params
    from analysis.pile_quantities import pile_record

    params = resolve_params(yaml.safe_load((REPO / "config" / "config.yaml").read_text())["analysis"])
    stem = REPO / "docs" / "reproduction" / "wedge" / "seed2"
    q, inputs = pile_record(Path(f"{stem}.summary.json"), Path(f"{stem}.fields.nc"),
                            Path(f"{stem}.base_pressure.nc"), params)
    assert math.isfinite(q["stress_column"]) and math.isfinite(q["base_pressure_column"])
    assert d1(inputs) == pytest.approx(q["stress_column"], rel=1e-9)
    assert d2(inputs) == pytest.approx(q["base_pressure_column"], rel=1e-9)
    with read_fields(f"{stem}.fields.nc") as f:
        assert q["stress_column"] == pile_stress_contrasts(f, params)["stress_column"]
    assert {"fabric_deviator", "fabric_axis_deg", "angle_deg"} <= set(q)
