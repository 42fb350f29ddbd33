"""The pile numerics' files and settings (workflow/numerics_piles.py), and what
the report says about its configuration (workflow/reporting.py): the files it
names, where it may be written, how many piles are there and whether its
results are up to date."""

import json
from pathlib import Path
from types import SimpleNamespace

import pytest
from workflow_config import configuration

from workflow.numerics_piles import NumericsPiles, factor_label
from workflow.piles import Piles
from workflow.reporting import (Freshness, check_report_path, configuration_files, piles_made, report_path,
                                shown_path)
from workflow.validation import merge_configs

CI = "config/numerics_piles_ci.yaml"


def numerics(*layers, base=CI):
    config = configuration(*layers, base=base)
    return NumericsPiles(Piles(config))


# --- the pile numerics ------------------------------------------------------------

def test_a_dt_factor_is_labelled_by_its_shortest_decimal():
    assert [factor_label(f) for f in (1.0, 0.5, 0.125, 0.1)] == ["1", "0.5", "0.125", "0.1"]


def test_every_small_pile_has_its_state_benchmark_and_cpu_time_in_the_numerics_folder():
    study = numerics()
    assert study.runs() == [(i, f, s) for i in ("gear", "verlet") for f in ("1", "0.5") for s in (1, 2)]
    assert study.pile("gear", "0.5", 2, "relaxed") == \
        "results/numerics_piles_ci/numerics/piles/gear/dt_factor0.5/seed2/relaxed.nc"
    assert study.pile_inputs("pour_cpu")[0] == \
        "results/numerics_piles_ci/benchmarks/numerics/piles/gear/dt_factor1/seed1_pour.times"
    assert study.pile_inputs("relax")[-1] == \
        "results/numerics_piles_ci/benchmarks/numerics/piles/verlet/dt_factor0.5/seed2_relax.tsv"
    assert study.pile_inputs("summaries")[0].endswith("gear/dt_factor1/seed1/relaxed.summary.json")
    assert len(study.pile_inputs("states")) == 8
    assert all(t.startswith("results/numerics_piles_ci/numerics/") for t in study.targets())


def test_a_small_pile_scales_the_time_step_of_its_integrator_by_its_factor():
    run = SimpleNamespace(integrator="gear", factor="0.5")
    automatic = json.loads(numerics().job_params(run, "relax"))
    assert automatic["model"]["integrator"] == "gear"
    assert automatic["model"]["dt_safety"] == 0.25          # the default 0.5, halved
    assert automatic["pour"]["n_particles"] == 12           # numerics.piles.n_particles, not pour's 30
    assert "relax" in automatic and "particles" not in automatic
    given = json.loads(numerics({"model": {"dt": 2e-6}}).job_params(run, "pour"))
    assert given["model"]["dt"] == 1e-6 and given["model"]["dt_safety"] == 0.5
    assert "particles" in given


def test_the_ensemble_study_reads_each_protocols_piles_and_benchmarks():
    study = numerics(base="config/smoke.yaml")
    files = {kind: study.ensemble_inputs(kind) for kind in ("fields", "base_pressure", "pour", "relax", "probe")}
    assert files["fields"][0] == "results/smoke/fields/wedge/seed1.nc" and len(files["fields"]) == 4
    assert files["base_pressure"] == ["results/smoke/ensemble/wedge/base_pressure.nc",
                                      "results/smoke/ensemble/layered/base_pressure.nc"]
    assert files["probe"][-1] == "results/smoke/benchmarks/probe/layered/seed2_reduced.tsv"
    args = study.ensemble_args()
    # every input file is handed to the script once, under its protocol
    assert sorted(a for a in args if a.startswith("results/")) == sorted(sum(files.values(), []))
    layered = args[args.index("layered") - 1:]
    assert layered[:4] == ["--protocol", "layered", "--seeds", "1"]
    assert "results/smoke/fields/wedge/seed1.nc" not in layered
    assert layered[layered.index("--pour-benchmarks") + 1] == "results/smoke/benchmarks/pour/layered/seed1.tsv"


@pytest.mark.parametrize("override, message", [
    ({"reference_integrator": "verlet", "integrators": ["gear"]},
     "numerics.piles.reference_integrator = 'verlet' is not in numerics.piles.integrators = ['gear']"),
    ({"dt_factors": [0.1, 0.10000001]},
     "numerics.piles.dt_factors = [0.1, 0.10000001] repeat a factor at 6 significant digits"),
])
def test_pile_numerics_the_schema_allows_but_no_run_can_do_are_refused(override, message):
    config = merge_configs(configuration(base=CI), {"numerics": {"piles": override}})
    assert NumericsPiles(Piles(config)).problems() == [message]
    assert numerics().problems() == []


# --- the report ------------------------------------------------------------------------

def test_the_report_names_the_configuration_files_from_the_repository(tmp_path):
    repo = Path(__file__).resolve().parents[1]
    assert shown_path(repo / "config" / "smoke.yaml", repo) == "config/smoke.yaml"
    assert shown_path(tmp_path / "mine.yaml", repo) in (str(tmp_path / "mine.yaml"), "mine.yaml")
    assert configuration_files([], {}, repo) == ["config/config.yaml"]
    assert configuration_files([repo / "config/smoke.yaml"], {"threads": 2, "results": "r"}, repo) == [
        "config/smoke.yaml", "--config threads=2 results=r"]


def test_the_report_path_is_read_from_the_command_line():
    assert report_path(["snakemake", "--report", "results/smoke/report.html"]) == "results/smoke/report.html"
    assert report_path(["snakemake", "--report=out.zip", "-n"]) == "out.zip"
    assert report_path(["snakemake", "--report-stylesheet", "s.css", "all"]) is None
    assert report_path(["snakemake", "--report"]) is None


def test_a_report_among_another_configurations_results_is_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    files = ["config/smoke.yaml"]
    with pytest.raises(ValueError, match=r"--report results/report.html: this configuration \(config/smoke.yaml\) "
                                         r"writes its results to results/smoke/ .* --report results/smoke/report.html"):
        check_report_path("results/report.html", "results/smoke", files)
    check_report_path("results/smoke/report.html", "results/smoke", files)
    check_report_path("elsewhere/report.html", "results/smoke", files)
    check_report_path(None, "results/smoke", files)


def test_the_report_counts_the_piles_that_have_their_last_stage(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config = configuration()
    piles = Piles(config)
    assert piles_made(piles, None) == "0 of 4 piles of 150 particles made so far"
    for stage in ("relaxed", "reduced"):
        path = tmp_path / piles.paths.pile("layered", 2, stage)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
    assert piles_made(piles, None) == "1 of 4 piles of 150 particles made so far"
    committed = configuration({"committed": "docs/reproduction", "outputs": ["fields"]})
    assert piles_made(Piles(committed), lambda protocol: [1] if protocol == "wedge" else []) == (
        "from the per-pile results committed under docs/reproduction/ (1 of the 4 piles recorded)")


class Dag:
    """Snakemake's DAG as Freshness reads it: the jobs it would run, and why."""

    def __init__(self, jobs):
        self.jobs = jobs

    def needrun_jobs(self):
        return [job for job, _ in self.jobs]

    def reason(self, job):
        return next(why for each, why in self.jobs if each is job)


def job(rule, *output):
    return SimpleNamespace(rule=SimpleNamespace(name=rule), output=list(output))


def reason(**why):
    return SimpleNamespace(**{attribute: why.get(attribute, False) for attribute, _ in Freshness.REASONS})


def test_results_whose_jobs_would_run_again_are_reported_out_of_date(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.nc").write_text("")
    warned, said = [], []
    fresh = Freshness(lambda: Dag([(job("draw_pile", "missing.png"), reason(missing_output=True))]),
                      warned.append, said.append, lambda: True)
    assert str(fresh).startswith("Up to date") and warned == [] and said == [f"Report: {fresh}"]
    dag = Dag([(job("analysis_fields", "a.nc"), reason(params_changed=True)),
               (job("analysis_fields", "b.nc"), reason(input_changed=True)),
               (job("all"), reason(input_changed=True))])
    text = str(Freshness(lambda: dag, warned.append, said.append, lambda: True))
    assert text.startswith("OUT OF DATE: 1 files of these results do not show what the workflow makes now "
                           "(code or settings changed; inputs changed since they were made): "
                           "Snakemake would run 2 jobs again (2 analysis_fields), for example for a.nc.")
    assert warned == [f"Report: {text}"]


def test_a_study_with_no_result_is_not_called_up_to_date():
    """A report of a configuration that has made nothing yet (make report on a
    fresh clone) says so, on the terminal too, instead of "Up to date"."""
    said = []
    text = str(Freshness(lambda: Dag([]), [].append, said.append, lambda: False))
    assert text.startswith("Nothing made yet: none of this configuration's results exists")
    assert "Up to date" not in text and said == [f"Report: {text}"]
