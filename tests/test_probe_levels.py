"""The probe-level study (workflow/tools/probe_levels.py) on probe files whose
answer is known: a pile answering in proportion to the reduction, one whose
strain grows as its square, a partial restoration, a slip."""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from analysis.params import resolve_params
from analysis.probes import pile_levels
from workflow.tools import probe_levels as levels

PARAMS = resolve_params({})


def _probes(u_of_level, restored_fraction=0.1, slip_at=None):
    x = np.round(np.arange(-0.3, 0.3 + 1e-9, 0.015), 6)
    y = np.round(np.arange(0.015, 0.15 + 1e-9, 0.015), 6)
    names = ["reduced", "reduced05", "reduced15", "restored"]
    u = np.zeros((4, y.size, x.size, 2, 2))
    base = 1e-4 * (1 + 0.2 * np.cos(x / 0.3))[None, :] * np.ones((y.size, 1))
    for k, d in enumerate([0.10, 0.05, 0.15]):
        u[k, ..., 1, 1] = base * u_of_level(d)
    u[3, ..., 1, 1] = -restored_fraction * u[0, ..., 1, 1]
    if slip_at is not None:
        u[names.index(slip_at), 2, x.size // 2, 1, 1] *= 100.0
    return xr.Dataset({"strain_increment": (("probe", "y", "x", "i", "j"), u),
                       "stress_increment": (("probe", "y", "x", "i", "j"), np.zeros_like(u))},
                      coords={"probe": names, "y": y, "x": x, "i": ["x", "y"], "j": ["x", "y"]})


def test_a_pile_answering_in_proportion_is_linear_and_nine_tenths_reversible():
    out = pile_levels(_probes(lambda d: d / 0.10), PARAMS)
    assert out["linearity"]["reduced05"] == pytest.approx(0.0, abs=1e-12)
    assert out["linearity"]["reduced15"] == pytest.approx(0.0, abs=1e-12)
    assert out["reversibility"] == pytest.approx(0.9)
    assert out["slips"] == {"reduced": 0, "reduced05": 0, "reduced15": 0, "restored": 0}


def test_a_strain_growing_as_the_square_of_the_reduction():
    out = pile_levels(_probes(lambda d: (d / 0.10) ** 2), PARAMS)
    # u/Delta grows as Delta: 0.05/0.10 - 1 and 0.15/0.10 - 1
    assert out["linearity"]["reduced05"] == pytest.approx(-0.5)
    assert out["linearity"]["reduced15"] == pytest.approx(0.5)


def test_a_slip_is_counted_under_its_probe_only():
    out = pile_levels(_probes(lambda d: d / 0.10, slip_at="reduced15"), PARAMS)
    assert out["slips"]["reduced15"] == 1 and out["slips"]["reduced"] == 0


def test_the_report_sets_ramp_against_step_pile_by_pile():
    step = pile_levels(_probes(lambda d: d / 0.10), PARAMS)
    ramp = pile_levels(_probes(lambda d: 0.8 * d / 0.10), PARAMS)   # 20 % stiffer
    text = levels.report({"step": {"wedge": [step, step]}, "ramp": {"wedge": [ramp, ramp]}}, 0.1)
    assert "wedge -20.0 ± 0.0 %" in text


@pytest.mark.parametrize("scene", ["probe_levels.yaml", "probe_levels_ramp.yaml"])
def test_the_probe_level_scenes_are_valid_over_the_sweep_piles_and_keep_the_papers_reduction_first(scene):
    import yaml

    from workflow.validation import validate_config

    root = Path(__file__).resolve().parents[1] / "config"
    merged = {}
    for layer in (root / "config.yaml", root / "sweep_piles.yaml", root / "scenes" / scene):
        for key, value in yaml.safe_load(layer.read_text()).items():
            merged[key] = {**merged[key], **value} if isinstance(value, dict) and isinstance(merged.get(key), dict) \
                else value
    validate_config(merged)
    assert merged["probe"]["levels"][0] == 0.10 and sorted(merged["probe"]["levels"]) == [0.05, 0.10, 0.15]
    assert merged["probe"]["restore"] and merged["probe"]["mode"] == ("ramp" if "ramp" in scene else "step")
