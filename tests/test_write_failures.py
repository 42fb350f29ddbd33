"""A state or an analysis file that cannot be written (a read-only file system, a full disk)
fails in one line that says why and that nothing was lost, the same line from both
command lines (one atomic write, :mod:`sim.atomic`) (issue 28: a full disk showed only "NetCDF: HDF
error" or even "Permission denied", a read-only one a traceback). netCDF's own errors
are made here as the library raises them on those file systems (checked by hand on a
read-only and a full tmpfs: errno 13 from the library, errno 30 from the folder)."""

import os
import shutil
from collections import namedtuple

import numpy as np
import pytest
from synthetic_states import step_pyramid, write_state

from analysis.__main__ import main as analysis_main
from sim.cli import main as sim_main
from sim.config import ModelParams
from sim.atomic import OutputError
from sim.engine import Simulation
from sim.io import save_state
from sim.shapes import make_shapes


@pytest.fixture
def sim3():
    sim = Simulation(make_shapes(np.random.default_rng(2), 3), ModelParams(), gravity=(0.0, -9.81))
    for k in range(3):
        sim.place(k, 0.01 * k, 0.01, 0.0)
    return sim


def _failing_netcdf(monkeypatch, written=4096):
    """to_netcdf writes ``written`` bytes to its temporary file, then fails as netCDF does."""
    def to_netcdf(self, path, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"\0" * written)
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr("xarray.Dataset.to_netcdf", to_netcdf)


def test_a_full_disk_is_named_and_the_old_file_kept(tmp_path, monkeypatch, sim3):
    path = tmp_path / "relaxed.nc"
    path.write_bytes(b"the finished file")
    _failing_netcdf(monkeypatch)
    Usage = namedtuple("Usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**6, 10**6 - 512, 512))
    with pytest.raises(OutputError) as err:
        save_state(sim3, path, {}, stage="relaxed")
    msg = str(err.value)
    assert f"cannot write {path}: the disk holding {tmp_path} is full (512 bytes free after 4096 bytes" in msg
    assert "nothing was lost" in msg and "is as it was" in msg and "\n" not in msg
    assert path.read_bytes() == b"the finished file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["relaxed.nc"]  # no partial file


def test_a_read_only_file_system_is_named(tmp_path, monkeypatch, sim3):
    _failing_netcdf(monkeypatch, written=0)
    real = os.statvfs

    class ReadOnly:
        def __init__(self, st):
            self.st = st
            self.f_flag = st.f_flag | os.ST_RDONLY

        def __getattr__(self, name):
            return getattr(self.st, name)

    monkeypatch.setattr(os, "statvfs", lambda p: ReadOnly(real(p)))
    with pytest.raises(OutputError, match=f"the file system holding {tmp_path} is read-only; nothing was lost: "
                                          f"{tmp_path / 'new.nc'} was not created"):
        save_state(sim3, tmp_path / "new.nc", {}, stage="relaxed")
    assert list(tmp_path.iterdir()) == []


def test_any_other_failure_keeps_the_library_s_reason(tmp_path, monkeypatch, sim3):
    _failing_netcdf(monkeypatch, written=0)
    with pytest.raises(OutputError, match="PermissionError: Permission denied; nothing was lost"):
        save_state(sim3, tmp_path / "x.nc", {}, stage="relaxed")


def test_the_command_line_says_it_in_one_line(tmp_path, monkeypatch, caplog):
    """A pour whose state cannot be written ends with exit status 3 and the one line, not a traceback."""
    def pour(*args, **kwargs):
        save_state(None, tmp_path / "p.nc")  # the state's write fails as above
    _failing_netcdf(monkeypatch, written=0)
    monkeypatch.setattr("sim.io.state_dataset", lambda sim, config=None, keep=None, **attrs: __import__("xarray").Dataset())
    monkeypatch.setattr("sim.pour.pour", pour)
    status = sim_main(["pour", "--params", "{}", "--protocol", "wedge", "--seed", "1", "--out", str(tmp_path / "p.nc")])
    assert status == 3
    assert f"cannot write {tmp_path / 'p.nc'}: PermissionError: Permission denied; nothing was lost" in caplog.text


def test_the_analysis_says_the_same_line(tmp_path, monkeypatch, capsys):
    """An analysis output on a full disk: exit status 1, the simulator's line, no partial file."""
    state = write_state(tmp_path / "relaxed.nc", step_pyramid(21, 0.006, slope=0.6))
    _failing_netcdf(monkeypatch)
    Usage = namedtuple("Usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**6, 10**6 - 512, 512))
    out = tmp_path / "out" / "fields.nc"
    status = analysis_main(["fields", "--relaxed", state, "--out", str(out), "--params",
                            '{"grid": {"x_min": -0.06, "x_max": 0.06, "y_min": 0.03, "y_max": 0.06, "spacing": 0.03}}'])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1
    assert err[-1] == (f"error: cannot write {out}: the disk holding {out.parent} is full (512 bytes free after "
                       f"4096 bytes of it were written); nothing was lost: {out} was not created and the partial "
                       "file was removed"), err
    assert list(out.parent.iterdir()) == []
