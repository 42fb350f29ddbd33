"""workflow/rules/analysis.smk and its schema, driven by a stand-in Snakefile.

The stand-in builds what common.smk provides to the analysis rules (the
``study`` of workflow/study.py, for two piles per protocol, every output and a
gravity probe), validates the analysis section against the schema, includes
the rules and asks for the analysis' targets. The dry run is fast; the full run is marked slow.
"""

import glob
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import yaml
from synthetic_states import displaced, step_pyramid, write_state

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SNAKEMAKE = os.path.join(os.path.dirname(sys.executable), "snakemake")


def _project(tmp_path, analysis_cfg=None):
    cfg = {"analysis": analysis_cfg if analysis_cfg is not None else
           {"grid": {"x_min": -0.12, "x_max": 0.12, "y_min": 0.03, "y_max": 0.09, "spacing": 0.03},
            "convergence": {"points": [[0.0, 0.04]], "sizes": [0.02, 0.05]}}}
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(cfg))
    (tmp_path / "Snakefile").write_text(textwrap.dedent(f"""
        import sys, glob
        from pathlib import Path
        from snakemake.utils import validate
        configfile: "config.yaml"
        validate(config["analysis"], "{REPO}/analysis/params.schema.yaml")
        config.update(committed=None, results="results", outputs=["fields", "strain", "fabric",
                      "fits", "figures"], protocols={{"wedge": {{"seeds": [1, 2]}}, "layered": {{"seeds": [1, 2]}}}},
                      probe={{"levels": [0.1], "tilts": [], "stretch": 0.0, "restore": False}})
        from workflow.study import Study
        study = Study(config, Path("{REPO}"), "{sys.executable}")
        wildcard_constraints:
            protocol="wedge|layered",
            seed=r"\\d+",
        include: "{REPO}/workflow/rules/analysis.smk"
        rule all:
            input: study.analysis.targets()
    """))
    for proto in ("wedge", "layered"):
        for seed in (1, 2):
            d = tmp_path / "results" / "piles" / proto / f"seed{seed}"
            d.mkdir(parents=True)
            s = step_pyramid(41 + 2 * seed, 0.006, slope=0.6)
            s["attrs"].update(protocol=proto, seed=seed)
            du = np.column_stack([2e-6 * s["x"] / 0.1, 2e-5 * s["y"] / 0.1])
            write_state(d / "relaxed.nc", s)
            write_state(d / "reduced.nc", displaced(s, du, 0.9, 0.9 * 9.81))
    return tmp_path


def _snakemake(path, *args, timeout=300):
    env = {**os.environ, "PYTHONPATH": REPO}
    return subprocess.run([SNAKEMAKE, "--cores", "2", "--directory", str(path), "--snakefile",
                           str(path / "Snakefile"), *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


def test_dry_run_schedules_every_analysis_target(tmp_path):
    p = _project(tmp_path)
    r = _snakemake(p, "-n", "--quiet", "rules")
    assert r.returncode == 0, r.stdout + r.stderr
    out = r.stdout + r.stderr
    for rule in ("analysis_fields", "analysis_ensemble", "analysis_moduli", "analysis_base_pressure",
                 "analysis_invariants", "analysis_convergence", "analysis_figure_vertical_strain",
                 "analysis_figure_base_pressure"):
        assert rule in out


def test_schema_rejects_bad_setting(tmp_path):
    p = _project(tmp_path, {"rve": {"shape": "hexagon"}})
    r = _snakemake(p, "-n")
    assert r.returncode != 0
    assert "hexagon" in r.stdout + r.stderr


@pytest.mark.slow
def test_full_run_produces_every_output(tmp_path):
    p = _project(tmp_path)
    r = _snakemake(p, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    for proto in ("wedge", "layered"):
        for name in ("fields.nc", "moduli.nc", "base_pressure.nc", "invariants.nc"):
            assert (p / "results" / "ensemble" / proto / name).exists()
        for seed in (1, 2):
            assert (p / "results" / "fields" / proto / f"seed{seed}.base_pressure.nc").exists()
    # Fig. 1 is drawn from every pile of analysis.figures.convergence_protocol
    for seed in (1, 2):
        assert (p / "results" / "fields" / "wedge" / f"seed{seed}.convergence.nc").exists()
    assert len(glob.glob(str(p / "results" / "figures" / "*.png"))) == 6
    assert len(glob.glob(str(p / "results" / "figures" / "*.pdf"))) == 6
    assert glob.glob(str(p / "results" / "benchmarks" / "analysis" / "fields" / "wedge" / "*.tsv"))
