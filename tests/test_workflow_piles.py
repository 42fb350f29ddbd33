"""The piles of a configuration (workflow/piles.py): stage names of the
probes (stages.py), the files of a pile (pile_paths.py), the settings each simulation job receives
(jobs.py), and the configuration's problems named with setting, value and what is allowed;
with the command lines (workflow/commands.py) and the resources of the jobs
(workflow/resources.py)."""

import json
import math
import subprocess
import sys
from types import SimpleNamespace

import pytest
from workflow_config import REPO, configuration, simulator

from sim.cli import _params as cli_params
from sim.config import STAGE_SECTIONS
from workflow.commands import Commands
from workflow.jobs import JobSettings, Unrecorded
from workflow.piles import Piles
from workflow.resources import ABSURD_RUNTIME_MIN, SimResources, per_attempt
from workflow.stages import probe_input_stage, stage_rule
from workflow.validation import check_problems, merge_configs


def piles_of(**probe):
    return Piles(configuration({"probe": probe}))


# --- stages ----------------------------------------------------------------

def test_the_first_level_is_reduced_and_the_others_are_named_by_their_percent():
    piles = piles_of(levels=[0.1, 0.2, 0.05])
    assert piles.stages.probe_stages() == ["reduced", "reduced20", "reduced05"]
    assert [piles.stages.level_for_stage(s) for s in piles.stages.probe_stages()] == [0.1, 0.2, 0.05]
    assert piles.stages.probe_change("reduced20") == ["--level", "0.2"]


def test_a_stage_that_is_no_configured_level_is_refused_naming_the_levels():
    with pytest.raises(ValueError, match=r"'reduced30'.*probe.levels \[0.1, 0.2\] give \['reduced', 'reduced20'\]"):
        piles_of(levels=[0.1, 0.2]).stages.level_for_stage("reduced30")


def test_tilts_stretch_and_restore_are_stages_after_the_reductions_with_their_options():
    piles = piles_of(levels=[0.1], tilts=[0.05], stretch=1e-4, restore=True)
    assert piles.stages.extra_probe_stages() == ["tiltp05", "tiltm05", "stretched", "restored"]
    assert piles.stages.probe_change("tiltm05") == ["--tilt", "-0.05"]
    assert piles.stages.probe_change("stretched") == ["--stretch", "0.0001"]
    assert piles.stages.probe_change("restored") == ["--restore"]
    assert probe_input_stage("restored") == "reduced"
    assert probe_input_stage("tiltp05") == "relaxed"


def test_without_extra_probes_a_pile_has_poured_relaxed_and_its_reductions():
    piles = piles_of(levels=[0.1], tilts=[], stretch=0.0, restore=False)
    assert piles.stages.all_stages() == ["poured", "relaxed", "reduced"]


def test_a_pile_is_finished_with_every_probe_or_else_relaxed():
    assert piles_of(levels=[0.1], tilts=[0.05], stretch=0.0, restore=True).stages.final_stages() == [
        "reduced", "tiltp05", "tiltm05", "restored"]
    assert piles_of(levels=[], tilts=[], stretch=0.0, restore=False).stages.final_stages() == ["relaxed"]


# --- files -----------------------------------------------------------------

def test_every_file_of_a_pile_lies_in_the_configurations_results_folder():
    piles = Piles(configuration())        # config/smoke.yaml: results/smoke
    assert piles.paths.pile("wedge", 3, "relaxed") == "results/smoke/piles/wedge/seed3/relaxed.nc"
    assert piles.paths.pile_figure("layered", 1, "poured") == "results/smoke/figures/piles/layered_seed1_poured.png"
    assert piles.paths.pile_film("wedge", 2, "html") == "results/smoke/films/wedge_seed2.html"
    assert piles.paths.compiled_flag == "results/smoke/.numba/compiled.ok"
    for path in (piles.paths.pour_log("wedge", 1), piles.paths.pour_checkpoint("wedge", 1), piles.paths.pile_frames("wedge", 1),
                 piles.paths.pile_vtk("wedge", 1, "relaxed"), piles.paths.run_times_table, *piles.benchmarks()):
        assert path.startswith("results/smoke/")


def test_the_log_and_benchmark_of_a_stages_job_are_named_by_its_rule():
    piles = Piles(configuration())        # config/smoke.yaml: results/smoke
    assert [stage_rule(s) for s in ("poured", "relaxed", "reduced", "tiltm05", "{stage}")] == [
        "pour", "relax", "probe", "probe", "probe"]
    assert piles.paths.stage_log("wedge", 3, "poured") == piles.paths.pour_log("wedge", 3) == "results/smoke/logs/pour/wedge/seed3.log"
    assert piles.paths.stage_log("wedge", 3, "relaxed") == "results/smoke/logs/relax/wedge/seed3.log"
    assert piles.paths.stage_benchmark("wedge", 3, "poured") == "results/smoke/benchmarks/pour/wedge/seed3.tsv"
    assert piles.paths.stage_benchmark("layered", 1, "tiltm05") == "results/smoke/benchmarks/probe/layered/seed1_tiltm05.tsv"
    # with the wildcards: the patterns of rule probe's log: and benchmark:
    assert piles.paths.stage_log("{protocol}", "{seed}", "{stage}") == "results/smoke/logs/probe/{protocol}/seed{seed}_{stage}.log"
    assert piles.paths.stage_benchmark("{protocol}", "{seed}", "{stage}") == (
        "results/smoke/benchmarks/probe/{protocol}/seed{seed}_{stage}.tsv")


def test_the_targets_are_every_stage_of_every_pile_wedge_first():
    config = configuration({"protocols": {"layered": {"seeds": [4, 2]}, "wedge": {"seeds": [7]}}})
    piles = Piles(config)
    assert piles.protocols == ["wedge", "layered"]
    assert piles.each() == [("wedge", 7), ("layered", 4), ("layered", 2)]
    stages = piles.stages.all_stages()
    assert piles.targets() == [piles.paths.pile(p, s, st) for p, s in piles.each() for st in stages]
    # one benchmark per simulation job: pour, relax and each probe
    assert len(piles.benchmarks()) == 3 * len(stages)


# --- settings of the simulation jobs -----------------------------------------

def test_a_job_receives_only_its_sections_without_the_bookkeeping():
    pour = json.loads(simulator().job_params("pour"))
    assert sorted(pour) == ["model", "particles", "physics", "pour"]
    assert pour["pour"]["n_particles"] == 150
    assert "checkpoint_interval" not in pour["pour"] and "frame_interval" not in pour["pour"]
    changed = simulator({"relax": {"max_time": 2.0}})
    assert changed.job_params("pour") == simulator().job_params("pour")
    assert changed.job_params("relax") != simulator().job_params("relax")


@pytest.mark.parametrize("stage", sorted(STAGE_SECTIONS))
def test_the_simulator_reads_a_job_s_settings_back_as_the_workflow_validated_them(stage):
    """The text the rules record is what ``python -m sim STAGE`` reads
    (sim.cli): every section the stage reads comes back equal, the
    bookkeeping included, for settings away from their defaults."""
    sim = simulator({"model": {"friction": 0.37, "youngs_modulus": 2e7},
                     "pour": {"checkpoint_interval": 60.0}, "relax": {"max_time": 2.0}})
    read = cli_params(sim.job_params(stage), str(JobSettings(sim).job_bookkeeping()))
    assert read.model.friction == 0.37 and read.model.youngs_modulus == 2e7
    for section in STAGE_SECTIONS[stage]:
        assert getattr(read, section) == getattr(sim, section), section


def test_the_bookkeeping_travels_unrecorded():
    bookkeeping = JobSettings(simulator({"pour": {"checkpoint_interval": 60.0}})).job_bookkeeping()
    assert isinstance(bookkeeping, Unrecorded)
    assert json.loads(str(bookkeeping))["pour"]["checkpoint_interval"] == 60.0


def test_the_stretch_and_the_gravity_probes_each_get_only_their_own_probe_settings():
    jobs = JobSettings(simulator({"probe": {"levels": [0.1], "stretch": 1e-4, "stretch_time": 0.5}}))
    stretch = json.loads(jobs.probe_job_params("stretched"))["probe"]
    gravity = json.loads(jobs.probe_job_params("reduced"))["probe"]
    assert stretch == {"stretch": 1e-4, "stretch_time": 0.5}
    assert "levels" in gravity and "stretch" not in gravity and "stretch_time" not in gravity
    # adding the stretch changes no gravity probe's settings
    assert JobSettings(simulator({"probe": {"levels": [0.1]}})).probe_job_params("reduced") == jobs.probe_job_params("reduced")


# --- problems ----------------------------------------------------------------

@pytest.mark.parametrize("override, words", [
    ({"probe": {"levels": [0.1, 0.2, 0.201]}}, ["probe.levels [0.1, 0.2, 0.201]",
                                                 "['reduced', 'reduced20', 'reduced20']", "percent resolution"]),
    ({"probe": {"tilts": [0.05, 0.051]}}, ["probe.tilts [0.05, 0.051]", "tiltp05", "percent resolution"]),
    ({"probe": {"stretch": 1e-4}, "physics": {"support": False}, "outputs": ["numerics"]},
     ["probe.stretch = 0.0001 with physics.support = false", "set probe.stretch to 0"]),
    ({"probe": {"stretch": 1e-4}, "model": {"support_friction": 0.0}},
     ["probe.stretch = 0.0001 with model.support_friction = 0", "model.support_friction > 0"]),
    ({"probe": {"levels": [], "restore": True}, "outputs": ["states"]},
     ["probe.restore = true with probe.levels = []", "give a level"]),
])
def test_a_configuration_the_stages_cannot_name_is_refused_naming_setting_and_value(override, words):
    """The settings laid over a valid configuration unvalidated: the
    simulator's own checks refuse some of them too, before these."""
    problems = Piles(merge_configs(configuration(), override)).problems()
    assert len(problems) == 1
    assert all(w in problems[0] for w in words), problems[0]
    with pytest.raises(ValueError, match="^invalid configuration:\n  probe"):
        check_problems(problems)


def test_the_configurations_of_the_repository_have_no_problem():
    for layers in ([], ["config/scenes/elastic_probes.yaml"], ["config/scenes/six_constants.yaml"]):
        assert Piles(configuration(*layers, base="config/config.yaml")).problems() == []
    check_problems([])


# --- command lines -------------------------------------------------------------

def test_the_simulator_runs_with_the_numba_settings_and_every_path_quoted():
    commands = Commands("/opt/my python/bin/python", "/work/a cache")
    assert commands.sim_shell("warmup") == (
        "NUMBA_NUM_THREADS={threads} NUMBA_CACHE_DIR='/work/a cache' '/opt/my python/bin/python' -m sim warmup")
    assert commands.sim_shell("summary x.nc", numba=False) == "'/opt/my python/bin/python' -m sim summary x.nc"
    assert commands.py_shell("-m analysis draw") == "'/opt/my python/bin/python' -m analysis draw"


# --- resources -----------------------------------------------------------------

def test_a_job_asks_1000_mb_and_a_tenth_of_a_mb_per_particle_more_on_each_attempt():
    resources = SimResources(configuration({"pour": {"n_particles": 3500}}))
    assert resources.sim_mem_mb(None, 1) == 1350
    assert resources.sim_mem_mb(None, 2) == 2700
    assert per_attempt(15)(None, 3) == 45


def test_the_time_step_is_the_given_one_or_scales_with_the_particles_stiffness():
    assert SimResources(configuration({"model": {"dt": 1e-6}})).estimated_dt() == 1e-6
    soft = SimResources(configuration({"model": {"youngs_modulus": 1e7}})).estimated_dt()
    stiff = SimResources(configuration({"model": {"youngs_modulus": 4e7}})).estimated_dt()
    assert math.isclose(soft / stiff, 2.0)


def test_runtimes_grow_with_the_attempt_and_shrink_with_threads():
    one = SimResources(configuration(base="config/config.yaml"))
    four = SimResources(configuration({"threads": 4}, base="config/config.yaml"))
    assert one.pour_runtime_min(None, 2) == 2 * one.pour_runtime_min(None, 1)
    assert four.pour_runtime_min(None, 1) < one.pour_runtime_min(None, 1)
    assert one.relax_runtime_min(None, 1) < one.pour_runtime_min(None, 1)
    ramp = SimResources(configuration({"probe": {"mode": "ramp", "ramp_time": 5.0}}, base="config/config.yaml"))
    stage = SimResources(configuration({"probe": {"mode": "step"}}, base="config/config.yaml"))
    reduced = SimpleNamespace(stage="reduced")
    assert ramp.probe_runtime_min(reduced, 1) > stage.probe_runtime_min(reduced, 1)


def test_a_pile_too_large_for_the_memory_is_refused_naming_the_limit():
    resources = SimResources(configuration({"pour": {"n_particles": 3500}}))
    with pytest.raises(ValueError, match=r"pour.n_particles = 3500: .* about 1350 MB .* more than "
                                         r"--resources mem_mb \(1000 MB\); pour fewer particles"):
        resources.check_size(1000, True, print)
    with pytest.raises(ValueError, match="the memory of this machine"):
        SimResources(configuration({"pour": {"n_particles": 10**6}})).check_size(None, True, print)   # 100 GB
    resources.check_size(SimpleNamespace(value=2000), True, print)   # a Snakemake resource
    resources.check_size(None, False, print)                         # a cluster node is large


def test_a_pour_estimated_to_take_more_than_a_week_is_warned_about():
    warnings = []
    # 7.6e9 steps at 6.9e-6 s: within the simulator's 1e10, but months of CPU
    slow = SimResources(configuration({"pour": {"n_particles": 3500, "rate": 0.1}}, base="config/config.yaml"))
    assert slow.pour_runtime_min(None, 1) > ABSURD_RUNTIME_MIN
    slow.check_size(None, False, warnings.append)
    assert len(warnings) == 1 and "pour.n_particles = 3500, pour.rate = 0.1" in warnings[0]
    SimResources(configuration(base="config/config.yaml")).check_size(None, False, warnings.append)
    assert len(warnings) == 1


def test_a_pour_beyond_the_simulators_step_count_is_refused_before_any_job():
    """3500 particles at 0.01/s: 1.5 x 3500 / 0.01 + 0.1 = 525 000 s over the study's
    Verlet step of about 6.9e-6 s is 7.6e10 steps, past sim.timestep.MAX_STEPS (1e10),
    which the simulator would refuse when the job starts."""
    slow = SimResources(configuration({"pour": {"n_particles": 3500, "rate": 0.01}}, base="config/config.yaml"))
    with pytest.raises(ValueError, match=r"^pour.n_particles = 3500 at pour.rate = 0.01/s with an automatic step "
                                         r"of about 6.9e-06 s .* needs about 7.609e\+10 steps, more than the "
                                         r"simulator's 1e\+10"):
        slow.check_size(None, False, print)


def test_the_workflows_modules_import_without_snakemake():
    """Every module of workflow/ is plain Python: importable where Snakemake is not."""
    modules = sorted(p.stem for p in (REPO / "workflow").glob("*.py"))
    code = ("import sys; sys.modules['snakemake'] = None; import importlib; "
            f"[importlib.import_module('workflow.' + m) for m in {modules!r}]")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert {"piles", "outputs", "analysis_inputs", "numerics_piles", "resources", "commands", "reporting"} <= set(modules)
