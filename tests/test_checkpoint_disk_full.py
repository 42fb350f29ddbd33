"""A checkpoint that cannot be written ends no pour (issue 59, item 8).

A full disk for the checkpoint stopped a pour whose output disk was healthy,
saying "nothing was lost", while all the pour since its start (or its last
checkpoint) was. The checkpoint only shortens a rerun after a stop; losing
one costs nothing unless the pour is stopped before the next one is written,
while stopping the pour loses its work for certain. So the pour goes on
without it, with one warning line per failed write that says what a stop
would lose, and writes its output; stopped by a signal while its checkpoint
cannot be written, it says that the state of the stop was not saved and
what is left on disk, never that it was kept.
"""

import errno
import logging
import signal

import pytest

import sim.io
from sim.atomic import atomic_path
from sim.config import SimConfig
from sim.engine import Simulation
from sim.io import read_state
from sim.pour import pour
from sim.run_loop import Interrupted

CFG = {"pour": {"n_particles": 12, "checkpoint_interval": 1e-9, "progress_interval": 1e9}}


def _full_disk_for(monkeypatch, victim):
    """Every write of the file `victim` fails as on a full disk (ENOSPC, the
    temporary file removed by :func:`sim.atomic.atomic_path`)."""
    write = sim.io.atomic_write

    def atomic_write(ds, path):
        if str(path) != str(victim):
            return write(ds, path)
        with atomic_path(path):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(sim.io, "atomic_write", atomic_write)


def test_a_full_checkpoint_disk_leaves_the_pour_going(tmp_path, monkeypatch, caplog):
    checkpoint = tmp_path / "ckpt" / "pour.ckpt.nc"
    _full_disk_for(monkeypatch, checkpoint)
    with caplog.at_level(logging.INFO, logger="sim"):
        done = pour(SimConfig.from_dict(CFG), "wedge", 1, tmp_path / "poured.nc", checkpoint)
    assert done.n == 12 and read_state(tmp_path / "poured.nc").sizes["particle"] == 12
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warned, "no word of the checkpoint that was not written"
    for line in warned:
        assert "\n" not in line and "nothing was lost" not in line
        assert line.startswith(f"pour wedge seed 1: checkpoint not written (cannot write {checkpoint}: "
                               "the disk holding")
        assert "pouring on without it" in line and "there is none yet" in line
    assert not checkpoint.exists()


def test_a_stop_whose_checkpoint_cannot_be_written_says_so(tmp_path, monkeypatch, caplog):
    checkpoint = tmp_path / "pour.ckpt.nc"
    _full_disk_for(monkeypatch, checkpoint)
    run = Simulation.run
    calls = []

    def stopped(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 30:
            raise Interrupted(signal.SIGTERM)
        return run(self, *args, **kwargs)

    monkeypatch.setattr(Simulation, "run", stopped)
    cfg = SimConfig.from_dict({"pour": {**CFG["pour"], "checkpoint_interval": 1e9}})
    with caplog.at_level(logging.INFO, logger="sim"), pytest.raises(Interrupted):
        pour(cfg, "wedge", 1, tmp_path / "poured.nc", checkpoint)
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert len(said) == 1 and "\n" not in said[0]
    assert said[0].startswith("pour wedge seed 1: stopped by SIGTERM; the checkpoint could not "
                              f"be written (cannot write {checkpoint}: the disk holding")
    assert "the state of the stop is lost" in said[0] and "holds t =" not in said[0]
    assert not checkpoint.exists()
