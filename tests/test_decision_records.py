"""The registered decision cannot be bent by its files (issue 59, item 1).

``python -m workflow.tools decision verdict`` and ``decision select`` run here on
copies of the committed records (docs/reproduction/decision/, .../calibration/)
in temporary folders, one record tampered with at a time: each tampered
ensemble is refused in one line naming the record, and no run without
``--out`` touches a committed page or the registered plan."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from workflow.tools.__main__ import main

REPO = Path(__file__).resolve().parents[1]
DECISION = REPO / "docs" / "reproduction" / "decision"
CALIBRATION = REPO / "docs" / "reproduction" / "calibration"
PLAN = REPO / "config" / "decision.yaml"
#: What no tool run without --out may change.
COMMITTED = [PLAN, *sorted((REPO / "docs" / "reproduction").glob("*.md"))]


def run(capsys, monkeypatch, *argv):
    """Run ``python -m workflow.tools ARGV`` here; its status, stdout and stderr."""
    monkeypatch.setattr(sys, "argv", list(sys.argv))   # the tool's runner names itself in sys.argv
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(autouse=True)
def committed_untouched():
    """Every test here leaves the committed pages and the plan as they were."""
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in COMMITTED}
    yield
    assert {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in COMMITTED} == before


@pytest.fixture
def records(tmp_path):
    """A copy of the decision's records."""
    folder = tmp_path / "decision"
    shutil.copytree(DECISION, folder)
    return folder


def edit(folder, name, new_name=None, **fields):
    """Change fields of the record `name` (``quantities`` merged), moving it to `new_name` if given."""
    path = folder / name
    record = json.loads(path.read_text())
    record["quantities"].update(fields.pop("quantities", {}))
    record.update(fields)
    path.unlink()
    (folder / (new_name or name)).write_text(json.dumps(record))


def assert_refused(status, out, err, name, words):
    """A refusal: status 2, nothing printed but one line naming the record `name` and saying `words`."""
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and name in err and words in err, err


def test_the_committed_records_give_the_committed_verdict(records, capsys, monkeypatch):
    status, out, _ = run(capsys, monkeypatch, "decision", "verdict", "--records", str(records))
    assert status == 0
    assert out.replace(f"from {records}/", "from docs/reproduction/decision/") == \
        (REPO / "docs" / "reproduction" / "decision.md").read_text()


def test_a_copy_under_another_seeds_name_is_refused(records, capsys, monkeypatch):
    copy = json.loads((records / "wedge_funnel-seed1026.json").read_text())
    (records / "wedge_funnel-seed1027.json").write_text(json.dumps({**copy, "seed": 1027}))
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "wedge_funnel-seed1027.json", "has the numbers of wedge_funnel-seed1026.json")


def test_a_seed_twice_is_refused(records, capsys, monkeypatch):
    edit(records, "layered_rain-seed1027.json", "layered_rain-seed1027b.json", seed=1026,
         quantities={"stress_column": -0.2})
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "layered_rain-seed1027b.json", "arm 'layered rain' seed 1026 again")


def test_a_seed_below_the_registered_ones_is_refused(records, capsys, monkeypatch):
    edit(records, "wedge_funnel-seed1027.json", "wedge_funnel-seed5.json", seed=5)
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "wedge_funnel-seed5.json", "seed 5;")


def test_a_28th_pile_is_refused(records, capsys, monkeypatch):
    """A pile past the registered 27, with numbers of its own (it would move D1 from -5.3 % to -7.3 %)."""
    record = json.loads((records / "wedge_funnel-seed1027.json").read_text())
    record["seed"] = 1028
    record["quantities"]["stress_column"] -= 0.5
    (records / "wedge_funnel-seed1028.json").write_text(json.dumps(record))
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "wedge_funnel-seed1028.json", "registers seeds 1001-1027")


def test_a_replacement_seed_stands_for_a_missing_pile(records, capsys, monkeypatch):
    """The registration's rule: a missing pile (D1 undefined) is replaced by the next seed."""
    record = json.loads((records / "wedge_funnel-seed1005.json").read_text())
    (records / "wedge_funnel-seed1028.json").write_text(json.dumps({**record, "seed": 1028}))
    edit(records, "wedge_funnel-seed1005.json", quantities={"stress_column": float("nan")})
    status, out, err = run(capsys, monkeypatch, "decision", "verdict", "--records", str(records))
    assert status == 0, err
    assert "missing: wedge funnel seed 1005." in out


@pytest.mark.parametrize("fields, words", [
    ({"protocol": "layered"}, "protocol 'layered' with settings"),
    ({"settings": {"pour": {"point_source": "drip"}}}, "is not arm 'wedge funnel'"),
    ({"arm": "wedge drip"}, "arm 'wedge drip' is not registered"),
    ({"n_particles": 100}, "100 particles; "),
])
def test_a_pile_of_another_arm_or_size_is_refused(records, capsys, monkeypatch, fields, words):
    edit(records, "wedge_funnel-seed1013.json", **fields)
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "wedge_funnel-seed1013.json", words)


def test_a_pile_poured_before_the_registration_is_refused(records, capsys, monkeypatch):
    registered = subprocess.run(["git", "-C", str(REPO), "log", "--diff-filter=A", "--format=%H", "--", str(PLAN)],
                                capture_output=True, text=True, check=True).stdout.split()[-1]
    before = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", f"{registered}^"],
                            capture_output=True, text=True, check=True).stdout.strip()
    edit(records, "layered_rain-seed1002.json", commit=before)
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "layered_rain-seed1002.json", f"commit '{before}', before the registration")
    edit(records, "layered_rain-seed1002.json", commit="0000000")
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "layered_rain-seed1002.json", "'0000000', unknown to git")


@pytest.mark.parametrize("text, words", [
    ('{"arm": "wedge funnel", "seed": 10', "not readable as JSON"),
    ("[1, 2]", "a JSON list"),
    ('{"arm": "wedge funnel"}', "protocol = None; allowed is a str"),
])
def test_a_record_that_is_no_record_is_refused(records, capsys, monkeypatch, text, words):
    (records / "wedge_funnel-seed1009.json").write_text(text)
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(records)),
                   "wedge_funnel-seed1009.json", words)


def test_an_empty_or_missing_folder_is_refused(tmp_path, capsys, monkeypatch):
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(tmp_path)),
                   str(tmp_path), "no record (*.json) in it")
    assert_refused(*run(capsys, monkeypatch, "decision", "verdict", "--records", str(tmp_path / "no")),
                   str(tmp_path / "no"), "no such folder")


def test_a_partial_ensemble_is_printed_not_written(records, capsys, monkeypatch, tmp_path):
    for path in sorted(records.glob("*.json"))[3:]:
        path.unlink()
    status, out, _ = run(capsys, monkeypatch, "decision", "verdict", "--records", str(records))
    assert status == 0 and "**No verdict yet**" in out
    page = tmp_path / "page.md"
    status, again, _ = run(capsys, monkeypatch, "decision", "verdict", "--records", str(records), "--out", str(page))
    assert status == 0 and page.read_text() == again == out


def test_select_never_rewrites_a_plan(capsys, monkeypatch):
    assert_refused(*run(capsys, monkeypatch, "decision", "select"),
                   "config/decision.yaml", "exists; a registered plan is never rewritten")


def test_select_writes_a_new_plan_and_no_page(tmp_path, capsys, monkeypatch):
    plan = tmp_path / "decision_new.yaml"
    status, out, _ = run(capsys, monkeypatch, "decision", "select", "--plan", str(plan))
    assert status == 0 and "registered N = **27** per protocol" in out
    new, old = (p.read_text().split("\n", 2)[2] for p in (plan, PLAN))
    assert new == old   # the rules, applied again to the same records, chose the same plan


def test_select_refuses_records_that_are_not_the_calibrations(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "calibration"
    shutil.copytree(CALIBRATION, folder)
    plan = tmp_path / "decision_new.yaml"
    edit(folder, "layered_top-seed206.json", "layered_top-seed1036.json", seed=1036)
    assert_refused(*run(capsys, monkeypatch, "decision", "select", "--records", str(folder), "--plan", str(plan)),
                   "layered_top-seed1036.json", "registers seeds 201-206")
    edit(folder, "layered_top-seed1036.json", "layered_flat-seed206.json", seed=206, arm="layered flat")
    assert_refused(*run(capsys, monkeypatch, "decision", "select", "--records", str(folder), "--plan", str(plan)),
                   "layered_flat-seed206.json", "arm 'layered flat' is not registered")
    assert not plan.exists()


def test_select_without_a_layered_control_writes_no_plan(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "calibration"
    shutil.copytree(CALIBRATION, folder)
    for path in folder.glob("layered_rain-*.json"):
        record = json.loads(path.read_text())
        record["growth"]["flank_p90_deg"] = 40.0
        path.write_text(json.dumps(record))
    plan = tmp_path / "decision_new.yaml"
    status, out, _ = run(capsys, monkeypatch, "decision", "select", "--records", str(folder), "--plan", str(plan))
    assert status == 0 and "No layered control" in out
    assert not plan.exists()
