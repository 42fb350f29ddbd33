# Shared names for all rule files. The Snakefile validates `config` (and fills
# its defaults) before this file is included, so every key is present here.
# No rules in this file (snakemake --lint wants functions and rules apart).

import json
import math
import os
import re
import shlex
import sys
from pathlib import Path

from snakemake.logging import logger
from snakemake.settings.types import DeploymentMethod

from sim.config import BOOKKEEPING, result_settings
from workflow.digest import code_digest

REPO = Path(workflow.basedir).resolve()

# Protocols to run, in a fixed order (wedge before layered), subset of the
# two the simulator knows.
PROTOCOLS = [p for p in ("wedge", "layered") if p in config["protocols"]]


def seeds(protocol):
    """Seeds (ints) of the piles of `protocol`, in config order."""
    return [int(s) for s in config["protocols"][protocol]["seeds"]]


# The folder of everything this configuration makes (config `results`,
# relative to the working directory): its piles, fields, ensembles, figures,
# films, report, and the logs and benchmarks of its jobs. Each configuration
# has its own (results/study, results/smoke, results/reproduction), so two of
# them never write the same file.
RESULTS = config["results"]


def results_path(path):
    """`path` (e.g. "piles/{protocol}/seed{seed}/poured.nc") in this
    configuration's results folder: "results/study/piles/..."."""
    return f"{RESULTS}/{path}"


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

# Python that runs the jobs: the interpreter running Snakemake (the project's
# venv under `make run`), so jobs see the same packages without activating
# anything. Under --software-deployment-method conda the rule's conda
# environment provides `python` instead.
_USE_CONDA = DeploymentMethod.CONDA in workflow.deployment_settings.deployment_method
PY = "python" if _USE_CONDA else sys.executable

# Environment prefix of every simulation command. Snakemake sets
# OMP_NUM_THREADS from `threads:` but not NUMBA_NUM_THREADS; a project-local
# Numba cache is filled once by rule compile_kernels before the jobs fan out.
NUMBA_CACHE = REPO / ".numba_cache"
NUMBA_ENV = f"NUMBA_NUM_THREADS={{threads}} NUMBA_CACHE_DIR={shlex.quote(str(NUMBA_CACHE))}"

# The simulator's command lines: SIM_CMD with the Numba settings (it keeps
# `{threads}` for Snakemake to fill in), PY_SIM without them for commands that
# run no kernels (summary).
PY_SIM = f"{shlex.quote(PY)} -m sim"
SIM_CMD = f"{NUMBA_ENV} {PY_SIM}"


def sim_shell(command, numba=True):
    """Shell command of a rule: `python -m sim <command>`, with the Numba
    environment unless numba=False."""
    return f"{SIM_CMD if numba else PY_SIM} {command}"


def py_shell(command):
    """Shell command `python <command>` run by PY, e.g.
    `shell: py_shell("-m analysis fields ... > {log:q} 2>&1")`. Writing `{PY}`
    in a shell string directly works too, but snakemake --lint flags it."""
    return f"{shlex.quote(PY)} {command}"


# Flag file written by rule compile_kernels; every simulation rule takes it as
# input so that no two jobs compile (and write the Numba cache) at once.
COMPILED_FLAG = results_path(".numba/compiled.ok")

SIM_THREADS = int(config["threads"])

# Stage names: the probes (gravity reductions, tilts, the restoring probe,
# the support stretch), and every stage of a pile.
STAGE_PATTERN = r"reduced|reduced\d\d|tilt[pm]\d\d|restored|stretched"
# The support-stretch probe (config probe.stretch) and its own settings: only
# its job reads them, and only it gets them (probe_sim_params).
STRETCH_STAGE = "stretched"
STRETCH_KEYS = ("stretch", "stretch_time")
PILE_STAGE_PATTERN = rf"poured|relaxed|{STAGE_PATTERN}"


def pile(protocol, seed, stage):
    """Path of a particle-state file (docs/formats.md#state-files)."""
    return results_path(f"piles/{protocol}/seed{seed}/{stage}.nc")


def pour_log(protocol, seed):
    """The pile's pour log: the lines of every run of its pour that held the
    pour's lock, each run from a line "pour P seed S: started by process HOST
    PID" (the simulator's --log; study_progress.py reads its progress lines)."""
    return results_path(f"logs/pour/{protocol}/seed{seed}.log")


def pour_checkpoint(protocol, seed):
    """Checkpoint of a running pour. Deliberately not a Snakemake output: it
    must survive a killed job so that the re-run resumes from it; the
    simulator deletes it when the pour has finished."""
    return results_path(f"piles/{protocol}/seed{seed}/pour.checkpoint.nc")


def stage_for_level(level):
    """Stage name of the gravity probe with reduction `level` (Delta).

    The first level in config probe.levels is the stage `reduced` of
    docs/formats.md#stages; any other is reducedNN with NN = round(100 * level).
    """
    levels = [float(x) for x in config["probe"]["levels"]]
    if float(level) == levels[0]:
        return "reduced"
    return f"reduced{round(100 * float(level)):02d}"


def probe_stages():
    """Stage names of all configured gravity probes, in config order."""
    return [stage_for_level(level) for level in config["probe"]["levels"]]


def tilt_stage(tilt):
    """Stage name of the tilted-gravity probe with horizontal component
    `tilt` g0: tiltpNN for tilt > 0, tiltmNN for tilt < 0, NN = round(100 |tilt|)."""
    return f"tilt{'p' if tilt > 0 else 'm'}{round(100 * abs(float(tilt))):02d}"


def signed_tilts():
    """Every tilted probe's tilt (config probe.tilts, each with + and - sign)."""
    return [sign * float(t) for t in config["probe"]["tilts"] for sign in (1.0, -1.0)]


def tilt_stages():
    """Stage names of the tilted-gravity probes (config probe.tilts)."""
    return [tilt_stage(t) for t in signed_tilts()]


def stretch_stages():
    """The support-stretch probe's stage, if config probe.stretch is not 0."""
    return [STRETCH_STAGE] if float(config["probe"]["stretch"]) != 0.0 else []


def extra_probe_stages():
    """The probes beyond the gravity reductions: the tilts, the support
    stretch (probe.stretch) and, with probe.restore, the stage `restored`
    (full gravity after `reduced`)."""
    return tilt_stages() + stretch_stages() + (["restored"] if config["probe"]["restore"] else [])


def probe_input_stage(stage):
    """The stage a probe starts from: `reduced` for `restored`, else `relaxed`."""
    return "reduced" if stage == "restored" else "relaxed"


def probe_change(stage):
    """The simulator's options of the probe `stage` (python -m sim probe):
    --level Delta, --tilt +-delta, --stretch epsilon or --restore."""
    if stage == "restored":
        return ["--restore"]
    if stage == STRETCH_STAGE:
        return ["--stretch", repr(float(config["probe"]["stretch"]))]
    for tilt in signed_tilts():
        if stage == tilt_stage(tilt):
            return ["--tilt", repr(tilt)]
    return ["--level", repr(level_for_stage(stage))]


def level_for_stage(stage):
    """Inverse of stage_for_level, for the probe rule's `stage` wildcard."""
    for level in config["probe"]["levels"]:
        if stage_for_level(level) == stage:
            return float(level)
    raise ValueError(
        f"stage {stage!r} is not a configured gravity probe; "
        f"probe.levels {config['probe']['levels']} give {probe_stages()}"
    )


def sim_params(*sections):
    """The given simulator sections of the config as canonical JSON (sorted keys).

    A simulation job receives only the sections it reads, so a changed setting
    re-runs exactly the jobs that depend on it (pouring reads model, particles,
    pour and physics; relaxing model, pour and relax, the physics coming with
    the poured state; probing also probe). Adding a
    gravity level therefore re-runs only the probes, and a change in analysis
    or protocols no simulation. The bookkeeping settings (sim.config.BOOKKEEPING:
    checkpoint and progress intervals) change no result and are left out; they
    travel in sim_bookkeeping().
    """
    return json.dumps(result_settings({k: config[k] for k in sections}), sort_keys=True)


def probe_sim_params(stage):
    """The simulator sections of the probe `stage` as canonical JSON
    (sim_params("model", "pour", "relax", "probe")), each probe with only
    its own keys of `probe`: the support stretch its STRETCH_KEYS, the
    gravity probes all others. So a scene that adds the stretch re-runs no
    gravity probe, and one that adds a tilt no stretch."""
    settings = json.loads(sim_params("model", "pour", "relax", "probe"))
    own = (lambda k: k in STRETCH_KEYS) if stage == STRETCH_STAGE else (lambda k: k not in STRETCH_KEYS)
    settings["probe"] = {k: v for k, v in settings["probe"].items() if own(k)}
    return json.dumps(settings, sort_keys=True)


class Unrecorded:
    """A rule param that Snakemake does not record, so that changing it re-runs
    nothing: Snakemake records and compares only params of builtin types. In a
    shell command it formats as `text`."""

    def __init__(self, text):
        self.text = text

    def __str__(self):
        return self.text


def sim_bookkeeping():
    """The bookkeeping settings (sim.config.BOOKKEEPING) as JSON for the
    simulator's --bookkeeping option, an Unrecorded param: a changed checkpoint
    or progress interval re-pours no pile."""
    settings = {s: {k: config[s][k] for k in keys} for s, keys in BOOKKEEPING.items()}
    return Unrecorded(json.dumps(settings, sort_keys=True))


def pile_targets(stages=None):
    """All particle-state files of the configured piles."""
    if stages is None:
        stages = ["poured", "relaxed"] + probe_stages() + extra_probe_stages()
    return [
        pile(protocol, seed, stage)
        for protocol in PROTOCOLS
        for seed in seeds(protocol)
        for stage in stages
    ]


def pile_figure(protocol, seed, stage):
    """Path of the picture of one pile state."""
    return results_path(f"figures/piles/{protocol}_seed{seed}_{stage}.png")


# The table of the simulation jobs' run times (rule run_times_table, in the report).
RUN_TIMES_TABLE = results_path("run_times.html")


def pile_benchmarks():
    """Benchmark files of every simulation job of the scene's piles (pour,
    relax, each probe)."""
    return [
        path
        for protocol in PROTOCOLS
        for seed in seeds(protocol)
        for path in [results_path(f"benchmarks/pour/{protocol}/seed{seed}.tsv"),
                     results_path(f"benchmarks/relax/{protocol}/seed{seed}.tsv")]
        + [results_path(f"benchmarks/probe/{protocol}/seed{seed}_{stage}.tsv")
           for stage in probe_stages() + extra_probe_stages()]
    ]


def pile_frames(protocol, seed):
    """Path of the frames of a pile's pour (python -m sim pour --frames; output film)."""
    return results_path(f"piles/{protocol}/seed{seed}/frames.nc")


def pile_film(protocol, seed, ext="mp4"):
    """Path of the film of a pile's pour (python -m analysis film): the MP4,
    or with ext="html" the page holding it that the report shows."""
    return results_path(f"films/{protocol}_seed{seed}.{ext}")


def pile_vtk(protocol, seed, stage):
    """Path of the VTK file of one pile state's particles (python -m analysis
    export; its contact network is the same name with _contacts)."""
    return results_path(f"vtk/{protocol}_seed{seed}_{stage}.vtu")


def pile_figure_targets(stage="relaxed"):
    """Pictures of all configured piles at one stage."""
    return [
        pile_figure(protocol, seed, stage)
        for protocol in PROTOCOLS
        for seed in seeds(protocol)
    ]


def _check_config():
    """The workflow's own checks (its stage names and probes) that neither the
    schemas nor the packages' checks (workflow/validation.py) express; fail
    before any job runs."""
    problems = []
    stages = probe_stages()
    if len(set(stages)) != len(stages):
        problems.append(
            f"probe.levels {config['probe']['levels']} give repeated stage names "
            f"{stages}: levels must differ at percent resolution"
        )
    tilts = tilt_stages()
    if len(set(tilts)) != len(tilts):
        problems.append(
            f"probe.tilts {config['probe']['tilts']} give repeated stage names {tilts}: "
            "tilts must differ at percent resolution"
        )
    stretch = float(config["probe"]["stretch"])
    if stretch != 0.0 and not config["physics"]["support"]:
        problems.append(
            f"probe.stretch = {stretch} with physics.support = false: the stretch moves the "
            "support's surface; set probe.stretch to 0"
        )
    if stretch != 0.0 and config["model"]["support_friction"] == 0:
        problems.append(
            f"probe.stretch = {stretch} with model.support_friction = 0: the support drags the "
            "particles only through friction; give model.support_friction > 0 or set probe.stretch to 0"
        )
    if config["probe"]["restore"] and not stages:
        problems.append(
            "probe.restore = true with probe.levels = []: restoring gravity needs a "
            "gravity reduction first (give a level)"
        )
    bad = [s for s in stages if not re.fullmatch(STAGE_PATTERN, s)]
    if bad:
        problems.append(
            f"probe.levels {config['probe']['levels']} give stage names {bad} "
            f"outside 'reduced' / 'reducedNN': keep each level in [0.005, 0.995)"
        )
    if problems:
        raise ValueError("invalid configuration:\n  " + "\n  ".join(problems))


_check_config()


wildcard_constraints:
    protocol="wedge|layered",
    seed=r"\d+",


# --- Resources for schedulers ----------------------------------------------
# What a cluster executor requests per job (SLURM: --cpus-per-task = threads,
# --mem = mem_mb, --time = runtime in minutes; docs/cluster.md); locally they only matter with --resources limits. The simulation
# runtimes are estimated from the configuration:
#
#   minutes = START_MIN + RUNTIME_MARGIN * steps * particles * PARTICLE_STEP_S
#             / speedup(threads) / 60,   steps = simulated time / dt,
#
# and multiplied by the attempt number, so a job that SLURM killed at its time
# limit asks for twice the time when --retries resubmits it (a pour resumes
# from its checkpoint, so it needs less; relaxations start again).

# Measured on this project's 2-core machine: the full-size layered pour of the
# study (3500 particles, velocity Verlet, 100 particles/s, one thread) took
# 4585 s of CPU for 5.14 M steps and 9.04e9 particle-steps, 0.51 us per
# particle-step (docs/performance.md, "How long").
PARTICLE_STEP_S = 0.5e-6
# Safety factor on the step cost (a slower or busier node).
RUNTIME_MARGIN = 1.5
# Python start, loading the compiled kernels, reading and writing state files.
START_MIN = 2
# Automatic time step of the default particles (semi-axis 3.4 mm, density
# 2500 kg/m2, Y = 1e7 N/m, dt_safety 0.5; docs/model.md, time-step rule). It scales
# like sqrt(mass / stiffness), i.e. like semi-axis * sqrt(density / Y).
DT_REFERENCE_S = {"gear": 1.9e-6, "verlet": 6.9e-6}
# A release waits while its spot is not clear, so pouring takes longer than
# n_particles / rate: 35.6 s (layered) and 41 s (wedge) instead of 35 s for the
# study's pours (docs/performance.md, "How long").
POUR_TIME_FACTOR = 1.5
# Simulated time a relaxation or gravity probe typically needs: a 3500-particle
# pile relaxed in 0.42-0.83 s (at most relax.max_time, after which the simulator
# gives up by itself).
RELAX_TYPICAL_S = 2.0
# Peak memory measured for 150 and for 3500 particles: 230-250 MB (Python,
# Numba and netCDF dominate; the particle arrays take about 1.3 kB each).
SIM_MEM_BASE_MB = 1000
SIM_MEM_PER_PARTICLE_MB = 0.1


def estimated_dt():
    """Time step (s) of the simulations: model.dt if set, else the automatic
    step of the reference particles scaled to the configured ones."""
    model, particles = config["model"], config["particles"]
    if model["dt"] is not None:
        return float(model["dt"])
    scale = (particles["semi_axis_mean"] / 3.4e-3) * math.sqrt(
        (model["density"] / 2500.0) / (model["youngs_modulus"] / 1e7)
    )
    return DT_REFERENCE_S[model["integrator"]] * scale * model["dt_safety"] / 0.5


def sim_runtime_min(simulated_s, particles, attempt):
    """Wall-clock minutes to request for `simulated_s` seconds of simulated
    time with `particles` particles on average, on SIM_THREADS threads (the
    parallel kernels are assumed to scale with 80 % efficiency)."""
    speedup = 1.0 + 0.8 * (SIM_THREADS - 1)
    seconds = simulated_s / estimated_dt() * particles * PARTICLE_STEP_S / speedup
    return attempt * math.ceil(START_MIN + RUNTIME_MARGIN * seconds / 60.0)


def pour_runtime_min(wildcards, attempt):
    """Runtime (min) of a pour: the release time, stretched by POUR_TIME_FACTOR,
    plus the settling time, with half the particles on average."""
    pour = config["pour"]
    simulated = POUR_TIME_FACTOR * pour["n_particles"] / pour["rate"] + 0.1
    return sim_runtime_min(simulated, pour["n_particles"] / 2, attempt)


def relax_runtime_min(wildcards, attempt):
    """Runtime (min) of relaxing the full pile for RELAX_TYPICAL_S (at most
    relax.max_time)."""
    simulated = min(RELAX_TYPICAL_S, config["relax"]["max_time"])
    return sim_runtime_min(simulated, config["pour"]["n_particles"], attempt)


def probe_runtime_min(wildcards, attempt):
    """Runtime (min) of a probe: the gravity ramp, if any, or the support
    stretch, and a relaxation."""
    probe = config["probe"]
    simulated = min(RELAX_TYPICAL_S, config["relax"]["max_time"])
    if wildcards.stage == STRETCH_STAGE:
        simulated += probe["stretch_time"]
    elif probe["mode"] == "ramp":
        simulated += probe["ramp_time"]
    return sim_runtime_min(simulated, config["pour"]["n_particles"], attempt)


def per_attempt(value):
    """Resource callable: `value` times the attempt number."""
    return lambda wildcards, attempt: value * attempt


def sim_mem_mb(wildcards, attempt):
    """Memory (MB) of a simulation job, growing with the attempt (a job killed
    for memory asks for more when resubmitted)."""
    n = config["pour"]["n_particles"]
    return attempt * math.ceil(SIM_MEM_BASE_MB + SIM_MEM_PER_PARTICLE_MB * n)


# Largest memory (MB) a cluster node is assumed to have when no --resources
# mem_mb says otherwise: 4 TB.
CLUSTER_NODE_MEM_MB = 4_000_000
# Run-time estimate (min) of one pour beyond which the plan is called absurd: a week.
ABSURD_RUNTIME_MIN = 7 * 24 * 60


def _check_size():
    """Refuse, before any job, a pile whose job cannot fit in memory: the limit
    is --resources mem_mb if given, else this machine's memory (local jobs) or
    CLUSTER_NODE_MEM_MB (cluster jobs). Warn about a pour estimated to take
    longer than ABSURD_RUNTIME_MIN."""
    need = sim_mem_mb(None, 1)
    limit = workflow.global_resources.get("mem_mb")
    limit, where = getattr(limit, "value", limit), "--resources mem_mb"
    if limit is not None:
        pass
    elif workflow.local_exec:
        limit = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
        where = "the memory of this machine"
    else:
        limit, where = CLUSTER_NODE_MEM_MB, "the largest cluster node assumed"
    n = config["pour"]["n_particles"]
    if need > limit:
        raise ValueError(
            f"pour.n_particles = {n}: a simulation job would need about {need:.0f} MB "
            f"({SIM_MEM_BASE_MB} MB + {SIM_MEM_PER_PARTICLE_MB} MB per particle), more than "
            f"{where} ({limit:.0f} MB); pour fewer particles")
    minutes = pour_runtime_min(None, 1)
    if minutes > ABSURD_RUNTIME_MIN:
        logger.warning(
            f"pour.n_particles = {n}, pour.rate = {config['pour']['rate']}: each pour is "
            f"estimated to take {minutes / 1440:.0f} days on {SIM_THREADS} threads")


_check_size()
