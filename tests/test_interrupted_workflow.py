"""A finished pour survives an interrupted Snakemake (issue 47, item 4).

``kill -INT`` to Snakemake (not to its jobs) makes it wait for the running
pours; they finish, write their state and delete their checkpoints, and
Snakemake, interrupted, marks those outputs incomplete: its rerun deletes them
and runs the pours again, which poured from the start. The pour keeps its
finished state apart (``python -m sim pour --finished``), so the rerun takes
it instead of pouring again, and a rerun under other settings pours anew.

First the simulator alone (a pour of a dozen particles), then a real tiny
Snakemake workflow in a temporary copy: the smoke configuration with one
small pile. Its pour is paused (SIGSTOP) once its log says it started and
resumed only after Snakemake has said it is terminating, so Snakemake is
interrupted while the pour runs, however loaded the machine.
"""

import contextlib
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from sim.atomic import temporary_path
from sim.config import SimConfig
from sim.engine import Simulation
from sim.pour import pour
from test_workflow import SNAKEMAKE, copy_workflow, with_overrides

PILE = "results/smoke/piles/wedge/seed1"
POURED = f"{PILE}/poured.nc"
FINISHED = f"{PILE}/pour.finished.nc"
RUN_LOG = "results/smoke/logs/pour/wedge/seed1.log"
#: One small pile of the smoke configuration (the wedge seed 1 is the target).
SMALL = {"pour": {"n_particles": 40}}
#: Generous: the machine may be busy with other work.
TIMEOUT = 900
#: A pour of a dozen particles, for the simulator alone.
TINY = {"pour": {"n_particles": 12, "rate": 400.0, "progress_interval": 1e9,
                 "frame_interval": 0.01},
        "model": {"integrator": "verlet"}}


def poured(tmp_path, data=TINY, film=True, **kwargs):
    """Pour the tiny pile of `data` (wedge, seed 3) into `tmp_path`, keeping the
    finished pour as fin.nc; the paths of its files."""
    paths = {"out": tmp_path / "poured.nc", "checkpoint": tmp_path / "ck.nc",
             "frames": tmp_path / "frames.nc" if film else None, "finished": tmp_path / "fin.nc"}
    pour(SimConfig.from_dict(data), "wedge", 3, **paths, **kwargs)
    return paths


def deleted(paths):
    """Delete the outputs of a pour, as Snakemake deletes those of an incomplete job."""
    for key in ("out", "frames"):
        if paths[key]:
            paths[key].unlink()


def no_step(*args, **kwargs):
    """A stand-in for :meth:`Simulation.run`: a pour that takes its finished copy runs nothing."""
    raise AssertionError("the pour ran the simulation")


def test_a_finished_pour_is_kept_and_taken_instead_of_pouring_again(tmp_path, caplog,
                                                                     monkeypatch):
    paths = poured(tmp_path)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["fin.frames.nc", "fin.nc", "frames.nc", "poured.nc"]   # no checkpoint
    first = {name: (tmp_path / name).read_bytes() for name in ("poured.nc", "frames.nc")}
    assert (tmp_path / "fin.nc").read_bytes() == first["poured.nc"]
    assert (tmp_path / "fin.frames.nc").read_bytes() == first["frames.nc"]
    deleted(paths)
    temporary_path(tmp_path / "poured.nc", 7).write_bytes(b"CDF half copied")   # a killed copy's
    monkeypatch.setattr(Simulation, "run", no_step)
    caplog.set_level("INFO", logger="sim")
    poured(tmp_path)
    assert "was made for this pile by this code under these settings; taken as it is" \
        in caplog.text
    assert {name: (tmp_path / name).read_bytes() for name in first} == first
    assert sorted(p.name for p in tmp_path.iterdir()) == names


def test_a_finished_pour_made_otherwise_is_removed_and_the_pile_poured_afresh(tmp_path, caplog):
    paths = poured(tmp_path)
    first = paths["out"].read_bytes()
    deleted(paths)
    caplog.set_level("INFO", logger="sim")
    poured(tmp_path, {**TINY, "model": {"integrator": "verlet", "friction": 0.45}})
    assert f"the finished pour {paths['finished']} was made with another configuration; " \
           "removed, pouring afresh" in caplog.text
    assert "pouring 12 particles" in caplog.text
    assert paths["out"].read_bytes() != first
    assert paths["finished"].read_bytes() == paths["out"].read_bytes()


def test_a_finished_pour_without_the_frames_asked_for_is_poured_again_with_them(tmp_path, caplog):
    paths = poured(tmp_path, film=False)
    assert not (tmp_path / "fin.frames.nc").exists()
    deleted(paths)
    caplog.set_level("INFO", logger="sim")
    paths = poured(tmp_path)
    assert "has no frames of a film" in caplog.text and "pouring 12 particles" in caplog.text
    assert (tmp_path / "fin.frames.nc").read_bytes() == paths["frames"].read_bytes()


def wait_for(condition, what, proc):
    """Poll `condition` until it holds; fail naming `what` after :data:`TIMEOUT`
    seconds, or when Snakemake `proc` has exited before it held."""
    deadline = time.monotonic() + TIMEOUT
    while not (found := condition()):
        if proc.poll() is not None:
            pytest.fail(f"Snakemake exited ({proc.returncode}) before {what}")
        if time.monotonic() > deadline:
            pytest.fail(f"no {what} within {TIMEOUT} s")
        time.sleep(0.1)
    return found


def text(path):
    """The text of `path`, or "" while it does not exist."""
    return path.read_text() if path.exists() else ""


def process_state(pid):
    """The state letter of process `pid` (``T``: stopped), "gone" once it has exited."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return "gone"


def default_sigint():
    """SIGINT as a terminal delivers it: a shell that started these tests in the
    background ignores it, and Python then never raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def snakemake(root, config, output):
    """Start Snakemake on the pile's poured state, as ``make run`` does (the
    default profile), its output to the file `output`."""
    with open(output, "w") as sink:
        return subprocess.Popen(
            [*SNAKEMAKE, "--profile", "workflow/profiles/default", "--cores", "1", *config, POURED],
            cwd=root, stdout=sink, stderr=subprocess.STDOUT, preexec_fn=default_sigint,
            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


def finish(proc, output):
    """Wait for Snakemake `proc`; its output."""
    proc.wait(timeout=TIMEOUT)
    return Path(output).read_text()


def runs(log):
    """The pile's log split at each run of its pour (the line "started by process")."""
    return text(log).split(": started by process ")[1:]


def started_by(log):
    """"HOST PID" of the pour's first run (its line "started by process"), once written whole."""
    first = runs(log)[:1]
    return bool(first) and "\n" in first[0] and first[0].split("\n")[0]


def interrupted_while_pouring(root, config, tmp_path):
    """Run Snakemake and send it SIGINT while the pour runs; its output."""
    output = tmp_path / "interrupted.out"
    proc = snakemake(root, config, output)
    log = root / RUN_LOG
    pid = int(wait_for(lambda: started_by(log), "pour started", proc).split()[1])
    os.kill(pid, signal.SIGSTOP)
    try:
        wait_for(lambda: process_state(pid) == "T", f"pause of the pour (process {pid})", proc)
        os.kill(proc.pid, signal.SIGINT)
        wait_for(lambda: "Terminating processes on user request" in text(output),
                 "Snakemake terminating on SIGINT", proc)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGCONT)
    out = finish(proc, output)
    assert proc.returncode != 0, out
    assert " INFO pour wedge seed 1 done: " in runs(log)[0], text(log)   # the pour did finish
    return out


def test_a_pour_finished_under_an_interrupted_snakemake_is_not_poured_again(tmp_path):
    root = copy_workflow(tmp_path / "wf")
    config = with_overrides(root, "small", SMALL)
    interrupted_while_pouring(root, config, tmp_path)
    kept = root / FINISHED
    made = kept.stat().st_mtime_ns if kept.exists() else None

    proc = snakemake(root, config, tmp_path / "rerun.out")
    out = finish(proc, tmp_path / "rerun.out")
    assert proc.returncode == 0, out
    assert len(runs(root / RUN_LOG)) == 2, out      # the incomplete pour did run again
    rerun = runs(root / RUN_LOG)[1]
    assert "pouring" not in rerun, rerun
    assert f"pour wedge seed 1: the finished pour {FINISHED} was made for this pile by " \
           "this code under these settings; taken as it is (copied to " in rerun, rerun
    # the state of the first pour, kept by it and untouched since, bit for bit
    assert kept.stat().st_mtime_ns == made
    poured = (root / POURED).read_bytes()
    assert poured == kept.read_bytes()

    # other settings: Snakemake re-runs the pour, which pours anew
    config = with_overrides(root, "other", {**SMALL, "model": {"friction": 0.45}})
    proc = snakemake(root, config, tmp_path / "other.out")
    out = finish(proc, tmp_path / "other.out")
    assert proc.returncode == 0, out
    other = runs(root / RUN_LOG)[2]
    assert "pouring 40 particles" in other and " done: " in other, other
    assert f"the finished pour {FINISHED} was made with another configuration; removed, " \
           "pouring afresh" in other, other
    assert (root / POURED).read_bytes() != poured
    assert (root / POURED).read_bytes() == (root / FINISHED).read_bytes()
