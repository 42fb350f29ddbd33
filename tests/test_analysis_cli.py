"""Command line: help, clear errors for bad parameters and bad state files, the fields/checks outputs."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from synthetic_states import displaced, step_pyramid, to_dataset, write_state

from analysis.__main__ import main

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMALL = json.dumps({"grid": {"x_min": -0.1, "x_max": 0.1, "y_min": 0.03, "y_max": 0.09, "spacing": 0.03}})


@pytest.fixture()
def states(tmp_path):
    s = step_pyramid(41, 0.006, slope=0.6)
    du = np.column_stack([1e-6 * s["x"], 2e-5 * s["y"]])
    r = displaced(s, du, 0.9, 0.9 * 9.81)
    return write_state(tmp_path / "relaxed.nc", s), write_state(tmp_path / "reduced.nc", r), s, r


def test_help_lists_commands():
    r = subprocess.run([sys.executable, "-m", "analysis", "--help"], capture_output=True, text=True, cwd=REPO)
    assert r.returncode == 0
    for cmd in ("fields", "ensemble", "moduli", "base-pressure", "invariants", "convergence", "figure"):
        assert cmd in r.stdout


@pytest.mark.parametrize("params,words", [
    ('{"rve": {"shape": "hexagon"}}', ["analysis.rve.shape", "'hexagon'", "'square'", "'circle'"]),
    ('{"rve": {"size": -1}}', ["analysis.rve.size", "-1", "> 0"]),
    ('{"rve": {"sise": 0.1}}', ["analysis.rve.sise", "allowed keys", "size"]),
    ('{"strain": {"min_contacts": 2.5}}', ["analysis.strain.min_contacts", "integer"]),
    ('{"grid": {"x_min": 1, "x_max": 0}}', ["analysis.grid.x_min", "x_max"]),
    ("{not json", ["--params", "JSON"]),
])
def test_bad_params_give_a_clear_error_before_reading_inputs(params, words, capsys):
    rc = main(["fields", "--relaxed", "missing.nc", "--reduced", "missing.nc", "--out", "x.nc",
               "--params", params])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.startswith("error: ") and "Traceback" not in err
    for w in words:
        assert w in err


def test_nan_in_state_file_names_variable_and_index(tmp_path, states, capsys):
    relaxed, _, s, r = states
    r["force_y"][7] = np.nan
    bad = write_state(tmp_path / "bad.nc", r)
    rc = main(["fields", "--relaxed", relaxed, "--reduced", bad, "--out", str(tmp_path / "f.nc"), "--params", SMALL])
    err = capsys.readouterr().err
    assert rc == 1
    assert "bad.nc" in err and "'force_y'" in err and "NaN" in err and "index 7" in err
    assert not (tmp_path / "f.nc").exists()


def test_missing_variable_and_wrong_dims(tmp_path, states, capsys):
    relaxed, _, s, _ = states
    ds = to_dataset(s).drop_vars("overlap_area")
    ds.to_netcdf(tmp_path / "nov.nc")
    assert main(["fields", "--relaxed", str(tmp_path / "nov.nc"), "--reduced", relaxed, "--out",
                 str(tmp_path / "f.nc")]) == 1
    assert "overlap_area" in capsys.readouterr().err
    ds = to_dataset(s)
    ds["x"] = xr.Variable("node", np.zeros(ds.sizes["node"]), {"units": "m"})
    ds.to_netcdf(tmp_path / "dims.nc")
    assert main(["fields", "--relaxed", str(tmp_path / "dims.nc"), "--reduced", relaxed, "--out",
                 str(tmp_path / "f.nc")]) == 1
    assert "'x' has dimensions ('node',)" in capsys.readouterr().err


def test_fields_and_checks_outputs(tmp_path, states):
    relaxed, reduced, _, _ = states
    out, chk = tmp_path / "f.nc", tmp_path / "f.checks.json"
    assert main(["fields", "--relaxed", relaxed, "--reduced", reduced, "--out", str(out), "--checks", str(chk),
                 "--params", SMALL]) == 0
    rep = json.loads(chk.read_text())
    assert rep["passed"] and set(rep["stages"]) == {"relaxed", "reduced"}
    assert abs(rep["stages"]["relaxed"]["support_reaction_rel_error"]) < 1e-12
    # both synthetic stages balance exactly, so their difference does too
    inc = rep["increment"]
    assert inc["passed"] and inc["weight_change"] < 0
    assert abs(inc["support_reaction_rel_error"]) < 1e-9 and abs(inc["love_rel_error_yy"]) < 1e-9
    with xr.open_dataset(out) as ds:
        assert ds.attrs["balance_checks_passed"] == 1
        assert ds.attrs["support_reaction_rel_error_increment"] == inc["support_reaction_rel_error"]
        assert ds["stress"].dims == ("y", "x", "i", "j")


def test_failed_balance_check_fails_loudly(tmp_path, states, capsys):
    _, reduced, s, _ = states
    s["force_y"] = s["force_y"] * np.where(s["contact_j"] < 0, 1.2, 1.0)
    bad = write_state(tmp_path / "unbalanced.nc", s)
    rc = main(["fields", "--relaxed", bad, "--reduced", reduced, "--out", str(tmp_path / "f.nc"), "--checks",
               str(tmp_path / "c.json"), "--params", SMALL])
    err = capsys.readouterr().err
    assert rc == 1 and "balance-law" in err and "support_reaction_rtol" in err and "unbalanced.nc" in err
    assert not (tmp_path / "f.nc").exists()
    assert json.loads((tmp_path / "c.json").read_text())["passed"] is False
    # with enforce: false the same pile is analysed and the failure only reported
    p = json.dumps({**json.loads(SMALL), "checks": {"enforce": False}})
    assert main(["fields", "--relaxed", bad, "--reduced", reduced, "--out", str(tmp_path / "f.nc"),
                 "--params", p]) == 0


def test_params_command_prints_effective_defaults(capsys):
    assert main(["params", "--params", '{"rve": {"size": 0.1}}']) == 0
    eff = json.loads(capsys.readouterr().out)
    assert eff["rve"]["size"] == 0.1 and eff["rve"]["shape"] == "square"


def test_stress_only_fields_and_their_ensemble(tmp_path, states, capsys):
    """Without --reduced and with no optional quantity: the stress fields and
    their balance check only, and an ensemble of such files."""
    relaxed, _, s, _ = states
    out, chk = tmp_path / "f.nc", tmp_path / "f.checks.json"
    assert main(["fields", "--relaxed", relaxed, "--quantities", "--out", str(out), "--checks", str(chk),
                 "--params", SMALL]) == 0
    rep = json.loads(chk.read_text())
    assert set(rep["stages"]) == {"relaxed"} and "increment" not in rep
    with xr.open_dataset(out) as ds:
        assert "stress" in ds and "stress_orientation" in ds
        assert not {"stress_increment", "fabric", "strain_increment", "displacement_gradient"} & set(ds.variables)
    other = write_state(tmp_path / "seed1.nc", {**s, "attrs": {**s["attrs"], "seed": 1}})
    out1 = tmp_path / "f1.nc"
    assert main(["fields", "--relaxed", other, "--quantities", "--out", str(out1), "--params", SMALL]) == 0
    ens = tmp_path / "ens.nc"
    assert main(["ensemble", "--fields", str(out), str(out1), "--out", str(ens), "--params", SMALL]) == 0
    with xr.open_dataset(ens) as ds:
        assert "stress_sem" in ds and "fabric" not in ds
    assert main(["fields", "--relaxed", relaxed, "--quantities", "strain", "--out", str(out),
                 "--params", SMALL]) == 1
    assert "strain needs the reduced state" in capsys.readouterr().err


def test_the_command_list_starts_without_the_heavy_libraries():
    """``python -m analysis --help`` lists the commands without importing xarray, scipy,
    matplotlib or numba (the modules of a command are imported when it runs): the help of
    a command line a user types first is instant."""
    code = ("import sys, contextlib, io\n"
            "from analysis.__main__ import main\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "    try:\n"
            "        main(['--help'])\n"
            "    except SystemExit:\n"
            "        pass\n"
            "assert 'COMMAND' in out.getvalue()\n"
            "print(sorted(m for m in ('xarray', 'scipy', 'matplotlib', 'numba') if m in sys.modules))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
