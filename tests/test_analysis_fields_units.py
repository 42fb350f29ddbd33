"""Fields files are read in the units their writer gives them, and only as
written (issue 47 item 7).

A fields file is written by the real writer (``python -m analysis fields`` on
two small synthetic stages).  A copy of it whose stress is converted to kPa
(values divided by 1000, ``units`` "kPa"), as a user's tool might leave it,
was averaged as N/m by every reader; now each reader refuses it in one line
naming the file, the variable, the unit found and the unit expected
(:func:`analysis.fields.check_units`), and so for a variable without
``units``.  The file carries a ``data_digest`` of its content, and a copy
whose numbers were changed in place is refused as damaged.
"""

import json

import numpy as np
import pytest
import xarray as xr
from synthetic_states import displaced, step_pyramid, write_state

from analysis.__main__ import main
from analysis.errors import InputError
from analysis.fields import read_fields
from sim.digest import data_digest

SMALL = {"grid": {"x_min": -0.1, "x_max": 0.1, "y_min": 0.03, "y_max": 0.09, "spacing": 0.03}}


@pytest.fixture(scope="module")
def fields(tmp_path_factory):
    """A fields file of the real writer, of a pile and its gravity reduction."""
    d = tmp_path_factory.mktemp("fields")
    s = step_pyramid(41, 0.006, slope=0.6)
    r = displaced(s, np.column_stack([1e-6 * s["x"], 2e-5 * s["y"]]), 0.9, 0.9 * 9.81)
    out = d / "fields.nc"
    assert main(["fields", "--relaxed", write_state(d / "relaxed.nc", s), "--reduced",
                 write_state(d / "reduced.nc", r), "--out", str(out), "--params", json.dumps(SMALL)]) == 0
    return out


def _copy(fields, path, edit):
    """A copy of ``fields`` at ``path``, changed by ``edit(ds)``, written with xarray as a user would."""
    with xr.open_dataset(fields) as ds:
        ds = ds.load()
    edit(ds)
    ds.to_netcdf(path)
    return str(path)


def _in_kpa(ds):
    attrs = {**ds["stress"].attrs, "units": "kPa"}
    ds["stress"] = ds["stress"] / 1000.0
    ds["stress"].attrs = attrs


def _readers(path, out):
    """Each way the analysis reads a fields file: (name, call); a call raises or returns the exit status."""
    return [
        ("ensemble", lambda: main(["ensemble", "--fields", path, "--out", str(out / "ens.nc")])),
        ("moduli", lambda: main(["moduli", "--ensemble", path, "--out", str(out / "mod.nc")])),
        ("invariants", lambda: main(["invariants", "--ensemble", path, "--out", str(out / "inv.nc")])),
        ("figure", lambda: main(["figure", "vertical-strain", "--inputs", f"p={path}", "--out",
                                 str(out / "fig.png")])),
        ("the scripts' reader", lambda: read_fields(path)),
    ]


def _refusal(call, capsys):
    """The one line a reader refuses with: the command line's error line or the exception's text."""
    try:
        status = call()
    except InputError as exc:
        return str(exc)
    err = capsys.readouterr().err
    assert status == 1, err
    return err.strip()


@pytest.mark.parametrize("reader", range(5))
def test_a_copy_in_kpa_is_refused_by_every_reader(fields, tmp_path, capsys, reader):
    path = _copy(fields, tmp_path / "kpa.nc", _in_kpa)
    name, call = _readers(path, tmp_path)[reader]
    line = _refusal(call, capsys)
    assert "\n" not in line, name
    for word in (path, "stress", "'kPa'", "'N m-1'"):
        assert word in line, (name, line)
    assert not list(tmp_path.glob("ens.nc")) and not list(tmp_path.glob("fig*.png"))


def test_a_variable_without_units_is_refused(fields, tmp_path, capsys):
    path = _copy(fields, tmp_path / "nounits.nc", lambda ds: ds["strain_increment"].attrs.pop("units"))
    assert main(["ensemble", "--fields", path, "--out", str(tmp_path / "ens.nc")]) == 1
    err = capsys.readouterr().err
    assert path in err and "strain_increment" in err and "no units" in err and "'1'" in err


@pytest.mark.parametrize("reader", range(5))
def test_the_file_as_written_is_read_by_every_reader(fields, tmp_path, capsys, reader):
    name, call = _readers(str(fields), tmp_path)[reader]
    status = call()
    assert status == 0 or isinstance(status, xr.Dataset), (name, capsys.readouterr().err)


def test_the_fields_file_carries_the_digest_of_its_content(fields):
    with xr.open_dataset(fields) as ds:
        ds = ds.load()
    assert ds.attrs["data_digest"] == data_digest(ds)


def test_a_copy_changed_in_place_is_refused_as_damaged(fields, tmp_path, capsys):
    def edit(ds):
        ds["solid_fraction"][0, 0] = 0.5
    path = _copy(fields, tmp_path / "edited.nc", edit)
    assert main(["ensemble", "--fields", path, "--out", str(tmp_path / "ens.nc")]) == 1
    err = capsys.readouterr().err
    assert path in err and "data_digest" in err and "damaged after it was written" in err
    assert not (tmp_path / "ens.nc").exists()
