"""A decision pile without its gravity probe: the statistics the decision reads do not change.

The gravity probe (``probe.levels``) runs after the relaxation and only adds
states after it, so every number of a pile's record that is read from the
poured and relaxed states must come out the same, bit for bit, when the probe
is cut (``probe: {levels: []}``, outputs without strain and fits), and every
number read from the probe must be NaN.  Here the calibration tool makes both
records of one tiny funnel pile, each pile poured, relaxed and analysed by the
workflow in its own working directory (same code, seed and machine): the
relaxed states must be equal, the quantities the decision statistics read
equal, the probe's quantities finite with the probe and NaN without.  The
settings it cannot run are refused before any pile.
"""

import json
import math
from pathlib import Path

import pytest
import xarray as xr
import yaml

from test_workflow import copy_workflow
from workflow.tools import calibration
from workflow.tools._cli import Refusal
from workflow.tools._records import check_registered

REPO = Path(__file__).resolve().parents[1]

#: Tiny piles: 200 of the study's particles from the equal-slope decision's funnel, about
#: 5 cm high and 30 cm wide, with the RVE grid and the windows scaled to them and the balance
#: checks reported, not enforced (a pile this small need not pass them).
TINY = {"threads": 1, "outputs": ["states", "fields", "strain", "fabric", "fits"],
        "pour": {"n_particles": 200, "point_source": "funnel"},
        "relax": {"max_time": 3.0},
        "analysis": {"grid": {"x_min": -0.15, "x_max": 0.15, "y_min": 0.01, "y_max": 0.05, "spacing": 0.01},
                     "rve": {"size": 0.03, "min_particles": 8, "min_solid_fraction": 0.5},
                     "strain": {"min_contacts": 6},
                     "base_pressure": {"x_min": -0.2, "x_max": 0.2},
                     "checks": {"enforce": False},
                     "convergence": {"points": [[0.0, 0.015]], "sizes": [0.01, 0.02, 0.03]},
                     "figures": {"heights": [0.01, 0.02]},
                     "history": {"centre": 0.015, "shoulder_inner": 0.03, "shoulder_outer": 0.07,
                                 "primary_height": 0.015, "core_height": 0.04,
                                 "flank_inner": 0.03, "flank_outer": 0.1, "flank_height": 0.03}}}
#: The cut, as a plan asks for it.
NO_PROBE = {"probe": {"levels": []}, "outputs": ["states", "fields", "fabric"]}


def plan(settings):
    """A registration of one pile of :data:`TINY` per arm: ``probed`` as the decision's piles
    are, ``unprobed`` with `settings` on top."""
    return {"piles": "config/tiny_piles.yaml", "frame_interval": 0.05, "seeds": [11],
            "arms": {"probed": {"protocol": "wedge", "settings": {}},
                     "unprobed": {"protocol": "wedge", "settings": settings}}}


@pytest.fixture
def workflow(tmp_path, monkeypatch):
    """A copy of the workflow with :data:`TINY` as ``config/tiny_piles.yaml``, which the tool runs:
    its jobs import the copy's code (they run in the piles' folders, not in the copy), whose
    kernels the copy holds compiled."""
    root = copy_workflow(tmp_path / "wf")
    (root / "config" / "tiny_piles.yaml").write_text(yaml.safe_dump(TINY))
    monkeypatch.setenv("PYTHONPATH", str(root))
    monkeypatch.setattr(calibration, "REPO", root)
    monkeypatch.setattr(calibration, "commit_of", lambda folder: "copy")   # the copy is no git checkout
    return root


def test_a_pile_without_the_probe_keeps_every_statistic_the_decision_reads(workflow):
    cal = plan(NO_PROBE)
    records = {arm: json.loads(calibration.run_pile(cal, arm, 11, workflow / "records").read_text())
               for arm in cal["arms"]}
    probed, unprobed = records["probed"], records["unprobed"]
    # one relaxed state: every variable and attribute but when it was written (and the digest over that)
    states = {arm: xr.load_dataset(workflow / "results" / "calibration" / arm / "seed11" / "results" / "study"
                                   / "piles" / "wedge" / "seed11" / "relaxed.nc") for arm in cal["arms"]}
    xr.testing.assert_equal(states["probed"], states["unprobed"])
    attrs = {arm: {k: str(v) for k, v in ds.attrs.items() if k not in ("history", "data_digest")}
             for arm, ds in states.items()}
    assert attrs["probed"] == attrs["unprobed"]
    assert not list((workflow / "results" / "calibration" / "unprobed" / "seed11").rglob("reduced.nc"))

    # what the decision statistics read: bit for bit (a float's JSON text is its exact value), and
    # finite, so that equal says something
    for key in ("stress_column", "base_pressure_column", "centre_column", "angle_deg", "height", "width",
                "solid_fraction"):
        assert math.isfinite(probed["quantities"][key]), key
        assert bits(unprobed["quantities"][key]) == bits(probed["quantities"][key]), key
    assert bits(unprobed["inputs"]) == bits(probed["inputs"])
    assert bits(unprobed["growth"]) == bits(probed["growth"])
    assert math.isfinite(probed["growth"]["interior_share"])

    # what the probe gives: finite with it, NaN without; every other quantity the same
    from_probe = {k for k in probed["quantities"]
                  if k.startswith(("strain@", "gravity_")) or k in ("youngs_modulus", "bulk_modulus")}
    assert {"strain@1.5", "gravity_gap", "youngs_modulus", "bulk_modulus"} <= from_probe
    assert all(math.isfinite(probed["quantities"][k]) for k in ("strain@1.5", "gravity_gap"))
    assert unprobed["quantities"].keys() == probed["quantities"].keys()
    for key, value in probed["quantities"].items():
        if key in from_probe:
            assert math.isnan(unprobed["quantities"][key]), key
        else:
            assert bits(unprobed["quantities"][key]) == bits(value), key

    # the record says which, and what the cut saved
    assert (probed["definitions"]["probe_levels"], unprobed["definitions"]["probe_levels"]) == ([0.1], [])
    assert probed["cpu_s"]["probe"] > 0 and unprobed["cpu_s"]["probe"] == 0
    assert unprobed["cpu_s"]["total"] == pytest.approx(unprobed["cpu_s"]["pour"] + unprobed["cpu_s"]["relax"])


@pytest.mark.parametrize("settings, words", [
    ({"probe": {"levels": []}}, "probe.levels is []"),                                   # strain without a probe
    ({"outputs": ["states", "fields", "fabric"]}, "probe.levels [0.1] with outputs"),    # a probe without its strain
    ({**NO_PROBE, "outputs": ["states", "fields"]}, "a pile's record reads the fabric"),
])
def test_settings_whose_pile_cannot_make_its_record_are_refused_before_any_pile(workflow, settings, words):
    with pytest.raises(Refusal) as refusal:
        calibration.main(["--config", str(write_plan(workflow, plan(settings))), "--records",
                          str(workflow / "records")])
    message = str(refusal.value)
    assert "arm 'unprobed'" in message and words in message and "\n" not in message
    assert not (workflow / "results").exists()


def test_a_record_probed_otherwise_than_its_registration_is_refused():
    """A registration that probes its piles (the equal-slope decision's) holds a record probed at its
    levels and refuses one made without the probe: a cut is registered before its piles."""
    plan = REPO / "config" / "decision_equal_slope.yaml"
    path = REPO / "docs" / "reproduction" / "decision_equal_slope" / "wedge_funnel-seed2001.json"
    record = json.loads(path.read_text())
    record["definitions"]["probe_levels"] = [0.1]
    check_registered({path: record}, plan)
    record["definitions"]["probe_levels"] = []
    with pytest.raises(Refusal, match=r"probe\.levels \[\]; .* registers probe\.levels \[0\.1\]"):
        check_registered({path: record}, plan)


def bits(value) -> str:
    """`value` as JSON text: equal texts are equal numbers to the last bit, NaN included."""
    return json.dumps(value)


def write_plan(root: Path, cal: dict) -> Path:
    """`cal` as a settings file in `root`."""
    path = root / "config" / "tiny_plan.yaml"
    path.write_text(yaml.safe_dump(cal))
    return path
