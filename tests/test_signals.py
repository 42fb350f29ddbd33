"""SIGTERM and SIGINT end a pour, a relaxation or a probe cleanly: one log
line saying what was saved and how to resume, the pour's lock released, no
half-written output, the conventional exit status (128 + the signal), and a
pour resumed from what it saved ends bit for bit as the uninterrupted one.
A run also says how far it got at least every progress interval, however
long one of its runs of steps lasts."""

import json
import logging
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import xarray as xr
import numpy as np

from sim.config import SimConfig
from sim.pour import pour
from sim.relax import relax_file

REPO = Path(__file__).resolve().parents[1]

#: A pour of 30 particles, long enough (a few seconds) to be stopped in its
#: middle after its first progress line.
PARAMS = {"pour": {"n_particles": 30, "rate": 400.0}, "model": {"integrator": "verlet"}}
BOOKKEEPING = {"pour": {"progress_interval": 0.1}}
VARIABLES = ("x", "y", "theta", "vx", "vy", "omega", "contact_i", "contact_j", "force_x",
             "force_y", "contact_spring")


def _config(data=PARAMS):
    return SimConfig.from_dict(json.loads(json.dumps(data)))


def stopped(command, signum, params=PARAMS):
    """Run ``python -m sim COMMAND``, send `signum` once it logged its first
    progress line (``ETA``), and return its exit status and its log."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "sim", *command, "--params", json.dumps(params),
                             "--bookkeeping", json.dumps(BOOKKEEPING)], cwd=REPO, env=env,
                            stderr=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if " ETA " in line:
            proc.send_signal(signum)
            break
    lines += proc.stderr.readlines()
    return proc.wait(timeout=120), lines


def assert_same_pile(a_path, b_path):
    with xr.open_dataset(a_path) as a, xr.open_dataset(b_path) as b:
        assert (a.attrs["step"], a.attrs["time"]) == (b.attrs["step"], b.attrs["time"])
        for v in VARIABLES:
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """The pile poured without interruption."""
    out = tmp_path_factory.mktemp("whole") / "poured.nc"
    pour(_config(), "wedge", 3, out)
    return out


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_stopped_pour_says_what_it_saved_frees_its_lock_and_resumes_bit_for_bit(
        tmp_path, caplog, whole, signum, status):
    out, ckpt, run_log = tmp_path / "poured.nc", tmp_path / "ck.nc", tmp_path / "pile.log"
    code, lines = stopped(["pour", "--protocol", "wedge", "--seed", "3", "--out", str(out),
                           "--checkpoint", str(ckpt), "--log", str(run_log)], signum)
    name = signal.Signals(signum).name
    assert code == status, "".join(lines)
    errors = [line for line in lines if " ERROR " in line]
    assert len(errors) == 1 and "Traceback" not in "".join(lines), "".join(lines)
    said = re.search(rf"ERROR pour wedge seed 3: stopped by {name}; checkpoint (\S+) holds "
                     r"t = ([\d.]+) s simulated, (\d+) of 30 particles released; to resume, run "
                     r"the same command again \(with --checkpoint (\S+)\)$", errors[0])
    assert said, errors[0]
    assert said[1] == said[4] == str(ckpt)
    assert 0 < int(said[3]) < 30
    # the pile's log ends with that line too
    assert run_log.read_text().splitlines()[-1].endswith(errors[0].split(" ERROR ")[1].strip())
    # the checkpoint and the log are all that is left: no lock, no temporary, no output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ck.nc", "pile.log"]
    with xr.open_dataset(ckpt) as ds:
        assert ds.attrs["stage"] == "checkpoint" and ds.sizes["particle"] == int(said[3])
        assert f"{ds.attrs['time']:.4f}" == said[2]
    caplog.set_level(logging.INFO, logger="sim")
    pour(_config(), "wedge", 3, out, checkpoint=ckpt)
    assert "resuming wedge seed 3" in caplog.text
    assert_same_pile(whole, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pile.log", "poured.nc"]


@pytest.fixture(scope="module")
def relaxed(whole):
    out = whole.with_name("relaxed.nc")
    relax_file(_config(), whole, out)
    return out


#: Rest criteria no pile meets: the relaxation runs until it is stopped.
RESTLESS = {**PARAMS, "relax": {"max_speed": 1e-30, "kinetic_energy_fraction": 1e-30,
                                "max_time": 5.0}}


@pytest.mark.parametrize("command, signum", [
    (["relax"], signal.SIGTERM),
    (["probe", "--level", "0.1"], signal.SIGINT),
])
def test_a_stopped_relaxation_or_probe_says_nothing_was_saved(tmp_path, whole, relaxed, command,
                                                            signum):
    source = relaxed if command[0] == "probe" else whole
    out = tmp_path / "out.nc"
    code, lines = stopped([*command, "--input", str(source), "--out", str(out)], signum,
                          RESTLESS)
    assert code == 128 + signum, "".join(lines)
    errors = [line for line in lines if " ERROR " in line]
    assert len(errors) == 1 and "Traceback" not in "".join(lines), "".join(lines)
    name = signal.Signals(signum).name
    assert re.search(rf"ERROR \S+( [\d.]+)?: stopped by {name} at t = [\d.]+ s simulated; "
                     rf"nothing saved \({re.escape(str(out))} is written only at the end of the "
                     r"stage\); to resume, run the same command again: it starts the stage "
                     r"afresh from its input$", errors[0]), errors[0]
    assert list(tmp_path.iterdir()) == []


def test_a_run_of_steps_longer_than_the_progress_interval_is_not_silent(tmp_path, caplog):
    """One release a simulated second: each run to the next release is about
    10⁵ steps, far longer than the interval, and still the lines come."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 2, "rate": 1.0, "progress_interval": 0.005},
                               "model": {"integrator": "verlet"}})
    caplog.set_level(logging.INFO, logger="sim")
    pour(cfg, "wedge", 3, tmp_path / "poured.nc")
    # the first run after the first release is one run of steps: before, one line at most
    assert caplog.text.count("released 1 of 2 (50 %)") >= 3


def test_a_signal_before_the_run_loop_ends_the_pour_in_one_line(tmp_path, monkeypatch, caplog):
    """A SIGTERM while the pour draws its shapes (before its release loop, before
    its kernels run) is held by the command line's handler, not the default
    one that kills the process without a word: the pour ends at its first
    chunk with one line, nothing saved, no lock, status 143."""
    import sim.pour
    from sim.cli import main

    draw = sim.pour.pile_shapes

    def drawn_then_signalled(*args, **kwargs):
        shapes = draw(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)
        return shapes

    monkeypatch.setattr(sim.pour, "pile_shapes", drawn_then_signalled)
    ckpt = tmp_path / "ck.nc"
    with caplog.at_level(logging.INFO, logger="sim"):
        status = main(["pour", "--params", json.dumps(PARAMS), "--protocol", "wedge", "--seed", "2",
                       "--out", str(tmp_path / "p.nc"), "--checkpoint", str(ckpt)])
    assert status == 128 + signal.SIGTERM
    stops = [r.getMessage() for r in caplog.records if "stopped by SIGTERM" in r.getMessage()]
    assert len(stops) == 1 and "before the first pass of its release loop; nothing saved" in stops[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
