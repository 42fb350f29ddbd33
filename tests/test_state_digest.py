"""The digest of a state file's content (attribute ``data_digest``, docs/formats.md#state-files):
random bytes written into a state file after it was written, where netCDF reads them
without complaint, are named as damage by both readers instead of passing as a pile
(issue 28: before, "particle 44: edge 2 is too short" or an overflow deep in a picture).
Both share one rule, sim.digest.data_digest; this test holds it against the documented one."""

import hashlib
import logging

import netCDF4
import numpy as np
import pytest
import xarray as xr

from analysis.errors import StateError
from analysis.states import load_state
from sim.engine import Simulation
from sim.config import ModelParams
from sim.io import StateFileError, read_state, save_state
from sim.shapes import make_shapes


@pytest.fixture(scope="module")
def state_file(tmp_path_factory):
    shapes = make_shapes(np.random.default_rng(7), 12)
    sim = Simulation(shapes, ModelParams(), gravity=(0.0, -9.81))
    d = 2.2 * float(shapes.radius.max())
    for k in range(12):
        sim.place(k, (k % 4) * d, (0.6 + k // 4) * d, 0.3 * k)
    sim.run(steps=200)
    path = tmp_path_factory.mktemp("digest") / "state.nc"
    save_state(sim, path, {"model": {}}, protocol="wedge", seed=1, stage="relaxed")
    return path


def documented_digest(ds):
    """The ``data_digest`` by the rule of docs/formats.md#global-attributes, written
    here from that text: the variables, then the attributes but the digest, each
    in the order of their names; a number as int64 or float64 bytes."""
    parts = []
    for name in sorted(ds.data_vars):
        values = np.ascontiguousarray(ds[name].values)
        parts.append(f"{name}|{values.dtype.str}|{values.shape}|".encode("utf-8") + values.tobytes())
    for name in sorted(ds.attrs):
        if name == "data_digest":
            continue
        value = ds.attrs[name]
        if isinstance(value, str):
            parts.append(f"@{name}|".encode("utf-8") + value.encode("utf-8"))
        else:
            kind = np.float64 if np.asarray(value).dtype.kind == "f" else np.int64
            parts.append(f"@{name}|".encode("utf-8") + np.asarray(value, dtype=kind).tobytes())
    return hashlib.sha256(b"".join(parts)).hexdigest()


def test_the_written_digest_is_the_documented_one(state_file):
    with xr.open_dataset(state_file) as ds:
        ds = ds.load()
    assert ds.attrs["data_digest"] == documented_digest(ds)
    assert any(not isinstance(v, str) for v in ds.attrs.values()), "numbers among the attributes"
    read_state(state_file)
    assert load_state(str(state_file)).n_particles == 12


def _damaged(src, tmp_path, name):
    """A copy of ``src`` with 8 bytes of the stored values of variable ``name`` (its
    third float64, found in the file's bytes) replaced: the netCDF structure stays intact."""
    raw = bytearray(src.read_bytes())
    with xr.open_dataset(src) as ds:
        values = np.ascontiguousarray(ds[name].values)
    where = bytes(raw).find(values[2:3].tobytes())
    assert where > 0, "the value's bytes are stored uncompressed in the file"
    raw[where:where + 8] = np.float64(0.123).tobytes()
    out = tmp_path / f"damaged_{name}.nc"
    out.write_bytes(bytes(raw))
    with xr.open_dataset(out) as ds:  # netCDF reads it without a word
        assert float(ds[name].values[2]) == 0.123
    return out


@pytest.mark.parametrize("name", ["x", "node_x"])
def test_changed_data_bytes_are_named_as_damage(state_file, tmp_path, name):
    bad = _damaged(state_file, tmp_path, name)
    with pytest.raises(StateFileError, match=f"state file {bad}: its data do not match the digest"):
        read_state(bad)
    with pytest.raises(StateError, match=f"{bad}: its content does not match the digest"):
        load_state(str(bad))


def test_a_changed_attribute_is_named_as_damage(state_file, tmp_path):
    bad = tmp_path / "time_changed.nc"
    bad.write_bytes(state_file.read_bytes())
    with netCDF4.Dataset(bad, "a") as nc:
        nc.setncattr("time", float(nc.getncattr("time")) + 1.0)
    with pytest.raises(StateFileError, match="damaged after it was written"):
        read_state(bad)
    with pytest.raises(StateError, match="damaged after it was written"):
        load_state(str(bad))


def test_a_file_written_before_digests_still_reads(state_file, tmp_path, caplog):
    """It reads, but the simulator says in one warning line that the file is
    unverified (issue 59, item 8: a file whose digest was removed was read
    silently, as if checked); one with its digest reads without a word."""
    old = tmp_path / "no_digest.nc"
    old.write_bytes(state_file.read_bytes())
    with netCDF4.Dataset(old, "a") as nc:
        nc.delncattr("data_digest")
    with caplog.at_level(logging.INFO, logger="sim"):
        read_state(state_file)
        assert not caplog.records
        read_state(old)
    said = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(said) == 1 and "\n" not in said[0].getMessage()
    assert said[0].getMessage().startswith(f"state file {old}: no data_digest attribute")
    assert "unverified" in said[0].getMessage()
    assert load_state(str(old)).n_particles == 12
