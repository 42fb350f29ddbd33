"""The run-time table of the report (python -m analysis run-times): from
Snakemake benchmark files of known times, each job's wall and CPU minutes,
cores used (CPU over wall) and peak memory, and the totals per kind of job;
and a real job's benchmark, whose CPU time a busy loop of known length
bounds."""

import math
import re
import subprocess
import sys

import pytest

from analysis.__main__ import main
from analysis.run_times import benchmark_row, job_label, run_times_html, stage_cpu_time

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def benchmark(path, wall, cpu, rss):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{wall}\t0:00:00\t{rss}\t0\t0\t0\t0\t0\t0\t{cpu}\n")
    return path


def cells(page, label):
    """The numbers of the table row whose first cell is `label`."""
    row = re.search(rf"<t[dh]>{re.escape(label)}</t[dh]>(.*?)</tr>", page).group(1)
    return [float(v) for v in re.findall(r"<td>([^<]+)</td>", row)]


def test_each_job_and_the_totals_per_kind(tmp_path):
    jobs = {
        "pour wedge seed1": benchmark(tmp_path / "benchmarks/pour/wedge/seed1.tsv", 600.0, 540.0, 250.0),
        "pour layered seed1": benchmark(tmp_path / "benchmarks/pour/layered/seed1.tsv", 1200.0, 600.0, 260.0),
        "relax wedge seed1": benchmark(tmp_path / "benchmarks/relax/wedge/seed1.tsv", 60.0, 57.0, 240.0),
    }
    assert {job_label(p) for p in jobs.values()} == set(jobs)
    page = run_times_html({label: str(p) for label, p in jobs.items()}, "smoke")
    assert cells(page, "pour wedge seed1") == [10.0, 9.0, 0.9, 250.0]
    assert cells(page, "pour layered seed1") == [20.0, 10.0, 0.5, 260.0]
    # totals: sums of the times, cores = total CPU / total wall, the largest memory
    assert cells(page, "pour: 2 jobs") == [30.0, 19.0, pytest.approx(1140 / 1800, abs=0.005), 260.0]
    assert cells(page, "relax: 1 jobs") == [1.0, 0.95, 0.95, 240.0]


def test_a_job_without_cpu_time_reads_as_unknown(tmp_path):
    path = tmp_path / "benchmarks/probe/wedge/seed1_reduced.tsv"
    path.parent.mkdir(parents=True)
    path.write_text(HEADER + "30.0\t0:00:30\t200\t0\t0\t0\t0\t0\t0\tNA\n")
    row = benchmark_row(path)
    assert row["wall_s"] == 30.0 and row["cpu_s"] != row["cpu_s"] and row["cores"] != row["cores"]


def test_a_real_job_measured_by_snakemake_benchmark(tmp_path):
    """A one-rule workflow that burns 2 s of CPU: its benchmark,
    read through the table, has a CPU time of the busy loop's order and
    cores used at most one (one thread)."""
    (tmp_path / "busy.py").write_text(
        "import time\nt = time.process_time()\nwhile time.process_time() - t < 2.0:\n    pass\n")
    (tmp_path / "Snakefile").write_text(
        "rule busy:\n"
        "    output: 'done'\n"
        "    benchmark: 'benchmarks/busy/wedge/seed1.tsv'\n"
        f"    shell: '{sys.executable} busy.py && touch {{output}}'\n")
    snakemake = [sys.executable, "-m", "snakemake", "--cores", "1", "--quiet"]
    subprocess.run(snakemake, cwd=tmp_path, check=True, capture_output=True, timeout=300)
    out = tmp_path / "table.html"
    assert main(["run-times", "--benchmarks", str(tmp_path / "benchmarks/busy/wedge/seed1.tsv"),
                 "--out", str(out)]) == 0
    wall, cpu_min, cores, _ = cells(out.read_text(), "busy wedge seed1")
    assert 1.0 / 60 <= cpu_min <= 30 / 60
    assert cores <= 1.05


def test_a_missing_benchmark_file_is_named(tmp_path, capsys):
    assert main(["run-times", "--benchmarks", str(tmp_path / "nope.tsv"), "--out",
                 str(tmp_path / "t.html")]) == 1
    assert "nope.tsv: no such benchmark file" in capsys.readouterr().err
    assert not (tmp_path / "t.html").exists()


@pytest.mark.parametrize("text", ["any text\nat all\n", "", HEADER])
def test_a_file_that_is_no_benchmark_is_refused_by_name_and_nothing_is_written(tmp_path, capsys, text):
    path = tmp_path / "any.txt"
    path.write_text(text)
    out = tmp_path / "table.html"
    assert main(["run-times", "--benchmarks", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert str(path) in err and "'s'" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_stage_cpu_is_its_last_summary_line_or_nan(tmp_path):
    """A log holding two runs of a stage (a pour that failed once is rerun into the same
    log) gives the last summary line's CPU; a log without one (a failed stage) NaN."""
    log = tmp_path / "seed3.log"
    done = ("2026-12-08 01:44:48,701 INFO pour layered seed 3 done: wall 639.8 s, 1323016 steps, "
            "3500 particles, t = 8.9554 s, angle of repose 27.6 deg, mean coordination 3.75; "
            "CPU {} s in this process")
    log.write_text("\n".join([done.format("12.5"), "a progress line", done.format("418.9"),
                              "2026-12-08 INFO frames: 3 written"]) + "\n")
    assert stage_cpu_time(log) == 418.9
    log.write_text("2026-12-08 ERROR pour layered seed 3: still in flight\n")
    assert math.isnan(stage_cpu_time(log))
