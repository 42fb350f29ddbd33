"""A pour's checkpoint, lock and end: resumed only under the same physics and
code, set aside when unreadable, never poured twice at once, killed at random
moments and still bit for bit the uninterrupted pile, and never "done" with
particles in flight."""

import logging
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from analysis.run_times import stage_cpu_time
from sim import checkpoint
from sim.atomic import temporary_path
from sim.config import SimConfig
from sim.engine import Simulation
from sim.io import StateFileError, read_state, save_state
from sim.lock import PourLock, PourLockedError
from sim.pour import LandingError, pile_shapes, pour
from sim.progress import process_cpu

TINY = {"pour": {"n_particles": 12, "rate": 400.0, "release_speed": 0.3, "checkpoint_interval": 0.02,
                 "progress_interval": 1e9, "frame_interval": 0.01},
        "model": {"integrator": "verlet"}}
VARIABLES = ("x", "y", "theta", "vx", "vy", "omega", "contact_i", "contact_j", "force_x",
             "force_y", "contact_spring")


def tiny(**changes):
    """The tiny pour's configuration with `changes` ({section: {key: value}})."""
    data = {section: dict(values) for section, values in TINY.items()}
    for section, values in changes.items():
        data.setdefault(section, {}).update(values)
    return SimConfig.from_dict(data)


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """The tiny pile poured without interruption (with the frames of its film
    beside it, frames.nc)."""
    out = tmp_path_factory.mktemp("whole") / "poured.nc"
    pour(tiny(), "wedge", 3, out, frames=out.with_name("frames.nc"))
    return out


def assert_same_pile(a_path, b_path):
    """Same steps, time and state, to the bit."""
    with xr.open_dataset(a_path) as a, xr.open_dataset(b_path) as b:
        assert a.attrs["step"] == b.attrs["step"]
        assert a.attrs["time"] == b.attrs["time"]
        for v in VARIABLES:
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


def started_checkpoint(path, cfg, seed=3):
    """A checkpoint of a pour of `cfg` that has released one particle."""
    sim = Simulation(pile_shapes(cfg, seed), cfg.model)
    sim.place(0, 0.0, 0.05, 0.0, 0.0, -1.0)
    sim.run(duration=0.002)
    save_state(sim, path, cfg.to_dict(), stage="checkpoint", next_release=0.0025,
               protocol="wedge", seed=seed)


@pytest.mark.parametrize("what, changes", [
    ("configuration", {"model": {"friction": 0.3}}),
    ("configuration", {"pour": {"rate": 300.0}}),
    ("code version", {}),
])
def test_a_checkpoint_of_other_physics_or_code_is_set_aside(tmp_path, caplog, monkeypatch,
                                                            what, changes):
    """Resumed under other physics (or other code), a half-poured pile would
    carry the wrong label: the pour starts afresh and says why."""
    ckpt = tmp_path / "pour.checkpoint.nc"
    started_checkpoint(ckpt, tiny())
    if what == "code version":
        monkeypatch.setattr(checkpoint, "code_version", lambda: "edited-code")
    cfg = tiny(**changes)
    fresh = tmp_path / "fresh.nc"
    pour(cfg, "wedge", 3, fresh)
    out = tmp_path / "poured.nc"
    with caplog.at_level(logging.INFO, logger="sim"):
        pour(cfg, "wedge", 3, out, checkpoint=ckpt)
    assert f"was made with another {what}" in caplog.text
    assert "resuming" not in caplog.text
    assert len(list(tmp_path.glob("pour.checkpoint.nc.*.unused"))) == 1
    assert_same_pile(fresh, out)


def test_a_checkpoint_is_resumed_when_only_bookkeeping_changed(tmp_path, caplog):
    ckpt = tmp_path / "pour.checkpoint.nc"
    started_checkpoint(ckpt, tiny())
    cfg = tiny(pour={"checkpoint_interval": 7.0, "progress_interval": 3.0})
    with caplog.at_level(logging.INFO, logger="sim"):
        pour(cfg, "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt)
    assert "resuming wedge seed 3 from checkpoint" in caplog.text
    assert not list(tmp_path.glob("*.unused"))


def test_bookkeeping_comes_apart_and_may_hold_nothing_else():
    from sim.cli import _params
    from sim.config import ConfigError

    cfg = _params('{"pour": {"rate": 50.0, "progress_interval": 1.0}}',
                  '{"pour": {"progress_interval": 2.0, "checkpoint_interval": 3.0}}')
    assert (cfg.pour.rate, cfg.pour.progress_interval, cfg.pour.checkpoint_interval) == \
        (50.0, 2.0, 3.0)
    with pytest.raises(ConfigError, match="change the result"):
        _params(None, '{"pour": {"rate": 5.0}}')


def test_a_truncated_checkpoint_is_set_aside_and_the_pour_restarts(tmp_path, caplog, whole):
    ckpt = tmp_path / "pour.checkpoint.nc"
    started_checkpoint(ckpt, tiny())
    ckpt.write_bytes(ckpt.read_bytes()[:5000])
    out = tmp_path / "poured.nc"
    with caplog.at_level(logging.INFO, logger="sim"):
        pour(tiny(), "wedge", 3, out, checkpoint=ckpt)
    assert "is unusable" in caplog.text and str(ckpt) in caplog.text
    assert len(list(tmp_path.glob("pour.checkpoint.nc.*.unused"))) == 1
    assert not ckpt.exists()
    assert_same_pile(whole, out)


def test_a_truncated_state_file_is_refused_in_one_line_naming_it(tmp_path, whole, caplog):
    from sim.cli import main

    bad = tmp_path / "poured.nc"
    bad.write_bytes(whole.read_bytes()[:4000])
    with pytest.raises(StateFileError, match=f"state file {bad} cannot be read") as err:
        read_state(bad)
    assert "\n" not in str(err.value)
    assert main(["relax", "--input", str(bad), "--out", str(tmp_path / "relaxed.nc")]) == 2
    errors = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 1 and str(bad) in errors[0] and "\n" not in errors[0]


def dead_pid():
    """The PID of a process that has ended."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_a_live_lock_refuses_a_second_pour_and_a_dead_one_is_taken_over(tmp_path, caplog):
    """Snakemake killed, its pour still running, the rerun must not race it."""
    import socket

    ckpt = tmp_path / "pour.checkpoint.nc"
    lock = tmp_path / "pour.checkpoint.nc.lock"
    lock.write_text(f"{socket.gethostname()} {os.getppid()}\n")
    with pytest.raises(PourLockedError, match=str(os.getppid())):
        pour(tiny(), "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt)
    assert not (tmp_path / "poured.nc").exists()
    lock.write_text(f"{socket.gethostname()} {dead_pid()}\n")
    with caplog.at_level(logging.INFO, logger="sim"):
        pour(tiny(), "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt)
    assert "taking over the lock" in caplog.text
    assert not lock.exists()     # released when done


def test_the_piles_log_gains_each_run_that_holds_the_lock_and_no_other(tmp_path, caplog):
    """The pile's log (run_log, the workflow's logs/pour/P/seedS.log) is
    appended to, never emptied: a run the live lock refuses leaves it byte
    for byte, and the run that holds the lock adds its lines after what was
    there, from a line naming its process, down to the pour's summary."""
    import socket

    run_log = tmp_path / "seed3.log"
    run_log.write_text("an earlier run's last line\n")
    ckpt = tmp_path / "pour.checkpoint.nc"
    lock = tmp_path / "pour.checkpoint.nc.lock"
    lock.write_text(f"{socket.gethostname()} {os.getppid()}\n")
    with pytest.raises(PourLockedError):
        pour(tiny(), "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt,
             run_log=run_log)
    assert run_log.read_text() == "an earlier run's last line\n"
    lock.unlink()
    with caplog.at_level(logging.INFO, logger="sim"):    # as the command line logs
        pour(tiny(), "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt,
             run_log=run_log)
    lines = run_log.read_text().splitlines()
    assert lines[0] == "an earlier run's last line"
    assert lines[1].endswith(f" INFO pour wedge seed 3: started by process {socket.gethostname()} "
                             f"{os.getpid()}"), lines[1]
    assert " INFO pour wedge seed 3 done: " in lines[-1], lines[-1]
    # the summary line's CPU, read back as a pile's record reads it: this process's
    # count when the line was written, so positive and at most its count now (the
    # line rounds to 0.1 s)
    assert 0 < stage_cpu_time(run_log) <= process_cpu() + 0.05


def test_a_run_killed_while_writing_its_results_leaves_no_temporary_file(tmp_path, whole):
    """Killed while writing the poured state or its film (after the last
    checkpoint, before the rename), a run leaves hidden temporary files
    (:func:`sim.atomic.temporary_path`); the next run, holding the lock,
    removes them with the checkpoint's and pours the same pile."""
    ckpt = tmp_path / "pour.checkpoint.nc"
    left = [temporary_path(tmp_path / name, pid) for name in ("poured.nc", "frames.nc",
                                                              "pour.checkpoint.nc") for pid in (7, 8)]
    for path in left:
        path.write_bytes(b"CDF half written")
    pour(tiny(), "wedge", 3, tmp_path / "poured.nc", checkpoint=ckpt,
         frames=tmp_path / "frames.nc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames.nc", "poured.nc"]
    assert_same_pile(whole, tmp_path / "poured.nc")


def test_another_hosts_lock_counts_until_it_is_stale(tmp_path):
    lock_path = tmp_path / "x.lock"
    lock_path.write_text("some-other-host 1\n")
    with pytest.raises(PourLockedError, match="some-other-host"):
        with PourLock(lock_path, stale_after=60.0):
            pass
    old = lock_path.stat().st_mtime - 120.0
    os.utime(lock_path, (old, old))
    with PourLock(lock_path, stale_after=60.0):
        assert lock_path.read_text().split()[1] == str(os.getpid())
    lock_path.write_text("")     # its writer was killed before writing
    with PourLock(lock_path, stale_after=60.0):
        pass


def test_a_pour_with_particles_in_flight_fails_naming_the_cause(tmp_path):
    """Released at 10 m/s the particles bounce off: no "done" for a cloud."""
    # dt_safety 0.15: a step short enough to resolve the motion at 10 m/s (docs/model.md)
    cfg = tiny(pour={"n_particles": 6, "release_speed": 10.0},
               model={"damping": 0.0, "dt_safety": 0.15})
    run_log = tmp_path / "seed3.log"
    with pytest.raises(LandingError, match="pour.release_speed = 10.0"):
        pour(cfg, "wedge", 3, tmp_path / "poured.nc", run_log=run_log)
    assert not (tmp_path / "poured.nc").exists()
    # the pile's log ends with the error, as the terminal shows it
    assert "ERROR pour wedge seed 3: 6 of 6 particles are still in flight" in \
        run_log.read_text().splitlines()[-1]


def fresh_numba_process_lock():
    """Give a forked child its own lock around Numba's threading-layer start.

    Numba takes a process-shared semaphore (made by the parent before the
    fork) at every ``numba.get_num_threads()``, which each new simulation asks
    once (:attr:`sim.engine.Simulation.threads`); a child SIGKILLed while
    holding it would leave it held for its siblings and the parent, which then
    wait for ever.  A pour started by
    exec (the workflow's) makes its own, so this is an artefact of forking."""
    from numba.np.ufunc import parallel

    parallel._backend_init_process_lock = None


def pour_killed_repeatedly(folder, kills, seed):
    """Pour the tiny pile into `folder`, forking a pour that is SIGKILLed at a
    random moment (up to 0.4 s in) `kills` times, each fork resuming from what
    the last left, then pouring to the end.  The tiny pour takes 0.2-0.3 s on
    the machines seen, so a fork may finish before its kill (it is poured
    again from scratch) or be killed before its first checkpoint: kills go on
    until `kills` have landed and the last left a checkpoint to resume from,
    whatever the speed of the host.  Run in a fresh process whose
    Numba threading layer is fork-safe (workqueue; GNU OpenMP is not); a fork
    whose pour fails exits with status 1 after printing why, and ends this."""
    import faulthandler
    import traceback

    faulthandler.dump_traceback_later(300, exit=True)    # a hang says where, within the timeout
    logging.basicConfig(level=logging.INFO)
    out, ckpt = Path(folder) / "poured.nc", Path(folder) / "pour.checkpoint.nc"
    frames = out.with_name("frames.nc")
    rng = random.Random(seed)
    pour(tiny(), "wedge", 3, out)      # compiles the kernels before the forks
    out.unlink()
    done = 0
    while done < kills or not ckpt.exists():
        assert done < 10 * kills, f"{done} kills and none after a first checkpoint"
        pid = os.fork()
        if pid == 0:
            status = 0
            try:
                fresh_numba_process_lock()
                pour(tiny(), "wedge", 3, out, checkpoint=ckpt, frames=frames)
            except BaseException:
                traceback.print_exc()
                status = 1
            finally:
                sys.stderr.flush()
                os._exit(status)
        time.sleep(rng.uniform(0.0, 0.4))
        os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        if os.WIFSIGNALED(status):
            done += 1
        else:
            assert os.WEXITSTATUS(status) == 0, "a forked pour failed (its traceback is above)"
            out.unlink()         # finished before the kill: pour again from scratch
            frames.unlink()
    pour(tiny(), "wedge", 3, out, checkpoint=ckpt, frames=frames)


def test_killed_at_random_moments_the_pour_ends_bit_for_bit_as_uninterrupted(tmp_path,
                                                                              whole):
    """SIGKILL at 20 random moments (mid-step, mid-checkpoint, holding the
    lock), each rerun resuming what the last one left: the pile and the frames
    of its film are the uninterrupted ones, and no lock, partial frames or
    temporary file is left behind."""
    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue", "NUMBA_NUM_THREADS": "1"}
    code = f"import test_pour_resume as t; t.pour_killed_repeatedly({str(tmp_path)!r}, 20, 12)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parent, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-5000:]
    assert proc.stderr.count("resuming wedge seed 3") >= 5     # the kills did interrupt
    assert_same_pile(whole, tmp_path / "poured.nc")
    # the film's frames too: every frame of the uninterrupted pour, none twice
    with xr.open_dataset(whole.with_name("frames.nc")) as a, \
            xr.open_dataset(tmp_path / "frames.nc") as b:
        assert a.sizes["frame"] >= 10
        for v in ("time", "x", "y", "theta", "speed", "released"):
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames.nc", "poured.nc"]
