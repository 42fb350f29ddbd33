"""The Snakemake workflow: lint, the jobs of a dry run, what re-runs after an
edit, and (slow) the smoke study end to end.

Every test works in a temporary copy of the workflow, so the repository's own
results/ and .snakemake/ are never touched.
"""

import contextlib
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
import pytest
import yaml

from sim.config import SimConfig

REPO = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]
SMOKE = ["--configfile", "config/smoke.yaml", "--replace-workflow-config"]
SMOKE_CONFIG = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
PILE_RULES = ("compile_kernels", "pour", "relax", "probe")


def copy_workflow(dest, with_sim=True):
    """Copy what the workflow needs (no results) to `dest`, with the kernels
    this test session has compiled so far (share_compiled_kernels)."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy2(REPO / "Snakefile", dest / "Snakefile")
    names = ["workflow", "config", "analysis"] + (["sim"] if with_sim else [])
    for name in names:
        shutil.copytree(REPO / name, dest / name, ignore=ignore)
    if with_sim:
        share_compiled_kernels(dest)
    return dest


def share_compiled_kernels(dest):
    """Copy the Numba cache of the repository's sim/ to the copy in `dest`,
    where the workflow keeps it (`.numba_cache`, workflow/rules/common.smk), so
    that its rule compile_kernels loads the kernels instead of compiling them
    again (about 30 s per copy on 2 cores).

    sim/kernel_cache.py files the cache under a folder named by a digest of the
    sources, the same for the copy; under it Numba names a folder per source
    folder by a hash of its absolute path, and takes an entry as fresh when
    its source file's modification time and size match, which shutil.copy2
    keeps. A fresh clone's first tests still compile into its empty cache.
    """
    from numba.core.caching import _CacheLocator

    import sim.kernel_cache  # noqa: F401 (sets the cache folder)

    cache = Path(numba.config.CACHE_DIR)
    for folder in sorted({path.parent for path in (REPO / "sim").rglob("*.py")}):
        ours = cache / _CacheLocator.get_suitable_cache_subpath(str(folder / "_.py"))
        copied = dest / folder.relative_to(REPO)
        theirs = dest / ".numba_cache" / cache.name / _CacheLocator.get_suitable_cache_subpath(
            str(copied / "_.py"))
        if ours.is_dir():
            shutil.copytree(ours, theirs, dirs_exist_ok=True)


def snakemake(cwd, *args, timeout=300):
    """Run Snakemake in `cwd`; stdout and stderr together."""
    proc = subprocess.run(
        [*SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True,
        timeout=timeout, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    proc.output = proc.stdout + proc.stderr
    return proc


def job_counts(output):
    """The 'Job stats' table of a (dry) run as {rule: count}; {} when there is
    nothing to do."""
    counts = {}
    if "Job stats:" not in output:
        return counts
    table = output.split("Job stats:", 1)[1]
    for line in table.splitlines()[3:]:
        match = re.fullmatch(r"\s*(\w+)\s+(\d+)\s*", line)
        if not match or match.group(1) == "total":
            break
        counts[match.group(1)] = int(match.group(2))
    return counts


def with_overrides(root, name, overrides):
    """Snakemake arguments: the smoke config plus a file of overrides (nested
    values given with --config lose their types)."""
    path = root / "config" / f"{name}.yaml"
    path.write_text(yaml.safe_dump(overrides))
    return ["--configfile", "config/smoke.yaml", str(path.relative_to(root)),
            "--replace-workflow-config"]


def smoke_piles():
    return [(p, s) for p in ("wedge", "layered") for s in SMOKE_CONFIG["protocols"][p]["seeds"]]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return copy_workflow(tmp_path_factory.mktemp("workflow"))


# --- (a) lint --------------------------------------------------------------

@pytest.mark.parametrize("configfile", [[], SMOKE], ids=["config", "smoke"])
def test_lint_passes(workdir, configfile):
    proc = snakemake(workdir, "--lint", *configfile)
    assert proc.returncode == 0, proc.output


# --- (b) dry runs ------------------------------------------------------------

@pytest.mark.parametrize("replace", [True, False], ids=["replace", "no-replace"])
def test_a_configfile_replaces_the_study_config(tmp_path, replace):
    """With or without --replace-workflow-config, `--configfile smoke.yaml` runs
    the smoke piles with the schema's defaults, never the study's settings:
    cluster jobs receive --configfiles without that flag, and a job that merged
    config/config.yaml back in would simulate with the study's settings. The
    study's config here carries a friction that neither smoke.yaml nor the
    schema gives."""
    root = copy_workflow(tmp_path / "wf")
    study = root / "config" / "config.yaml"
    study.write_text(study.read_text().replace("  friction: 0.5 ", "  friction: 0.37"))
    assert "friction: 0.37" in study.read_text()
    args = SMOKE if replace else SMOKE[:2]
    proc = snakemake(root, "-n", "-p", "--cores", "2", *args)
    assert proc.returncode == 0, proc.output
    assert job_counts(proc.output)["pour"] == len(smoke_piles())
    assert '"friction": 0.5' in proc.output and '"friction": 0.37' not in proc.output


def test_smoke_dry_run_lists_the_pile_jobs(workdir):
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *SMOKE)
    assert proc.returncode == 0, proc.output
    counts = job_counts(proc.output)
    n = len(smoke_piles())
    assert n == 4
    expected = {"compile_kernels": 1, "pour": n, "relax": n, "probe": n, "draw_pile": n, "export_pile": n}
    assert {rule: counts.get(rule) for rule in expected} == expected, proc.output
    assert counts["all"] == 1
    for protocol, seed in smoke_piles():
        base = f"results/smoke/piles/{protocol}/seed{seed}"
        for stage in ("poured", "relaxed", "reduced"):
            assert f"{base}/{stage}.nc" in proc.output
        assert f"--checkpoint {base}/pour.checkpoint.nc" in proc.output
        assert f"results/smoke/figures/piles/{protocol}_seed{seed}_relaxed.png" in proc.output
    assert "--level 0.1 " in proc.output
    assert "NUMBA_NUM_THREADS=1 " in proc.output  # smoke.yaml: threads 1


def test_a_pour_refused_by_the_lock_leaves_the_running_pours_log_whole(tmp_path):
    """A second Snakemake (--nolock) pours a pile that a live process is
    pouring: the simulator's lock refuses, the running pour's log is left as
    it was, and the refusal, naming the running process, is in the job's log
    and on the terminal (Snakemake deleted the job's log, then the pile's
    log, before the simulator could refuse). The running pour is this test's
    process, named in the lock, with a log of one progress line."""
    import socket

    root = copy_workflow(tmp_path / "wf")
    pile = root / "results/smoke/piles/wedge/seed1"
    pile.mkdir(parents=True)
    running = f"{socket.gethostname()} {os.getpid()}"
    (pile / "pour.checkpoint.nc.lock").write_text(running + "\n")
    log = root / "results/smoke/logs/pour/wedge/seed1.log"
    log.parent.mkdir(parents=True)
    first = ("2026-12-04 10:00:00,000 INFO pour wedge seed 1: released 40 of 150 (27 %), "
             "ETA 0:01:00; t = 0.4000 s simulated\n")
    log.write_text(first)
    compiled = root / "results/smoke/.numba/compiled.ok"   # the kernels: not this test's subject
    compiled.parent.mkdir(parents=True)
    compiled.touch()
    proc = snakemake(root, "--nolock", "--show-failed-logs", "--cores", "1", *SMOKE,
                     str(pile.relative_to(root) / "poured.nc"))
    assert proc.returncode != 0 and job_counts(proc.output) == {"pour": 1}, proc.output
    assert log.read_text() == first
    refused = f"being poured by process {running!r}"
    assert refused in log.with_suffix(".job.log").read_text() and refused in proc.output
    assert not (pile / "poured.nc").exists()


def test_paper_dry_run_has_19_piles(workdir):
    proc = snakemake(workdir, "-n", "--cores", "2", "piles")
    assert proc.returncode == 0, proc.output
    counts = job_counts(proc.output)
    assert counts == {"compile_kernels": 1, "pour": 19, "relax": 19, "probe": 19, "piles": 1}


def job_files(output, field):
    """Every path a dry run lists in the jobs' `field:` lines (input, output, log, benchmark)."""
    return [path for line in output.splitlines() if line.startswith(f"    {field}: ")
            for path in line.split(": ", 1)[1].split(", ")]


REPRODUCTION = ["--configfile", "config/config.yaml", "config/scenes/elastic_probes.yaml",
                "config/reproduction.yaml"]


@pytest.mark.parametrize("args, target, folder", [
    ([], "all", "results/study/"),
    (SMOKE, "all", "results/smoke/"),
    (REPRODUCTION, "reproduction", "results/reproduction/"),
], ids=["study", "smoke", "reproduction"])
def test_each_configuration_writes_its_own_results_folder(workdir, args, target, folder):
    """Issue 29, item 2: make reproduction once rewrote the smoke's ensembles and
    figures, and make report and the smoke the same report. Every output, log
    and benchmark of a configuration lies in its own folder (config `results`);
    only make reproduction writes the committed records' figures and tables,
    which are its purpose."""
    if target == "reproduction" and not (workdir / "docs" / "reproduction").exists():
        shutil.copytree(REPO / "docs" / "reproduction", workdir / "docs" / "reproduction")
    proc = snakemake(workdir, target, "-n", "--cores", "2", *args)
    assert proc.returncode == 0, proc.output
    written = job_files(proc.output, "output") + job_files(proc.output, "log") \
        + job_files(proc.output, "benchmark")
    assert len(written) > 20
    records = ("docs/reproduction/", f"{workdir}/docs/reproduction/")
    committed = {path for path in written if path.startswith(records)}
    assert [path for path in written if not path.startswith(folder) and path not in committed] == []
    assert bool(committed) == (target == "reproduction")


def test_a_report_among_another_configurations_results_is_refused(workdir):
    """The smoke's report belongs in results/smoke/: results/report.html (the
    one file make report and make smoke both wrote) and the study's folder
    are refused before anything is read, naming where it belongs."""
    for path in ("results/report.html", "results/study/report.html"):
        proc = snakemake(workdir, *SMOKE, "--report", path)
        assert proc.returncode != 0
        assert f"--report {path}: this configuration (config/smoke.yaml) writes its results to " \
            "results/smoke/" in proc.output, proc.output
        assert not (workdir / path).exists()


def test_no_job_lists_the_sources_as_inputs(workdir):
    """Issue 29, item 7: every rule once listed sim/*.py or all 33 analysis/*.py
    as inputs, so each job's entry in the log was that long; the code now
    travels as a digest param, and the inputs are the job's own files."""
    proc = snakemake(workdir, "-n", "--cores", "2", *SMOKE)
    assert proc.returncode == 0, proc.output
    inputs = job_files(proc.output, "input")
    assert inputs and not [path for path in inputs if path.endswith(".py")]


def test_an_edit_of_the_analysis_remakes_the_pages_of_make_reproduction(tmp_path):
    """The tools' rules of make reproduction carry the analysis' digest (param
    `code`, as the analysis rules do): an edit of analysis/history.py remakes
    the variant's page, whose numbers it computes, which once stayed as it
    was; the page made again from the records is the committed one. (The
    decision's pages need the git history of their registrations, which a copy
    lacks.)"""
    root = copy_workflow(tmp_path)
    shutil.copytree(REPO / "docs" / "reproduction", root / "docs" / "reproduction")
    page = root / "docs" / "reproduction" / "variants" / "support_friction_0.9.md"  # the rules' paths are absolute
    proc = snakemake(root, str(page), "--cores", "1", *REPRODUCTION, "--forcerun", "reproduction_variant")
    assert proc.returncode == 0, proc.output
    assert page.read_text() == (REPO / page.relative_to(root)).read_text()
    assert job_counts(snakemake(root, str(page), "-n", "--cores", "1", *REPRODUCTION).output) == {}
    with edited(root / "analysis" / "history.py"):
        proc = snakemake(root, str(page), "-n", "--cores", "1", *REPRODUCTION)
    assert job_counts(proc.output) == {"reproduction_variant": 1}, proc.output
    assert "Params have changed since last execution" in proc.output


def test_the_simulation_digest_is_the_code_version_of_the_states(tmp_path):
    """The param `code` of the simulation rules is the code version every state
    file records (sim.io.code_version), and the analysis' --version prints the
    digest of its rules: one rule (sim.digest.code_digest), over the same files.
    The digest is checked against hashlib over the files written out here."""
    import hashlib

    from sim.digest import code_digest
    from sim.io import code_version

    assert code_digest(REPO / "sim") == code_version()
    assert code_digest(REPO / "analysis") != code_digest(REPO / "sim")
    by_hand = hashlib.sha256(b"a.py\0x = 1\n" + b"b.py\0y = 2\n").hexdigest()[:16]
    (tmp_path / "b.py").write_text("y = 2\n")
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "c.py").write_text("z = 3\n")       # subfolders do not count
    assert code_digest(tmp_path) == by_hand
    out = subprocess.run([sys.executable, "-m", "analysis", "--version"], capture_output=True, text=True,
                         cwd=REPO).stdout
    assert f"code digest {code_digest(REPO / 'analysis')} " in out


def test_each_probe_level_is_a_stage(workdir):
    config = with_overrides(workdir, "levels", {"probe": {"levels": [0.1, 0.05]}})
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *config, "piles")
    assert proc.returncode == 0, proc.output
    assert job_counts(proc.output)["probe"] == 2 * len(smoke_piles())
    assert "results/smoke/piles/wedge/seed1/reduced.nc" in proc.output
    assert "results/smoke/piles/wedge/seed1/reduced05.nc" in proc.output
    assert "--level 0.05 " in proc.output


@pytest.mark.parametrize("name, override, message", [
    ("corners", {"particles": {"corners_min": 8, "corners_max": 6}}, "corners_min"),
    ("levels", {"probe": {"levels": [0.1, 0.05, 0.051]}}, "percent resolution"),
    ("tilts", {"probe": {"tilts": [0.05, 0.0501]}}, "tilts must differ at percent resolution"),
    ("restore", {"probe": {"levels": [], "restore": True}}, "probe.restore = true with probe.levels = []"),
    ("threads", {"threads": 0}, "threads"),
    # workflow/validation.py runs before any job (and before resource functions)
    ("nan", {"model": {"youngs_modulus": float("nan")}}, "model.youngs_modulus = nan"),
    ("integer", {"pour": {"n_particles": 150.0}}, "pour.n_particles = 150.0: must be an integer"),
    ("grid", {"analysis": {"grid": {"x_min": 0.1, "x_max": -0.1}}}, "analysis.grid.x_min = 0.1"),
    ("size", {"pour": {"n_particles": 10**6}}, "would need about 101000 MB"),
    ("seed", {"protocols": {"wedge": {"seeds": [10**20]}}}, "4294967295"),
    ("raster", {"analysis": {"rve": {"size": 50.0}}}, "analysis.rve.size = 50.0 over the grid"),
    ("too_few", {"pour": {"n_particles": 1}}, "pour.n_particles = 1 is fewer than analysis.rve.min_particles = 8"),
    ("convergence_seed", {"analysis": {"convergence": {"seed": 7}}},
     "analysis.convergence.seed = 7 is not a seed of protocol wedge"),
])
def test_bad_config_stops_before_any_job(workdir, name, override, message):
    config = with_overrides(workdir, f"bad_{name}", override)
    proc = snakemake(workdir, "-n", "--cores", "2", *config)
    assert proc.returncode != 0
    assert message in proc.output, proc.output


def shell_blocks(text):
    """The `shell:` sections of a rule file, each as one string."""
    blocks, lines = [], text.splitlines()
    for k, line in enumerate(lines):
        if line.strip() == "shell:":
            indent = len(line) - len(line.lstrip())
            block = []
            for rest in lines[k + 1:]:
                if rest.strip() and len(rest) - len(rest.lstrip()) <= indent:
                    break
                block.append(rest)
            blocks.append("\n".join(block))
    return blocks


def test_every_file_and_param_reaches_the_shell_quoted():
    """A value with a space or a `;` must stay one argument: every {input},
    {output}, {log} and {params} in a shell command carries :q."""
    found = 0
    for path in sorted((REPO / "workflow" / "rules").glob("*.smk")):
        for block in shell_blocks(path.read_text()):
            for name, spec in re.findall(r"(?<!\{)\{((?:input|output|log|params)[.\w]*)(:\w*)?\}",
                                         block):
                found += 1
                assert spec == ":q", f"{path.name}: {{{name}{spec}}} is not quoted"
    assert found > 50


# --- scenes: only what the configuration's outputs ask for is built -----------

def scene_args(name):
    """Snakemake arguments of a scene of config/scenes laid over the smoke study."""
    return ["--configfile", "config/smoke.yaml", f"config/scenes/{name}.yaml",
            "--replace-workflow-config"]


def test_stress_only_scene_runs_no_probe_no_fit_no_figure(workdir):
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *scene_args("stress_only"))
    assert proc.returncode == 0, proc.output
    n = len(smoke_piles())
    assert job_counts(proc.output) == {
        "compile_kernels": 1, "pour": n, "relax": n, "pile_summary": n, "analysis_fields": n,
        "analysis_base_pressure_pile": n, "analysis_ensemble": 2, "analysis_base_pressure": 2,
        "all": 1}
    assert "--reduced" not in proc.output and "reduced.nc" not in proc.output
    assert "--quantities  --params" in proc.output   # the stress only


def test_the_elastic_probes_scene_tilts_and_restores_every_pile(workdir):
    """config/scenes/elastic_probes.yaml: per pile the reduction, gravity tilted
    by +0.05 and -0.05 g0 from the relaxed state, and full gravity restored
    from the reduced one; the run-time table counts all four probes."""
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *scene_args("elastic_probes"))
    assert proc.returncode == 0, proc.output
    n = len(smoke_piles())
    assert job_counts(proc.output)["probe"] == 4 * n
    for protocol, seed in smoke_piles():
        folder = f"results/smoke/piles/{protocol}/seed{seed}"
        for start, option, stage in (("relaxed", "--level 0.1", "reduced"),
                                     ("relaxed", "--tilt 0.05", "tiltp05"),
                                     ("relaxed", "--tilt -0.05", "tiltm05"),
                                     ("reduced", "--restore", "restored")):
            assert f"--input {folder}/{start}.nc {option} --out {folder}/{stage}.nc" in proc.output, \
                (protocol, seed, stage)


def test_a_scene_without_figures_draws_nothing(workdir):
    outputs = ["states", "fields", "strain", "fabric", "fits"]
    config = with_overrides(workdir, "no_figures", {"outputs": outputs})
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *config)
    assert proc.returncode == 0, proc.output
    counts = job_counts(proc.output)
    assert not [rule for rule in counts if "figure" in rule or rule == "draw_pile"], counts
    n = len(smoke_piles())
    assert counts["probe"] == n and counts["analysis_moduli"] == 2
    assert "--quantities fabric strain " in proc.output


@pytest.mark.parametrize("name", ["frictionless", "no_rotation"])
def test_physics_scenes_reach_the_pour(workdir, name):
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *scene_args(name))
    assert proc.returncode == 0, proc.output
    scene = yaml.safe_load((REPO / "config" / "scenes" / f"{name}.yaml").read_text())
    pour = next(line for line in proc.output.splitlines() if " pour --params " in line)
    params = json.loads(shlex.split(pour.split(" pour --params ", 1)[1])[0])
    for section, values in scene.items():
        if section in params:
            assert params[section] == {**params[section], **values}, section


def test_the_analysis_settings_travel_as_flow_text_the_report_shows_unescaped(workdir):
    """snakemake --report shows a job's params under "Job parameters" with
    every double quote backslash-escaped (Snakemake escapes them before it
    stores the params as JSON in the page), so JSON settings read
    {\\"rve\\": ...}. The analysis settings travel as one line of YAML flow
    text instead, without double quotes, backslashes or line breaks, and the
    analysis reads them back to the configured values."""
    from analysis.params import parse_params

    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *SMOKE)
    assert proc.returncode == 0, proc.output
    lines = [line for line in proc.output.splitlines() if "-m analysis figure " in line]
    assert lines, proc.output
    for line in lines:
        text = shlex.split(line.split(" --params ", 1)[1])[0]
        assert text.startswith("{") and " rve: {" in text, text   # YAML flow: keys without quotes
        assert not set(text) & set('"\\\n'), text
        assert parse_params(text) == parse_params(json.dumps(SMOKE_CONFIG["analysis"])), text


@pytest.mark.parametrize("name, override, message", [
    ("fits_without_strain", {"outputs": ["states", "fields", "fits"]}, "fits needs strain"),
    ("strain_without_probe", {"outputs": ["fields", "strain"], "probe": {"levels": []}},
     "strain is the response to a gravity probe but probe.levels is []"),
    ("unknown_output", {"outputs": ["fields", "stresses"]}, "'stresses' is not one of"),
    ("no_support", {"physics": {"support": False}}, "physics.support = false"),
    ("base_pressure_stage", {"outputs": ["fields"], "probe": {"levels": []},
                             "analysis": {"base_pressure": {"stage": "reduced"}}},
     "analysis.base_pressure.stage = 'reduced' is not a stage of this scene"),
])
def test_bad_scene_stops_before_any_job(workdir, name, override, message):
    config = with_overrides(workdir, f"bad_{name}", override)
    proc = snakemake(workdir, "-n", "--cores", "2", *config)
    assert proc.returncode != 0
    assert message in proc.output, proc.output


# --- (c) what re-runs after an edit -------------------------------------------

# A stand-in for `python -m sim`: checks the command line the rules build
# against the simulator's interface and writes what it was given as "output".
#: The fake simulator's checks of the piles before any job (workflow.piles.Piles.preflight):
#: it stands for sim/preflight.py and refuses nothing, as the fake simulator pours anything.
FAKE_PREFLIGHT = '''def check_piles(cfg, protocols, seed):
    """Stands for sim.preflight.check_piles: the fake simulator refuses no settings."""
'''

FAKE_SIM_MAIN = '''
import argparse, json, os, sys
from pathlib import Path

SECTIONS = {"pour": {"model", "particles", "pour", "physics"}, "relax": {"model", "pour", "relax"},
            "probe": {"model", "pour", "relax", "probe"}}
cmd, rest = sys.argv[1], sys.argv[2:]
if cmd == "warmup":
    assert os.environ["NUMBA_CACHE_DIR"].endswith(".numba_cache")
    sys.exit(0)
if cmd == "summary":  # one JSON line per state file, on stdout
    for state in rest:
        assert Path(state).exists(), state
        print(json.dumps({"cmd": cmd, "state": state}))
    sys.exit(0)
parser = argparse.ArgumentParser()
for option in ("--params", "--bookkeeping", "--protocol", "--seed", "--out", "--checkpoint",
               "--input", "--level", "--frames", "--log", "--finished"):
    parser.add_argument(option)
args = parser.parse_args(rest)
if cmd in ("pour", "relax", "probe"):
    assert set(json.loads(args.params)) == SECTIONS[cmd], args.params
    assert "checkpoint_interval" not in json.loads(args.params)["pour"], args.params
    assert set(json.loads(args.bookkeeping)["pour"]) == {"checkpoint_interval",
                                                        "progress_interval", "frame_interval"}
    assert int(os.environ["NUMBA_NUM_THREADS"]) >= 1
if cmd != "pour":
    assert Path(args.input).exists()
if cmd == "probe":
    float(args.level)
record = {"cmd": cmd, "args": vars(args),
          "env": {k: os.environ.get(k) for k in ("NUMBA_NUM_THREADS", "NUMBA_CACHE_DIR")}}
Path(args.out).write_text(json.dumps(record))
if args.frames:
    Path(args.frames).write_text(json.dumps(record))
'''

# python -m analysis draw, faked: records its command line in the picture.
FAKE_ANALYSIS_MAIN = '''
import argparse, json, sys
from pathlib import Path

cmd, rest = sys.argv[1], sys.argv[2:]
assert cmd == "draw", cmd
parser = argparse.ArgumentParser()
for option in ("--input", "--out"):
    parser.add_argument(option, required=True)
args = parser.parse_args(rest)
assert Path(args.input).exists()
Path(args.out).write_text(json.dumps({"cmd": cmd, "args": vars(args)}))
'''


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """A copy with a fake simulator and picture code whose pile and picture jobs have all run."""
    root = copy_workflow(tmp_path_factory.mktemp("edits"), with_sim=False)
    (root / "sim").mkdir()
    (root / "sim" / "__init__.py").write_text("")
    (root / "sim" / "__main__.py").write_text(FAKE_SIM_MAIN)
    (root / "sim" / "kernels.py").write_text("# stands for the Numba kernels\n")
    (root / "sim" / "preflight.py").write_text(FAKE_PREFLIGHT)
    (root / "analysis" / "__main__.py").write_text(FAKE_ANALYSIS_MAIN)
    targets = ["piles"] + [f"results/smoke/figures/piles/{p}_seed{s}_relaxed.png"
                           for p, s in smoke_piles()]
    proc = snakemake(root, "--cores", "2", *SMOKE, *targets)
    assert proc.returncode == 0, proc.output
    return root, targets


def dry_run(root, targets, *extra):
    proc = snakemake(root, "-n", "--cores", "2", *SMOKE, *targets, *extra)
    assert proc.returncode == 0, proc.output
    return job_counts(proc.output)


class edited:
    """Context: `path` is edited (a line appended, mtime in the future), then
    restored. Snakemake 9 re-runs a job only when an input is newer than its
    output *and* its checksum differs from the recorded one, so a mere touch
    would not do."""

    def __init__(self, path):
        self.path = path

    def __enter__(self):
        self.text = self.path.read_bytes()
        self.stat = self.path.stat()
        self.path.write_bytes(self.text + b"\n# edited\n")
        future = time.time() + 60
        os.utime(self.path, (future, future))

    def __exit__(self, *exc):
        self.path.write_bytes(self.text)
        os.utime(self.path, ns=(self.stat.st_atime_ns, self.stat.st_mtime_ns))


def test_fake_run_passed_the_expected_command_lines(ran):
    root, _ = ran
    pour = json.loads((root / "results/smoke/piles/wedge/seed1/poured.nc").read_text())
    assert pour["args"]["protocol"] == "wedge" and pour["args"]["seed"] == "1"
    assert pour["args"]["checkpoint"] == "results/smoke/piles/wedge/seed1/pour.checkpoint.nc"
    assert pour["env"]["NUMBA_NUM_THREADS"] == str(SMOKE_CONFIG["threads"])
    assert pour["env"]["NUMBA_CACHE_DIR"] == str(root / ".numba_cache")
    params = json.loads(pour["args"]["params"])
    assert params["pour"]["n_particles"] == SMOKE_CONFIG["pour"]["n_particles"]
    # smoke.yaml's integrator, every other model setting filled in by the schema
    assert params["model"] == {**SimConfig().to_dict()["model"], **SMOKE_CONFIG["model"]}
    probe = json.loads((root / "results/smoke/piles/layered/seed2/reduced.nc").read_text())
    assert probe["args"]["input"] == "results/smoke/piles/layered/seed2/relaxed.nc"
    assert float(probe["args"]["level"]) == 0.1
    figure = json.loads((root / "results/smoke/figures/piles/layered_seed2_relaxed.png").read_text())
    assert figure["cmd"] == "draw"
    assert figure["args"]["input"] == "results/smoke/piles/layered/seed2/relaxed.nc"


def test_nothing_to_do_after_a_run(ran):
    assert dry_run(*ran) == {}


def test_asking_for_fewer_outputs_reruns_no_simulation(ran):
    root, _ = ran
    config = with_overrides(root, "states_only", {"outputs": ["states", "figures"]})
    proc = snakemake(root, "-n", "--cores", "2", *config)
    # the run-time table (part of figures) and the piles' run summaries (with the
    # states) are all that is missing: not a simulation
    n = len(smoke_piles())
    assert proc.returncode == 0 and job_counts(proc.output) == {"run_times_table": 1, "pile_summary": n,
                                                                 "all": 1}, proc.output


def test_editing_simulator_code_reruns_the_piles(ran):
    root, targets = ran
    with edited(root / "sim" / "kernels.py"):
        counts = dry_run(root, targets)
    n = len(smoke_piles())
    assert counts == {"compile_kernels": 1, "pour": n, "relax": n, "probe": n,
                      "draw_pile": n, "piles": 1}


def test_editing_the_picture_code_redraws_only(ran):
    root, targets = ran
    with edited(root / "analysis" / "draw.py"):
        assert dry_run(root, targets) == {"draw_pile": len(smoke_piles())}


@pytest.mark.parametrize("folder,rerun", [("analysis", {"draw_pile"}), ("workflow/report", set())])
def test_editing_analysis_code_or_a_caption_leaves_the_piles(ran, folder, rerun):
    """Analysis code re-draws the pictures of piles (analysis/draw.py reads
    the states), never a simulation; a caption re-runs nothing."""
    root, targets = ran
    files = sorted(p for p in (root / folder).rglob("*") if p.is_file())
    assert files
    with contextlib.ExitStack() as stack:
        for path in files:
            stack.enter_context(edited(path))
        assert dry_run(root, targets) == {rule: len(smoke_piles()) for rule in rerun}


@pytest.mark.parametrize("section,change,rerun", [
    ("model", {"friction": 0.4}, ("pour", "relax", "probe")),
    ("relax", {"max_time": 2.0}, ("relax", "probe")),
    ("probe", {"mode": "ramp"}, ("probe",)),
    ("physics", {"rotation": False}, ("pour", "relax", "probe")),
    # bookkeeping: how often a pour saves and reports, never what it pours
    ("pour", {"checkpoint_interval": 5.0}, ()),
    ("pour", {"progress_interval": 1.0}, ()),
    ("pour", {"frame_interval": 0.1}, ()),
])
def test_simulation_parameters_rerun_exactly_the_jobs_that_read_them(ran, section, change,
                                                                       rerun):
    root, targets = ran
    assert dry_run(root, targets, "--config", "threads=2") == {}
    config = with_overrides(root, section, {section: change})
    proc = snakemake(root, "-n", "--cores", "2", *config, *targets)
    assert proc.returncode == 0, proc.output
    counts = job_counts(proc.output)
    n = len(smoke_piles())
    assert {rule: counts.get(rule) for rule in ("pour", "relax", "probe")} == \
        {rule: (n if rule in rerun else None) for rule in ("pour", "relax", "probe")}
    assert "compile_kernels" not in counts


def test_a_scene_without_film_repours_nothing_a_scene_with_film_poured(ran):
    """The smoke asks for films, so its pours wrote frames; the same piles
    without the film output need no pour again (the frames are an extra
    output, passed outside the recorded params)."""
    root, targets = ran
    for frames in root.glob("results/smoke/piles/*/seed*/frames.nc"):
        assert frames.exists()
    assert len(list(root.glob("results/smoke/piles/*/seed*/frames.nc"))) == len(smoke_piles())
    without = with_overrides(root, "no_film", {"outputs": ["states", "figures"]})
    proc = snakemake(root, "-n", "--cores", "2", *without, *targets)
    assert proc.returncode == 0, proc.output
    assert job_counts(proc.output) == {}, proc.output


# python -m analysis, any command, faked: writes what it was given into every
# file named after --out (one or two), --checks, --html and --vtk (and the
# contacts file beside a --vtk one), so the whole smoke study runs in seconds.
FAKE_ANALYSIS_ANY = '''
import json, sys
from pathlib import Path

args = sys.argv[1:]
outs = []
for k, option in enumerate(args):
    if option in ("--out", "--checks", "--html", "--vtk"):
        for value in args[k + 1:]:
            if value.startswith("--"):
                break
            outs += [value] + ([value.replace(".vtu", "_contacts.vtu")] if option == "--vtk" else [])
for out in outs:
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps({"args": args}))
'''


@pytest.fixture(scope="module")
def ran_all(tmp_path_factory):
    """A copy with a fake simulator and analysis in which the whole smoke study
    (rule all: piles, pictures, VTK, films, fields, ensembles, fits, figures) has run."""
    root = copy_workflow(tmp_path_factory.mktemp("all"), with_sim=False)
    (root / "sim").mkdir()
    (root / "sim" / "__init__.py").write_text("")
    (root / "sim" / "__main__.py").write_text(FAKE_SIM_MAIN)
    (root / "sim" / "kernels.py").write_text("# stands for the Numba kernels\n")
    (root / "sim" / "preflight.py").write_text(FAKE_PREFLIGHT)
    (root / "analysis" / "__main__.py").write_text(FAKE_ANALYSIS_ANY)
    proc = snakemake(root, "--cores", "2", *SMOKE, timeout=600)
    assert proc.returncode == 0, proc.output[-5000:]
    full = snakemake(root, "-n", "--cores", "2", *SMOKE, "--forceall")
    assert full.returncode == 0, full.output
    return root, job_counts(full.output)


def test_editing_an_analysis_file_reruns_the_analysis_jobs_and_nothing_else(ran_all):
    """With the code a digest param instead of 33 inputs per job (issue 29, item
    7) an edit of analysis/ still re-runs every job that runs the analysis,
    each once, and no simulation; an edit of sim/ the simulations and all after."""
    root, everything = ran_all
    assert dry_run(root, []) == {}
    with edited(root / "analysis" / "fields.py"):
        counts = dry_run(root, [])
    simulation = {*PILE_RULES, "pile_summary"}
    assert counts == {rule: n for rule, n in everything.items() if rule not in simulation}, counts
    assert {"analysis_fields", "analysis_moduli", "analysis_figure_moduli", "draw_pile",
            "film_pile", "export_pile", "run_times_table"} <= set(counts)
    with edited(root / "sim" / "kernels.py"):
        assert dry_run(root, []) == everything


def test_a_report_says_whether_its_results_are_out_of_date(ran_all):
    """The report's first paragraph, and the terminal, say when results are
    out of date by Snakemake's judgement: after an edit of analysis/ the jobs
    that a dry run would run, rule by rule; before it, that none would run.
    (A report of such a study once showed its old results without a word.)"""
    root, _ = ran_all
    report = root / "results" / "smoke" / "report.html"
    proc = snakemake(root, *SMOKE, "--report", str(report))
    assert proc.returncode == 0, proc.output[-5000:]
    assert "Up to date: Snakemake would remake none of these results" in report.read_text()
    assert "OUT OF DATE" not in report.read_text() + proc.output
    with edited(root / "analysis" / "fields.py"):
        counts = dry_run(root, [])
        proc = snakemake(root, *SMOKE, "--report", str(report))
    assert proc.returncode == 0, proc.output[-5000:]
    del counts["all"]
    jobs = (f"Snakemake would run {sum(counts.values())} jobs again ("
            + ", ".join(f"{n} {rule}" for rule, n in sorted(counts.items())) + ")")
    page = report.read_text()
    for text in (page, proc.output):
        assert "OUT OF DATE: " in text and "(code or settings changed since they were made)" in text
        assert jobs in text, text[-3000:]
        assert "run the workflow with the options of this report but without --report" in text


# --- (d) the smoke study, end to end ----------------------------------------

CONTRACT_VARIABLES = [
    "x", "y", "theta", "vx", "vy", "omega", "mass", "inertia", "area",
    "node_count", "node_x", "node_y", "contact_i", "contact_j", "contact_x",
    "contact_y", "force_x", "force_y", "normal_x", "normal_y", "overlap_area",
]


@pytest.mark.slow
def test_smoke_study_end_to_end(tmp_path):
    """config/smoke.yaml, all targets (piles, pictures, analysis), 2 cores.
    Needs the real simulator (python -m sim) and analysis."""
    import xarray as xr

    root = copy_workflow(tmp_path / "smoke")
    proc = snakemake(root, "--cores", "2", *SMOKE, "--show-failed-logs", timeout=3600)
    assert proc.returncode == 0, proc.output[-20000:]
    for protocol, seed in smoke_piles():
        for stage in ("poured", "relaxed", "reduced"):
            path = root / f"results/smoke/piles/{protocol}/seed{seed}/{stage}.nc"
            with xr.open_dataset(path) as ds:
                missing = [v for v in CONTRACT_VARIABLES if v not in ds.variables]
                assert not missing, (path, missing)
                assert ds.attrs["protocol"] == protocol and int(ds.attrs["seed"]) == seed
                assert 0 < ds.sizes["particle"] <= SMOKE_CONFIG["pour"]["n_particles"]
        assert not (root / f"results/smoke/piles/{protocol}/seed{seed}/pour.checkpoint.nc").exists()
        png = root / f"results/smoke/figures/piles/{protocol}_seed{seed}_relaxed.png"
        assert png.read_bytes()[:4] == b"\x89PNG"
        assert (root / f"results/smoke/benchmarks/pour/{protocol}/seed{seed}.tsv").exists()
        check_vtk_files(root / f"results/smoke/vtk/{protocol}_seed{seed}_relaxed.vtu",
                        root / f"results/smoke/piles/{protocol}/seed{seed}/relaxed.nc")
        check_film(root, protocol, seed)
    # A second run has nothing to do: no parameter or code trigger fires spuriously.
    again = snakemake(root, "-n", "--cores", "2", *SMOKE)
    assert again.returncode == 0 and job_counts(again.output) == {}, again.output
    check_report(root)
    check_stress_only_scene_gives_the_same_values(root)
    check_reproduction_from_recorded_piles(root)


def check_vtk_files(particles, state):
    """Output vtk of a smoke pile: meshio and VTK's own reader (ParaView's)
    load its polygons, one per particle, and its contacts with the fields a
    ParaView user colours by."""
    import meshio
    import vtk
    import xarray as xr

    with xr.open_dataset(state) as ds:
        n, n_contacts = ds.sizes["particle"], ds.sizes["contact"]
    contacts = particles.with_name(particles.stem + "_contacts.vtu")
    mesh = meshio.read(particles)
    assert sum(len(block.data) for block in mesh.cells) == n
    assert {"velocity", "pressure", "coordination", "area"} <= set(mesh.cell_data)
    for path, cells, fields in ((particles, n, ("pressure", "velocity", "coordination")),
                                (contacts, n_contacts, ("normal_force", "tangential_force", "force"))):
        reader = vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(path))
        reader.Update()
        grid = reader.GetOutput()
        assert grid.GetNumberOfCells() == cells, path
        assert all(grid.GetCellData().GetArray(name) is not None for name in fields), path


def check_film(root, protocol, seed):
    """Output film of a smoke pile: the pour's frames end on the poured state,
    and the MP4 holds one picture per frame (tests/test_analysis_film.py
    checks the frames and the film in detail)."""
    import imageio_ffmpeg
    import xarray as xr

    with xr.open_dataset(root / f"results/smoke/piles/{protocol}/seed{seed}/frames.nc") as frames, \
            xr.open_dataset(root / f"results/smoke/piles/{protocol}/seed{seed}/poured.nc") as poured:
        n_frames = frames.sizes["frame"]
        assert frames["released"].values[-1] == poured.sizes["particle"]
        assert frames["time"].values[-1] == poured.attrs["time"]
    # a frame every pour.frame_interval of a pour of n_particles / rate seconds, and more while it settles
    pour = SMOKE_CONFIG["pour"]
    assert n_frames >= pour["n_particles"] / 100.0 / pour["frame_interval"]
    counted, _ = imageio_ffmpeg.count_frames_and_secs(str(root / f"results/smoke/films/{protocol}_seed{seed}.mp4"))
    assert counted == n_frames
    assert "data:video/mp4;base64," in (root / f"results/smoke/films/{protocol}_seed{seed}.html").read_text()


# Every result of the report, decoded by the browser: images loaded (their
# width), films played up to their first frame (their width and length), and
# HTML pages without a film checked for a table.
REPORT_RESULTS_JS = """
const done = arguments[arguments.length - 1];
const out = {};
const checks = Object.entries(results).map(([path, r]) => new Promise(resolve => {
  const put = (value) => { out[path] = Object.assign({caption: r.caption || ""}, value); resolve(); };
  if (r.mime_type.startsWith("image/")) {
    const img = new Image();
    img.onload = () => put({kind: "image", width: img.naturalWidth});
    img.onerror = () => put({kind: "image", width: 0});
    img.src = r.data_uri;
  } else if (r.mime_type === "text/html") {
    fetch(r.data_uri).then(x => x.text()).then(text => {
      const film = text.match(/src="(data:video\\/mp4;base64,[^"]+)"/);
      if (!film) { put({kind: "html", table: text.includes("<table")}); return; }
      const video = document.createElement("video");
      video.muted = true;
      video.onloadeddata = () => put({kind: "film", width: video.videoWidth, seconds: video.duration});
      video.onerror = () => put({kind: "film", width: 0});
      video.src = film[1];
    });
  } else { put({kind: r.mime_type}); }
}));
Promise.all(checks).then(() => done(out));
"""


def check_report(root):
    """snakemake --report of the smoke study, opened in headless Chromium (make
    test installs it): the first page loads with the workflow's description
    and the result categories, and its screenshot is saved as
    results/smoke/report_first_page.png (here and in the repository's results/smoke/);
    every figure of the report decodes, every film plays, the run-time table
    is there, and the captions say with how many piles."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    report = root / "results" / "smoke" / "report.html"
    proc = snakemake(root, *SMOKE, "--report", str(report), timeout=600)
    assert proc.returncode == 0, proc.output[-5000:]
    chromium, driver_path = shutil.which("chromium"), shutil.which("chromedriver")
    assert chromium and driver_path, "make test installs chromium and chromium-driver (Debian)"
    profile = tempfile.TemporaryDirectory(prefix="chromium-profile-")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--window-size=1400,1000", f"--user-data-dir={profile.name}"):
        options.add_argument(flag)
    browser = webdriver.Chrome(service=Service(driver_path), options=options)
    try:
        browser.get(report.as_uri())
        categories = ("Analysis", "Films of the pours", "Piles", "Run times")
        WebDriverWait(browser, 120).until(
            lambda b: all(c in b.find_element(By.TAG_NAME, "body").text for c in categories))
        body = words(browser.find_element(By.TAG_NAME, "body").text)
        assert "discrete-element simulations of sand piles" in body
        # it names what it describes (the smoke's once said "Configuration: config/config.yaml")
        assert ("Configuration: config/smoke.yaml; results: results/smoke/, 4 of 4 piles of 150 "
                "particles made so far") in body, body[:2000]
        assert "Up to date: Snakemake would remake none of these results" in body
        shot = root / "results" / "smoke" / "report_first_page.png"
        assert browser.save_screenshot(str(shot))
        browser.set_script_timeout(120)
        found = browser.execute_async_script(REPORT_RESULTS_JS)
    finally:
        browser.quit()
        profile.cleanup()
    assert shot.read_bytes()[:4] == b"\x89PNG"
    if root != REPO:
        (REPO / "results" / "smoke").mkdir(parents=True, exist_ok=True)
        shutil.copy(shot, REPO / "results" / "smoke" / shot.name)
    piles = smoke_piles()
    films = {f"results/smoke/films/{p}_seed{s}.html" for p, s in piles}
    pictures = {f"results/smoke/figures/piles/{p}_seed{s}_relaxed.png" for p, s in piles}
    figures = {f"results/smoke/figures/{name}.png" for name in (
        "fig1_convergence", "fig2_vertical_strain", "fig3_fabric", "fig4_moduli", "fig5_invariants",
        "base_pressure")}
    assert set(found) == films | pictures | figures | {"results/smoke/run_times.html"}, sorted(found)
    for path in pictures | figures:
        assert found[path]["kind"] == "image" and found[path]["width"] > 500, (path, found[path])
    for path in films:
        assert found[path]["kind"] == "film" and found[path]["width"] == 1280, (path, found[path])
        assert found[path]["seconds"] > 1.0, (path, found[path])
        assert "the scene has 2 piles of this protocol" in words(found[path]["caption"])
    assert found["results/smoke/run_times.html"]["table"]
    for path in figures - {"results/smoke/figures/fig1_convergence.png"} | {"results/smoke/run_times.html"}:
        assert "2 wedge and 2 layered" in words(found[path]["caption"]), (path, found[path]["caption"])


def words(text):
    """`text` with every run of white space made one blank."""
    return " ".join(text.split())


def check_reproduction_from_recorded_piles(root):
    """Record every finished smoke pile (rule record_pile) with the extra
    probes' scene, as make reproduction reads them, delete the states and
    per-pile results, and rebuild the study from the records alone (make
    reproduction): no simulation runs, and the ensembles, fits, base pressure
    and general fit are those of the full run, bit for bit."""
    import xarray as xr

    scene = scene_args("elastic_probes")
    # the stress-only scene rewrote the fields without strain: the full study first
    proc = snakemake(root, "--cores", "2", *scene, "--show-failed-logs", timeout=600)
    assert proc.returncode == 0, proc.output[-20000:]
    records = [f"docs/reproduction/{p}/seed{s}.summary.json" for p, s in smoke_piles()]
    proc = snakemake(root, "--cores", "2", *scene, *records, "--show-failed-logs", timeout=600)
    assert proc.returncode == 0, proc.output[-20000:]
    assert all((root / f"docs/reproduction/{p}/seed{s}.probes.nc").exists() for p, s in smoke_piles())
    # convergence of every recorded pile, base pressure and summary per pile
    assert job_counts(proc.output)["record_pile"] == len(smoke_piles())
    full = root / "full_study"
    shutil.copytree(root / "results" / "smoke" / "ensemble", full)
    shutil.rmtree(root / "results")
    committed = ["--config", "committed=docs/reproduction",
                 "outputs=[fields,strain,fabric,fits,figures]"]
    proc = snakemake(root, "reproduction", "--cores", "2", *scene, *committed, "--show-failed-logs",
                     timeout=600)
    assert proc.returncode == 0, proc.output[-20000:]
    counts = job_counts(proc.output)
    assert not set(counts) & {*PILE_RULES, "analysis_fields", "analysis_base_pressure_pile",
                              "analysis_convergence", "analysis_probes", "draw_pile"}, counts
    docs = root / "docs" / "reproduction"
    assert {f.name for f in (docs / "figures").glob("*.png")} == {
        "fig1_convergence.png", "fig2_vertical_strain.png", "fig3_fabric.png", "fig4_moduli.png",
        "fig5_invariants.png", "base_pressure.png", "general_fit.png"}
    table = (docs / "piles.md").read_text()
    for p, s in smoke_piles():
        assert f"| {p} seed{s} |" in table
    numbers = (docs / "numbers.md").read_text()
    assert "## wedge (2 piles)" in numbers and "## layered (2 piles)" in numbers
    assert "## Extra probes, wedge" in numbers and "## Extra probes, layered" in numbers
    for p in ("wedge", "layered"):
        for name in ("fields.nc", "moduli.nc", "invariants.nc", "base_pressure.nc", "general_moduli.nc"):
            with xr.open_dataset(root / "results" / "smoke" / "ensemble" / p / name) as again, \
                    xr.open_dataset(full / p / name) as first:
                assert set(again.data_vars) == set(first.data_vars)
                for var in first.data_vars:
                    if first[var].dtype.kind in "fiu":
                        np.testing.assert_array_equal(again[var].values, first[var].values,
                                                      err_msg=f"{p}/{name}: {var}")


def check_stress_only_scene_gives_the_same_values(root):
    """The stress-only scene over the finished smoke study: it pours, relaxes and
    probes nothing again (same simulation settings), recomputes the fields with
    the stress only, and every variable it writes holds the values of the full
    study's, bit for bit."""
    import xarray as xr

    full = root / "full"
    for name in ("fields", "ensemble"):
        shutil.copytree(root / "results" / "smoke" / name, full / name)
    proc = snakemake(root, "--cores", "2", *scene_args("stress_only"), "--show-failed-logs",
                     timeout=600)
    assert proc.returncode == 0, proc.output[-20000:]
    n = len(smoke_piles())
    # each pile's run summary is made anew: it lists the scene's stages, and this scene has no probe
    assert job_counts(proc.output) == {"analysis_fields": n, "pile_summary": n, "analysis_ensemble": 2, "all": 1}
    files = [f"fields/{p}/seed{s}.nc" for p, s in smoke_piles()]
    files += [f"ensemble/{p}/fields.nc" for p in ("wedge", "layered")]
    for name in files:
        with xr.open_dataset(root / "results" / "smoke" / name) as part, \
                xr.open_dataset(full / name) as whole:
            assert "stress" in part and "stress_increment" not in part and "fabric" not in part
            assert set(part.data_vars) < set(whole.data_vars)
            for var in part.data_vars:
                np.testing.assert_array_equal(part[var].values, whole[var].values,
                                              err_msg=f"{name}: {var}")
