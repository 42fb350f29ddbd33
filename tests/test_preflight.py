"""The settings a pour or its relaxation would refuse when it starts are refused
by :func:`sim.preflight.check_piles` from the settings alone (issue 47, item 2:
before any job of the workflow).

Each case is one the pour itself refuses (:func:`sim.pour.pour`, asserted here
on the same settings) or a stage's rule (the relaxation's number of steps),
so the preflight agrees with the runs it stands in for; the study's settings
pass.
"""

import json

import pytest

from sim.config import SimConfig
from sim.pour import pour
from sim.preflight import check_piles

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
