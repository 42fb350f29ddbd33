# Shared names for all rule files: the configuration validated (defaults
# filled in), then the names the rules call, bound to the plain Python modules
# of workflow/ that hold the functions (tested without Snakemake in tests/):
#   workflow/piles.py           the piles: protocols, seeds, stages, paths, the simulation jobs' settings
#   workflow/commands.py        the command lines (python -m sim with the Numba environment)
#   workflow/resources.py       runtime and memory of the simulation jobs
#   workflow/scene.py           the outputs the configuration asks for (config `outputs`)
#   workflow/analysis_inputs.py the analysis' inputs, settings and targets (config `committed`)
#   workflow/numerics_piles.py  the small piles and the ensemble of the pile numerics
#   workflow/reporting.py       what the report says (used by the Snakefile)
# No rules and no functions in this file (snakemake --lint wants them apart).

import json
import os
import sys
from pathlib import Path

from snakemake.logging import logger
from snakemake.settings.types import DeploymentMethod

from workflow.analysis_inputs import ANALYSIS_FIGURES, ANALYSIS_MEM_MB, AnalysisInputs, labelled
from workflow.commands import Commands
from sim.digest import code_digest
from workflow.numerics_piles import NumericsPiles
from workflow.piles import PILE_STAGE_PATTERN, STAGE_PATTERN, Piles, Unrecorded, probe_input_stage
from workflow.resources import SimResources, per_attempt
from workflow.scene import Scene
from workflow.validation import check_config_files, check_problems, validate_config

# The --configfile files read again strictly: a repeated key, which YAML
# reads as its last value, and an empty section laid over another file, which
# the merge ignores, are refused naming the file and line. Then the one
# validator (schemas, finite numbers, integers, the simulator's and the
# analysis' own checks); it fills in every default of the schemas, so the
# rules see a complete config. A refusal is the user's: its line, not a traceback.
try:
    check_config_files(workflow.overwrite_configfiles)
    validate_config(config)
except ValueError as exc:
    sys.exit(str(exc))

REPO = Path(workflow.basedir).resolve()

# --- the piles (workflow/piles.py) -----------------------------------------
piles = Piles(config)
check_problems(piles.problems())
check_problems(piles.preflight())
PROTOCOLS, seeds, results_path, RESULTS = piles.protocols, piles.seeds, piles.results_path, piles.results
pile, pour_log, pour_checkpoint = piles.pile, piles.pour_log, piles.pour_checkpoint
stage_log, stage_benchmark = piles.stage_log, piles.stage_benchmark
pile_frames, pile_film, pile_vtk, pile_figure = piles.pile_frames, piles.pile_film, piles.pile_vtk, piles.pile_figure
probe_stages, extra_probe_stages, probe_change = piles.probe_stages, piles.extra_probe_stages, piles.probe_change
sim_params, probe_sim_params, sim_bookkeeping = piles.sim_params, piles.probe_sim_params, piles.sim_bookkeeping
pile_targets, pile_benchmarks = piles.pile_targets, piles.pile_benchmarks
COMPILED_FLAG, RUN_TIMES_TABLE = piles.compiled_flag, piles.run_times_table

# Code as a param: Snakemake does not look inside the packages a command
# imports, but it re-runs a job whose recorded params changed. Each rule that
# runs the simulator carries SIM_DIGEST (sim/*.py) as param `code`, each that
# runs the analysis ANALYSIS_DIGEST (analysis/*.py), so an edit of sim/
# re-runs the simulations and an edit of analysis/ only the analysis, and the
# log lists a job's files, not the package's 33 sources. A file only touched
# (same content) re-runs nothing. The analysis' numerics (analysis/numerics/:
# run times, precision and cost of piles) add their own digest to the rules that
# run them, so an edit there re-runs those and nothing else.
SIM_DIGEST = code_digest(REPO / "sim")
ANALYSIS_DIGEST = code_digest(REPO / "analysis")
ANALYSIS_NUMERICS_DIGEST = f"{ANALYSIS_DIGEST}-{code_digest(REPO / 'analysis' / 'numerics')}"

# --- command lines (workflow/commands.py) ----------------------------------
# Python that runs the jobs: the interpreter running Snakemake, so jobs see the
# same packages without activating anything; under
# --software-deployment-method conda the rule's conda environment provides
# `python`. A project-local Numba cache is filled once by rule compile_kernels
# before the jobs fan out.
commands = Commands(
    "python" if DeploymentMethod.CONDA in workflow.deployment_settings.deployment_method else sys.executable,
    REPO / ".numba_cache")
sim_shell, py_shell = commands.sim_shell, commands.py_shell

# --- resources of the simulation jobs (workflow/resources.py) --------------
# Refuses, before any job, a pile whose job cannot fit in memory (--resources
# mem_mb, else this machine's or a cluster node's); warns about a pour
# estimated to take longer than a week.
sim_resources = SimResources(config)
SIM_THREADS, sim_mem_mb = sim_resources.threads, sim_resources.sim_mem_mb
pour_runtime_min, relax_runtime_min = sim_resources.pour_runtime_min, sim_resources.relax_runtime_min
probe_runtime_min = sim_resources.probe_runtime_min
sim_resources.check_size(workflow.global_resources.get("mem_mb"), workflow.local_exec, logger.warning)

# --- the scene (workflow/scene.py) -----------------------------------------
scene = Scene(piles)
check_problems(scene.problems(REPO), "scene")
wants, field_quantities = scene.wants, scene.field_quantities

# --- the analysis (workflow/analysis_inputs.py) ----------------------------
analysis_inputs = AnalysisInputs(scene, REPO)
ANALYSIS_PARAMS, PILE_RESULTS, COMMITTED = analysis_inputs.params, analysis_inputs.pile_results, analysis_inputs.committed
pile_result, analysis_seeds = analysis_inputs.pile_result, analysis_inputs.analysis_seeds
general_fit_protocols = analysis_inputs.general_fit_protocols
reported_general_protocols, reported_probes = analysis_inputs.reported_general_protocols, analysis_inputs.reported_probes
analysis_targets = analysis_inputs.targets

# --- the pile numerics (workflow/numerics_piles.py) ------------------------
pile_numerics = NumericsPiles(piles)
check_problems(pile_numerics.problems())
NUMERICS_PILES, NUMERICS_ENSEMBLE, NUMERICS_DIR = pile_numerics.settings, pile_numerics.ensemble, pile_numerics.folder


wildcard_constraints:
    protocol="wedge|layered",
    seed=r"\d+",
