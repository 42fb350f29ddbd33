"""The settings a pour or its relaxation would refuse when it starts are refused
by :func:`sim.preflight.check_piles` from the settings alone (issue 47, item 2:
before any job of the workflow).

Each case is one the pour itself refuses (:func:`sim.pour.pour`, asserted here
on the same settings) or a stage's rule (the relaxation's number of steps),
so the preflight agrees with the runs it stands in for; the study's settings
pass.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from sim.config import SimConfig
from sim.pour import pour
from sim.preflight import check_piles

REPO = Path(__file__).resolve().parents[1]
SMALL = {"pour": {"n_particles": 40}}


def _cfg(change):
    data = json.loads(json.dumps(SMALL))
    for section, values in change.items():
        data.setdefault(section, {}).update(values)
    return SimConfig.from_dict(data)


#: setting changed -> words the refusal must contain (the setting and its value)
POURS_REFUSE = {
    "too flat a recipe": ({"particles": {"semi_axis_spread": 0.9}},
                          ["particles:", "semi_axis_spread = 0.9", "draw no valid polygon"]),
    "a fall from 100 m": ({"pour": {"release_height": 100.0}},
                          ["pour.release_height = 100", "allowed: at most"]),
    "a fall from 1e308 m": ({"pour": {"release_height": 1e308}},
                            ["pour.release_height = 1e+308", "allowed: at most"]),
    "a step above the limit": ({"model": {"dt": 0.01}}, ["model.dt = 0.01", "stability limit"]),
    "a rate of 1e-308": ({"pour": {"rate": 1e-308}}, ["pour.rate = 1e-308", "at most 1e+10 steps"]),
    "a density of 1e308": ({"model": {"density": 1e308}}, ["model.density = 1e+308", "allowed:"]),
}


@pytest.mark.parametrize("case", sorted(POURS_REFUSE))
def test_what_the_pour_refuses_the_preflight_refuses_first(case, tmp_path):
    change, words = POURS_REFUSE[case]
    with pytest.raises(ValueError) as before:
        check_piles(_cfg(change), ["wedge", "layered"], 1)
    for w in words:
        assert w in str(before.value), str(before.value)
    with pytest.raises(ValueError) as at_start:
        pour(_cfg(change), "wedge", 1, tmp_path / "poured.nc")
    assert str(at_start.value).split(";")[0].split(": ", 1)[-1] in str(before.value)
    assert not (tmp_path / "poured.nc").exists()


def test_a_relaxation_longer_than_the_step_rule_allows_is_refused():
    with pytest.raises(ValueError, match=r"relaxation of a pile of seed 1: relax.max_time = "
                                         r"1000000.0 s make up to 1e\+06 s .* at most 1e\+10 steps"):
        check_piles(_cfg({"relax": {"max_time": 1e6}}), ["wedge"], 1)


@pytest.mark.parametrize("change", [{}, {"physics": {"rough_base": True}},
                                    {"particles": {"aspect_ratio": 2.0}}])
def test_the_study_settings_and_its_levers_pass(change):
    check_piles(_cfg(change), ["wedge", "layered"], 1)


@pytest.mark.parametrize("case", ["too flat a recipe", "a fall from 100 m", "a step above the limit"])
def test_the_workflow_refuses_them_before_its_first_job(case, tmp_path):
    """Over the smoke piles each of these passed ``snakemake -n`` and failed in the
    pour or after it; now the dry run stops on the preflight's line, and no
    results folder is made."""
    change, words = POURS_REFUSE[case]
    overlay = tmp_path / "overlay.yaml"
    results = f"results/test_preflight_{tmp_path.name}"
    overlay.write_text(json.dumps({**change, "results": results}))
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--cores", "1", "--configfile",
                           str(REPO / "config" / "smoke.yaml"), str(overlay)], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    line = next((ln for ln in out.splitlines() if words[0] in ln), None)
    assert line is not None, out[-3000:]
    assert all(w in line for w in words), line
    assert "Traceback" not in out and "Job stats" not in out
    assert not (REPO / results).exists()
