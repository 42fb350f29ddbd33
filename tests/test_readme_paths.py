"""Every path of the study's or the smoke run's results that the README, or the
guide's "Reading the results" it sends readers to, names is made by
``make smoke``: the study's paths (``results/study/...``) taken under the
smoke run's folder, each must be a file, log or benchmark of a job of the
smoke configuration's dry run (wildcards such as ``{protocol}`` and ``*``
standing for one path part, a folder for any file in it), or the report the
Makefile's smoke target writes. (The README once sent readers to each pile's
``summary.json``, which neither ``make smoke`` nor ``make run`` made.) Paths
of ``results/reproduction/`` are ``make reproduction``'s and not checked here."""

import re
from pathlib import Path

import pytest

from test_workflow import SMOKE, copy_workflow, snakemake

REPO = Path(__file__).resolve().parents[1]
PATH = re.compile(r"results/(?:study|smoke)/[\w{}./*-]*")


def named_paths():
    """The results paths of the README and of the guide's "Reading the results",
    each taken under results/smoke/."""
    guide = (REPO / "docs" / "guide.md").read_text(encoding="utf-8")
    reading = re.search(r"^## Reading the results\n(.*?)(?=^## )", guide, re.S | re.M).group(1)
    text = (REPO / "README.md").read_text(encoding="utf-8") + reading
    return sorted({re.sub(r"^results/study/", "results/smoke/", p.rstrip(".")) for p in PATH.findall(text)})


def pattern(path):
    """A regular expression of the files `path` names: ``{x}`` and ``*`` one path
    part (or part of one), a folder any file below it."""
    parts = re.split(r"(\{\w+\}|\*)", path)
    regex = "".join("[^/]+" if part.startswith("{") or part == "*" else re.escape(part) for part in parts)
    return re.compile(regex + (".+" if path.endswith("/") else ""))


@pytest.fixture(scope="module")
def smoke_files(tmp_path_factory):
    """The outputs, logs and benchmarks of every job of the smoke run's dry run."""
    root = copy_workflow(tmp_path_factory.mktemp("readme_paths"))
    proc = snakemake(root, "-n", "--cores", "2", *SMOKE)
    assert proc.returncode == 0, proc.output
    files = set()
    for line in proc.output.splitlines():
        match = re.match(r"\s+(output|log|benchmark): (.+)$", line)
        if match:
            files.update(f.strip() for f in match.group(2).split(","))
    return files


def test_the_pattern_reads_wildcards_globs_and_folders():
    assert pattern("results/smoke/piles/{protocol}/seed{seed}/*.nc").fullmatch(
        "results/smoke/piles/wedge/seed2/relaxed.nc")
    assert not pattern("results/smoke/fields/{protocol}/seed{seed}.nc").fullmatch(
        "results/smoke/fields/wedge/seed2.summary.json")
    assert pattern("results/smoke/figures/").fullmatch("results/smoke/figures/piles/wedge_seed1_relaxed.png")


def test_every_results_path_the_readme_names_is_made_by_make_smoke(smoke_files):
    paths = named_paths()
    assert "results/smoke/fields/{protocol}/seed{seed}.summary.json" in paths
    makefile = (REPO / "Makefile").read_text()
    smoke_target = re.search(r"^smoke:.*?(?=^\S)", makefile, re.S | re.M).group(0)
    reports = set(re.findall(r"--report (\S+)", smoke_target))
    missing = [p for p in paths if p not in reports
               and not any(pattern(p).fullmatch(f) for f in smoke_files)]
    assert missing == [], f"named in the README or the guide, not made by make smoke: {missing}"
