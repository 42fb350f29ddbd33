"""config/scenes/six_constants.yaml in the workflow (dry runs, about 30 s):
over the smoke study it runs, per pile, the probes of elastic_probes.yaml
and the support stretch from the relaxed pile (stage stretched), and the
per-pile probe increments take it in; the gravity probes' jobs get no
stretch setting (so adding the stretch re-runs none of them) and the
stretch's job no gravity setting; a stretch without a frictional support
is refused before any job."""

import json
import re
import shlex

import pytest
import yaml
from test_workflow import copy_workflow, job_counts, smoke_piles, snakemake

SCENE = ["--configfile", "config/smoke.yaml", "config/scenes/six_constants.yaml", "--replace-workflow-config"]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return copy_workflow(tmp_path_factory.mktemp("six_constants"), with_sim=False)


def _probe_commands(output):
    """(stage, --params JSON, the command) of every `python -m sim probe` the dry run prints."""
    out = []
    for line in output.splitlines():
        if " -m sim probe " not in line:
            continue
        words = shlex.split(line.split(" -m sim probe ", 1)[1])
        stage = re.search(r"/([a-z0-9]+)\.nc$", words[words.index("--out") + 1]).group(1)
        out.append((stage, json.loads(words[words.index("--params") + 1]), words))
    return out


def test_the_scene_stretches_every_pile_besides_its_gravity_probes(workdir):
    proc = snakemake(workdir, "-n", "-p", "--cores", "2", *SCENE)
    assert proc.returncode == 0, proc.output
    n = len(smoke_piles())
    counts = job_counts(proc.output)
    assert counts["probe"] == 5 * n and counts["analysis_probes"] == n and counts["analysis_general_fit"] == 2
    commands = _probe_commands(proc.output)
    assert sorted(stage for stage, _, _ in commands) == sorted(
        ["reduced", "tiltp05", "tiltm05", "stretched", "restored"] * n)
    for stage, params, words in commands:
        if stage == "stretched":
            assert words[words.index("--stretch") + 1] == "0.0001"
            assert words[words.index("--input") + 1].endswith("/relaxed.nc")
            assert params["probe"] == {"stretch": 1e-4, "stretch_time": 0.1}
        else:
            assert "--stretch" not in words
            assert set(params["probe"]) == {"levels", "tilts", "restore", "mode", "ramp_time"}, stage
    assert re.search(r"--probes .*stretched=\S*/stretched\.nc", proc.output)


@pytest.mark.parametrize("override, message", [
    ({"model": {"support_friction": 0.0}}, "probe.stretch = 0.0001 with model.support_friction = 0"),
])
def test_a_stretch_without_a_frictional_support_stops_before_any_job(workdir, override, message):
    path = workdir / "config" / "no_support_friction.yaml"
    path.write_text(yaml.safe_dump(override))
    proc = snakemake(workdir, "-n", "--cores", "2", *SCENE[:3], str(path.relative_to(workdir)), SCENE[3])
    assert proc.returncode != 0 and message in proc.output, proc.output
