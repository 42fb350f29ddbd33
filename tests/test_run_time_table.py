"""The table of measured run times (workflow/run_times.json) and the pages
written from it: docs/run_times.md and the README's times are what
``python -m workflow.tools run_times`` makes of it; each row names its command,
host, date and commit or says they were not recorded, and the rows taken from
committed records hold those records' numbers; the README's estimate of
``make run`` is the line ``make progress`` prints on a fresh clone."""

import csv
import glob
import json
import re
from pathlib import Path

import pytest

from workflow.tools import run_times as rt
from workflow.tools import study_progress as sp

REPO = Path(__file__).resolve().parents[1]
TABLE = json.loads((REPO / "workflow" / "run_times.json").read_text(encoding="utf-8"))
FIELDS = ("id", "what", "command", "wall_s", "cpu_s", "host", "date", "commit", "source")


def test_the_page_and_the_readme_are_written_from_the_table():
    assert rt.main(["--check"]) == 0, "run python -m workflow.tools run_times"


def test_every_row_says_how_where_when_and_at_which_commit():
    for row in TABLE["rows"]:
        assert set(FIELDS) <= set(row), row["id"]
        assert row["command"], row["id"]
        measured = row["wall_s"] is not None or row["cpu_s"] is not None
        assert measured == (row["host"] is not None), row["id"]  # no host without a time, nor a time without
        if row["date"] is not None:
            assert re.fullmatch(r"\d{4}-\d\d-\d\d( to \d{4}-\d\d-\d\d)?", row["date"]), row["id"]
        if row["commit"] is not None:
            assert re.fullmatch(r"[0-9a-f]{7}", row["commit"]), row["id"]
    assert len({row["id"] for row in TABLE["rows"]}) == len(TABLE["rows"])


def test_the_rows_from_committed_records_hold_their_numbers():
    """The means of the calibration and decision records, the study's pours from
    their benchmarks, the measured pour from its performance file."""
    rows = {row["id"]: row for row in TABLE["rows"]}
    for row in rows.values():
        spec = row.get("records")
        if spec is None:
            continue
        records = [json.loads(Path(f).read_text()) for f in sorted(glob.glob(str(REPO / spec["folder"] / "*.json")))]
        chosen = [r["cpu_s"] for r in records if r["arm"] == spec["arm"] and r["commit"] == spec["commit"]]
        assert f"mean of {len(chosen)} seeds" in row["what"]
        assert row["cpu_s"] == pytest.approx(sum(c["total"] for c in chosen) / len(chosen), abs=0.05)
        assert row["pour_cpu_s"] == pytest.approx(sum(c["pour"] for c in chosen) / len(chosen), abs=0.05)

    # rows from a pour-budget page: the arm's column of its total CPU per pile
    for row in rows.values():
        spec = row.get("budget")
        if spec is None:
            continue
        lines = (REPO / spec["page"]).read_text(encoding="utf-8").splitlines()
        header = next(line for line in lines if line.startswith("| per pile |")).split(" | ")
        column = next(i for i, cell in enumerate(header) if cell.startswith(spec["arm"] + " ("))
        total = next(line for line in lines if line.startswith("| CPU s with the tail") and "total" in line)
        assert float(total.split(" | ")[column].split()[0]) == row["cpu_s"], row["id"]
        piles = int(header[column].split("(")[1].split()[0])
        assert f"of {piles} seeds" in row["what"], row["id"]

    def benchmark(path):
        with open(path, newline="") as f:
            return next(csv.DictReader(f, delimiter="\t"))

    pours = [benchmark(p) for p in sorted(glob.glob(str(REPO / "docs/reproduction/*/seed*.pour.tsv")))]
    assert len(pours) == 19
    assert rows["run-pours"]["cpu_s"] == pytest.approx(sum(float(p["cpu_time"]) for p in pours), abs=0.01)
    seed5 = benchmark(REPO / "docs/reproduction/layered/seed5.pour.tsv")
    assert (rows["pour-3500-layered"]["wall_s"], rows["pour-3500-layered"]["cpu_s"]) == \
        (float(seed5["s"]), float(seed5["cpu_time"]))
    measured = json.loads((REPO / rows["pour-3500-wedge"]["source"]).read_text())
    pour = next(p for p in measured["pours"] if p["code"].startswith(rows["pour-3500-wedge"]["commit"]))
    assert (rows["pour-3500-wedge"]["cpu_s"], rows["pour-3500-wedge"]["wall_s"], rows["pour-3500-wedge"]["steps"]) \
        == (pour["cpu_s"], pour["wall_s"], pour["steps"])


def test_the_readme_estimate_is_what_make_progress_says_on_a_fresh_clone(tmp_path):
    """`make progress` with no pile made: the same wall time and CPU per pile as
    the README's row of make run, priced by the same measured pour."""
    from sim.durations import hms
    from workflow.validation import load_config

    estimate = rt.run_estimate()
    line = sp.progress_line(tmp_path, load_config([REPO / "config" / "config.yaml"]), rt.CORES, 0.0)
    assert f"about {hms(estimate['wall_s'])} left at 2 jobs" in line
    assert f"{hms(estimate['cpu_per_pile_s'])} of CPU per pile" in line
    basis = next(row for row in TABLE["rows"] if row["id"] == TABLE["cost_model"])
    assert f"({basis['id']}: {basis['commit']}, {basis['host']}, {basis['date']};" in line
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert f"| `make run` | about {hms(estimate['wall_s'])}, an estimate" in readme
    assert f"commit {basis['commit']} |" in readme


def test_a_readme_without_the_markers_is_refused():
    with pytest.raises(ValueError, match="no table of run times"):
        rt.with_block("# a README\n", "table")


def test_the_study_from_measured_piles_prices_each_protocols_piles_by_its_pile():
    """The study's configuration has 9 wedge and 10 layered seeds; each pile costs its
    protocol's measured pile, two piles at a time on 2 cores."""
    import yaml

    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    counts = {p: len(v["seeds"]) for p, v in config["protocols"].items()}
    table = {"rows": [{**row, "cpu_s": 100.0 if row["id"] == rt.MEASURED_STUDY["wedge"] else row["cpu_s"]}
                      for row in TABLE["rows"]]}
    table["rows"] = [{**row, "cpu_s": 7.0} if row["id"] == rt.MEASURED_STUDY["layered"] else row
                     for row in table["rows"]]
    out = rt.measured_study(table)
    assert out["counts"] == counts == {"wedge": 9, "layered": 10}
    assert out["cpu_s"] == 9 * 100.0 + 10 * 7.0 and out["wall_s"] == out["cpu_s"] / 2
