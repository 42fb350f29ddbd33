"""The outputs a scene asks for (workflow/outputs.py) and which per-pile results the
analysis reads (workflow/analysis_inputs.py): the files of the targets of a
scene, the seeds of committed results, the protocols of the general fit, and
the problems of a scene named with setting, value and what to change."""

from pathlib import Path
from types import SimpleNamespace

import pytest
from workflow_config import configuration

from workflow.analysis_inputs import AnalysisInputs, labelled
from workflow.piles import Piles
from workflow.outputs import Outputs
from workflow.validation import merge_configs

NUMERICS = ["results/smoke/numerics/collisions.nc"]


def study(*layers, base="config/smoke.yaml", repo=Path("/nowhere"), config=None):
    """(piles, outputs, analysis inputs) of a configuration."""
    config = configuration(*layers, base=base) if config is None else config
    piles = Piles(config)
    outputs = Outputs(piles)
    return piles, outputs, AnalysisInputs(outputs, repo)


def targets(*layers, **kwargs):
    piles, outputs, analysis = study(*layers, **kwargs)
    return outputs.targets(analysis.targets(), NUMERICS)


# --- targets -------------------------------------------------------------------

def test_the_smoke_study_asks_for_every_stage_picture_film_and_figure():
    files = targets()
    for protocol in ("wedge", "layered"):
        for seed in (1, 2):
            for stage in ("poured", "relaxed", "reduced"):
                assert f"results/smoke/piles/{protocol}/seed{seed}/{stage}.nc" in files
            assert f"results/smoke/figures/piles/{protocol}_seed{seed}_relaxed.png" in files
            assert f"results/smoke/films/{protocol}_seed{seed}.mp4" in files
            assert f"results/smoke/vtk/{protocol}_seed{seed}_relaxed.vtu" in files
        for name in ("fields.nc", "base_pressure.nc", "moduli.nc", "invariants.nc"):
            assert f"results/smoke/ensemble/{protocol}/{name}" in files
    for stem in ("fig1_convergence", "fig2_vertical_strain", "fig3_fabric", "fig4_moduli", "fig5_invariants",
                 "base_pressure"):
        assert f"results/smoke/figures/{stem}.png" in files and f"results/smoke/figures/{stem}.pdf" in files
    assert "results/smoke/run_times.html" in files
    assert not set(NUMERICS) & set(files)          # no numerics asked for
    assert not [f for f in files if "general" in f]  # no extra probes, no general fit


def test_the_stress_only_scene_asks_for_states_and_the_stress_ensembles_only():
    files = targets("config/scenes/stress_only.yaml")
    assert not [f for f in files if "reduced" in f or "/figures/" in f or "moduli" in f]
    assert sorted(f for f in files if "/ensemble/" in f) == sorted(
        f"results/smoke/ensemble/{p}/{n}" for p in ("wedge", "layered") for n in ("fields.nc", "base_pressure.nc"))
    assert len([f for f in files if "/piles/" in f]) == 4 * 2   # poured and relaxed of 4 piles


def test_the_elastic_probes_scene_adds_tilts_restore_and_the_general_fit():
    files = targets("config/scenes/elastic_probes.yaml")
    for stage in ("tiltp05", "tiltm05", "restored"):
        assert f"results/smoke/piles/wedge/seed1/{stage}.nc" in files
    assert "results/smoke/ensemble/layered/general_moduli.nc" in files
    assert "results/smoke/figures/general_fit.png" in files


def test_numerics_are_asked_for_only_with_output_numerics():
    assert targets({"outputs": ["numerics"]}) == NUMERICS
    assert set(NUMERICS) < set(targets({"outputs": ["states", "numerics"]}))


def test_the_fields_quantities_follow_the_outputs_in_the_analysis_order():
    assert study({"outputs": ["strain", "fields", "fabric"]})[1].field_quantities() == ["fabric", "strain"]
    assert study({"outputs": ["fields"]})[1].field_quantities() == []


# --- problems of a scene ----------------------------------------------------------

@pytest.mark.parametrize("override, words", [
    ({"outputs": ["states", "fits"]}, ["outputs ['states', 'fits']: fits needs strain",
                                       "add 'strain' or leave 'fits' out"]),
    ({"outputs": ["fields", "strain"], "probe": {"levels": []}},
     ["strain is the response to a gravity probe but probe.levels is []", "give a level"]),
    ({"physics": {"support": False}, "outputs": ["states"]},
     ["physics.support = false with outputs ['states']", "only allowed output is [numerics]"]),
    ({"analysis": {"convergence": {"seed": 7}}},
     ["analysis.convergence.seed = 7 is not a seed of protocol wedge (seeds [1, 2])", "or null"]),
    ({"analysis": {"rve": {"min_particles": 200}}},
     ["pour.n_particles = 150 is fewer than analysis.rve.min_particles = 200", "pour at least 200"]),
    ({"analysis": {"base_pressure": {"stage": "reduced20"}}},
     ["analysis.base_pressure.stage = 'reduced20' is not a stage", "['reduced']"]),
])
def test_a_scene_its_physics_cannot_give_is_refused_naming_the_settings(override, words):
    """The settings laid over the smoke study unvalidated: the simulator's own
    checks refuse some of them too, before these."""
    config = merge_configs(configuration(), override)
    problems = Outputs(Piles(config)).problems(Path("/"))
    assert problems and all(any(w in p for p in problems) for w in words), problems


def test_committed_results_must_be_there_and_replace_the_simulation(tmp_path):
    config = configuration({"committed": "records", "outputs": ["states", "fields"]})
    problems = Outputs(Piles(config)).problems(tmp_path)
    assert problems == [
        f"committed = 'records': no such folder under {tmp_path}",
        "committed = 'records' with outputs ['states', 'fields']: committed results replace the simulation, "
        "so states, vtk, film and numerics cannot be asked for; leave them out of outputs"]
    (tmp_path / "records").mkdir()
    config = configuration({"committed": "records", "outputs": ["fields"]})
    assert Outputs(Piles(config)).problems(tmp_path) == []


# --- the analysis' inputs -----------------------------------------------------------

def write(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("")


def test_committed_results_enter_the_ensembles_pile_by_pile_as_recorded(tmp_path):
    write(tmp_path / "records" / "wedge" / "seed2.fields.nc")
    write(tmp_path / "records" / "layered" / "seed1.fields.nc")
    write(tmp_path / "records" / "layered" / "seed2.fields.nc")
    piles, outputs, analysis = study({"committed": "records", "outputs": ["fields"]}, repo=tmp_path)
    assert analysis.pile_result("wedge", 2, "fields") == str(tmp_path / "records" / "wedge" / "seed2.fields.nc")
    assert analysis.analysis_seeds("wedge") == [2]
    assert analysis.analysis_seeds("layered") == [1, 2]
    assert analysis.fields(SimpleNamespace(protocol="wedge")) == [str(tmp_path / "records/wedge/seed2.fields.nc")]
    with pytest.raises(ValueError, match=r"committed = 'records': no pile of protocol wedge \(seeds \[1, 2\]\) "
                                         r"has its checks file there \(\{protocol\}/seed\{seed\}.checks.json\)"):
        analysis.analysis_seeds("wedge", "checks")


def test_computed_results_of_every_pile_enter_the_ensembles():
    piles, outputs, analysis = study()
    assert analysis.pile_result("layered", 1, "fields") == "results/smoke/fields/layered/seed1.nc"
    assert analysis.pile_result("layered", 1, "checks") == "results/smoke/fields/layered/seed1.checks.json"
    assert analysis.analysis_seeds("layered", "convergence") == [1, 2]
    assert "probes" not in analysis.pile_results


def test_the_general_fit_takes_the_protocols_with_recorded_probes(tmp_path):
    assert study()[2].general_fit_protocols() == []       # no extra probes
    assert study("config/scenes/elastic_probes.yaml")[2].general_fit_protocols() == ["wedge", "layered"]
    write(tmp_path / "records" / "layered" / "seed2.probes.nc")
    write(tmp_path / "records" / "layered" / "seed2.fields.nc")
    piles, outputs, analysis = study("config/scenes/elastic_probes.yaml",
                                   {"committed": "records", "outputs": ["fields", "strain", "fits"]}, repo=tmp_path)
    assert analysis.general_fit_protocols() == ["layered"]
    assert analysis.reported_probes() == [("layered", str(tmp_path / "records/layered/seed2.probes.nc"))]
    without_fits = study("config/scenes/elastic_probes.yaml", {"outputs": ["fields", "strain"]})[2]
    assert without_fits.reported_general_protocols() == []


def test_a_figure_of_a_protocol_outside_the_study_draws_the_first_protocol():
    config = configuration({"analysis": {"figures": {"fabric_protocol": "wedge"}}})
    del config["protocols"]["wedge"]
    analysis = study(config=config)[2]
    assert analysis.figure_protocol("fabric_protocol") == "layered"
    assert analysis.convergence_seeds("layered") == [1, 2]
    one = study({"analysis": {"convergence": {"seed": 2}}})[2]
    assert one.convergence_files() == ["results/smoke/fields/wedge/seed2.convergence.nc"]


def test_a_pile_without_a_gravity_probe_gets_no_reduced_state():
    pile = SimpleNamespace(protocol="wedge", seed="1")
    assert study()[2].fields_reduced(pile) == "results/smoke/piles/wedge/seed1/reduced.nc"
    assert study("config/scenes/stress_only.yaml")[2].fields_reduced(pile) == []
    assert AnalysisInputs.reduced_option(pile, SimpleNamespace(reduced="r.nc")) == ["--reduced", "r.nc"]
    assert AnalysisInputs.reduced_option(pile, SimpleNamespace(reduced=[])) == []
    assert labelled(["a.nc", "b.nc"], ["wedge", "layered"]) == ["wedge=a.nc", "layered=b.nc"]
