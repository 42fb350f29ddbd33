"""Every tool of ``python -m workflow.tools`` refuses a bad argument or file in one line (issue 59, item 6).

Each tool runs here with bad arguments (:data:`BAD`, one list per tool: a tool
added without them fails :func:`test_every_tool_has_bad_arguments_here`) and
must answer with status 2 and one line on stderr that names the tool and the
argument or file, no traceback and nothing on stdout; ``--help`` of every tool
prints its usage. The committed pages and plan stay as they were."""

import json
import shutil
import sys
from pathlib import Path

import pytest

from workflow.tools import TOOLS
from workflow.tools.__main__ import main
from workflow.tools.source_growth import frames_stem

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "reproduction"
CALIBRATION = DOCS / "calibration"
COMMITTED = [REPO / "config" / "decision.yaml", *sorted(DOCS.glob("*.md"))]

#: Per tool, bad command lines and a word each refusal must hold (the argument or file it names).
#: ``<tmp>``: an empty folder; ``<bad_json>``: a truncated JSON record; ``<listed_json>``: a JSON list;
#: ``<bad_state>``: a truncated state file; ``<page>``: a page without the settings tables' markers;
#: ``<calibration>``: the calibration records with one copied under another seed's name.
BAD = {
    "calibration": [(["--jobs", "0"], "--jobs"),
                    (["--config", str(REPO / "config" / "smoke.yaml")], "smoke.yaml"),
                    (["--arms", "wedge"], "--arms"),
                    (["--seeds", "-1"], "--seeds"),
                    (["--table", "--out", "/nonexistent/x.md"], "--out"),
                    (["--table", "--records", "<tmp>"], "--records"),
                    (["--table", "--records", "<tmp>/no"], "--records"),
                    (["--table", "--records", "<calibration>"], "wedge_drip-seed207.json")],
    "decision": [(["verdict", "--records", "<tmp>"], "--records"),
                 (["verdict", "--out", "/nonexistent/x.md"], "--out"),
                 (["verdict", "--plan", "<tmp>/plan.yaml"], "plan.yaml"),
                 (["select"], "--plan"),
                 (["verdict", "--records", "<calibration>"], "wedge_drip-seed207.json")],
    "growing_pile_shapes": [(["<bad_state>"], "bad.nc"), (["<tmp>/no.nc"], "no.nc")],
    "piles_table": [(["<bad_json>"], "bad.summary.json"), (["<listed_json>"], "listed.summary.json"),
                    (["<tmp>/no.summary.json"], "no.summary.json")],
    "pour_budget": [(["<tmp>/no", "--records", "<tmp>"], "FOLDER"), (["<tmp>"], "--records"),
                    (["<tmp>", "--records", "<tmp>/no"], "--records"), (["<tmp>", "--records", "<tmp>"], "FOLDER"),
                    (["<tmp>", "--records", "<tmp>", "--out", "/nonexistent/x.md"], "--out")],
    "probe_levels": [(["--piles", str(REPO / "config" / "sweep_piles.yaml")], "--step"),
                     (["--piles", str(REPO / "config" / "calibration.yaml"), "--step", "<tmp>"], "calibration.yaml"),
                     (["--piles", str(REPO / "config" / "sweep_piles.yaml"), "--step", "<tmp>"], "--step"),
                     (["--piles", str(REPO / "config" / "sweep_piles.yaml"), "--ramp", "<tmp>/no"], "--ramp")],
    "reproduction_numbers": [
        (["--ensemble", "<tmp>", "--protocols", "wedge", "--convergence", "<bad_json>", "--checks", "<bad_json>",
          "--heights", "0.045"], "--ensemble"),
        (["--ensemble", "<tmp>", "--protocols", "wedge", "--convergence", "<bad_json>", "--checks", "<bad_json>",
          "--heights", "nan"], "--heights"),
        (["--ensemble", "<tmp>", "--protocols", "wedge", "--convergence", "<bad_json>", "--checks", "<bad_json>",
          "--heights", "0.045", "--fields", "wedge"], "--fields"),
        (["--ensemble", "<tmp>", "--protocols", "wedge", "--convergence", "<bad_json>", "--checks", "<bad_json>",
          "--heights", "0.045", "--params", "{rve: {size: -1}}"], "--params")],
    "run_times": [(["--check", "stale"], "stale"), (["--write"], "--write")],
    "setting_sweep": [(["--setting", "pour.rate", "--values", "50", "--name", "../.."], "--name"),
                      (["--setting", "pour.rate", "--values", "-5", "--name", "x"], "-5"),
                      (["--setting", "pour.rate", "--values", "5", "--name", "x", "--cores", "0"], "--cores"),
                      (["--setting", "pour.rate", "--name", "x"], "--values"),
                      (["--setting", "pour.rate", "--name", "no_such_sweep", "--keep-recorded"], "no_such_sweep.json")],
    "settings_table": [(["--check", "<tmp>/no.md"], "--check"), (["--check", "<page>"], "page.md"),
                       (["--write", "<page>", "--check", "<page>"], "--check")],
    "six_constants_table": [(["--variant", "<tmp>/no", "--study", str(DOCS)], "--variant"),
                            (["--variant", "<tmp>", "--study", str(DOCS)], "--variant"),
                            (["--variant", "<tmp>", "--study", str(DOCS), "--points", "3"], "--points")],
    "source_growth": [(["--out", "<tmp>", "--sources", "nosuch"], "--sources"),
                      (["--out", "<tmp>", "--n", "0"], "--n"),
                      (["--out", "<tmp>", "--frame", "nan"], "--frame"),
                      (["--out", "<tmp>", "--from", "1.5"], "--from"),
                      (["--out", "<tmp>", "--pour", "outlet_width"], "--pour"),
                      (["--out", "<tmp>", "--pour", "outlet_width=-1"], "outlet_width"),
                      (["--out", "<bad_json>"], "--out")],
    "step_error": [(["--records", "<tmp>"], "--records"), (["--records", "<tmp>/no"], "--records"),
                   (["--plan", "<tmp>/no.yaml"], "no.yaml"), (["--out", "/nonexistent/x.md"], "--out"),
                   (["--plan", str(REPO / "config" / "calibration.yaml")], "calibration.yaml"),
                   (["--records", "<calibration>"], "wedge_drip-seed207.json")],
    "study_progress": [(["--every", "-5"], "--every"), (["--every", "nan"], "--every"),
                       (["--cores", "0"], "--cores"), (["--directory", "<tmp>/no"], "--directory"),
                       (["--configfile", str(REPO / "config" / "calibration.yaml")], "piles")],
    "variant_table": [(["--study", str(DOCS), "--variant", "<tmp>/no", "--overlay", "<page>"], "--variant"),
                      (["--study", str(DOCS), "--variant", "<tmp>", "--overlay", "<tmp>/no.yaml"], "--overlay"),
                      (["--study", str(DOCS), "--variant", "<tmp>", "--overlay", "<page>", "--params", "{nosuch: 1}"],
                       "--params")],
}
CASES = [(tool, argv, word) for tool in TOOLS for argv, word in BAD.get(tool, [])]


@pytest.fixture(autouse=True)
def committed_untouched():
    """No run here changes the committed pages or the plan."""
    before = {p: p.read_bytes() for p in COMMITTED}
    yield
    assert {p: p.read_bytes() for p in COMMITTED} == before


@pytest.fixture
def files(tmp_path):
    """The folders and broken files the bad command lines name."""
    empty = tmp_path / "empty"
    empty.mkdir()
    (tmp_path / "bad.summary.json").write_text('{"stage": "relaxed", "height"')
    (tmp_path / "listed.summary.json").write_text("[1, 2, 3]\n")
    (tmp_path / "bad.nc").write_bytes((REPO / "tests" / "data" / "stretch_heap.nc").read_bytes()[:20000])
    (tmp_path / "page.md").write_text("# A page without the settings tables\n")
    calibration = tmp_path / "calibration"
    shutil.copytree(CALIBRATION, calibration)
    record = json.loads((calibration / "wedge_drip-seed206.json").read_text())
    (calibration / "wedge_drip-seed207.json").write_text(json.dumps({**record, "seed": 207}))
    return {"tmp": empty, "bad_json": tmp_path / "bad.summary.json", "listed_json": tmp_path / "listed.summary.json",
            "bad_state": tmp_path / "bad.nc", "page": tmp_path / "page.md", "calibration": calibration}


def run(capsys, monkeypatch, argv):
    """``python -m workflow.tools ARGV`` in this process: its status, stdout and stderr."""
    monkeypatch.setattr(sys, "argv", list(sys.argv))
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize("tool", TOOLS)
def test_every_tool_has_bad_arguments_here(tool):
    assert BAD.get(tool), f"{tool}: a new tool; give it bad command lines in BAD"


@pytest.mark.parametrize("tool, argv, word", CASES, ids=[f"{t}:{' '.join(a)}" for t, a, _ in CASES])
def test_a_bad_argument_is_refused_in_one_line(tool, argv, word, files, capsys, monkeypatch):
    for name, path in files.items():
        argv = [a.replace(f"<{name}>", str(path)) for a in argv]
    status, out, err = run(capsys, monkeypatch, [tool, *argv])
    assert status == 2 and out == "", (out, err)
    assert err.startswith(f"python -m workflow.tools {tool}: ") and err.count("\n") == 1, err
    assert word in err, err


@pytest.mark.parametrize("tool", TOOLS)
def test_an_unknown_option_is_refused_in_one_line(tool, capsys, monkeypatch):
    """Refused by name, or, where the tool needs arguments, by the arguments it still needs."""
    status, out, err = run(capsys, monkeypatch, [tool, "--no-such-option"])
    assert status == 2 and out == "" and err.count("\n") == 1, err
    assert "unrecognized arguments: --no-such-option" in err or " required" in err, err


@pytest.mark.parametrize("tool", TOOLS)
def test_every_tool_prints_its_usage(tool, capsys, monkeypatch):
    with pytest.raises(SystemExit) as done:
        run(capsys, monkeypatch, [tool, "--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("usage: ")


def test_the_calibration_table_counts_the_values_it_leaves_out(tmp_path, capsys, monkeypatch):
    """A pile whose value is not a number (NaN) is left out of the mean, and the cell says so."""
    folder = tmp_path / "calibration"
    shutil.copytree(CALIBRATION, folder)
    record = json.loads((folder / "wedge_drip-seed203.json").read_text())
    record["quantities"]["youngs_modulus"] = float("nan")
    (folder / "wedge_drip-seed203.json").write_text(json.dumps(record))
    status, out, _ = run(capsys, monkeypatch, ["calibration", "--table", "--records", str(folder)])
    assert status == 0
    row = next(line for line in out.splitlines() if line.startswith("| core E (N/m)"))
    assert row.split(" | ")[1].endswith("(5 of 6 piles)") and "of 6 piles" not in row.split(" | ", 2)[2]


def test_a_source_growth_pour_is_reused_only_at_the_same_size_and_frames(tmp_path):
    """The pours it keeps are named by their particles and frame interval too: a rerun at another
    --n or --frame pours anew instead of reading frames of other settings."""
    stems = {frames_stem(tmp_path, "wedge funnel", ["outlet_width=3"], n, frame, 1)
             for n in (300, 600) for frame in (0.02, 0.05)}
    assert len(stems) == 4
    assert frames_stem(tmp_path, "wedge funnel", [], 300, 0.02, 1) == tmp_path / "wedge_funnel_n300_frame0.02_1"
