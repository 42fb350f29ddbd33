"""netCDF and JSON output: CF attributes and atomic writes.

Every file gets the global attributes ``Conventions``, ``title``, ``source``
(``analysis <version>``), ``history``, ``config`` (the effective analysis
parameters as JSON text) and ``software`` (the versions that computed it);
every variable and coordinate must carry ``units`` and ``long_name``
(checked before writing). Files are written to a temporary
name in the destination folder and renamed, so a killed job never leaves a
complete-looking file: :func:`sim.atomic.atomic_path`, the project's one
atomic write, shared with the simulator like its check of paths (a failed
write is an :class:`sim.atomic.OutputError`, the same line from either
command line). Each file carries ``data_digest``, the digest of its content as
read back (:func:`sim.digest.data_digest`, the simulator's rule), which :func:`read_dataset`
verifies.
"""

from __future__ import annotations

import datetime as _dt
import functools
import json
import os
import sys
from typing import Any, Callable

import numpy as np
import xarray as xr

from sim.atomic import atomic_path
from sim.digest import data_digest

from . import __version__

CONVENTIONS = "CF-1.10"
TENSOR_COORDS = {"i": ["x", "y"], "j": ["x", "y"]}


def tensor_coords() -> dict[str, xr.Variable]:
    """Coordinates of the tensor component dimensions ``i`` and ``j``."""
    return {
        "i": xr.Variable("i", np.array(["x", "y"]), {"long_name": "tensor component (first index)", "units": "1"}),
        "j": xr.Variable("j", np.array(["x", "y"]), {"long_name": "tensor component (second index)", "units": "1"}),
    }


def check_cf(ds: xr.Dataset) -> None:
    """Raise ``ValueError`` naming any variable or coordinate without ``units`` or ``long_name``."""
    bad = [str(n) for n, v in ds.variables.items() if "units" not in v.attrs or "long_name" not in v.attrs]
    if bad:
        raise ValueError(f"variables without units/long_name: {', '.join(sorted(bad))}")


@functools.lru_cache(maxsize=1)
def software_versions() -> str:
    """``python 3.11.7, numpy 2.4.6, scipy ..., xarray ..., netCDF4 ...``: what computed an analysis file."""
    import platform
    from importlib.metadata import version

    return ", ".join([f"python {platform.python_version()}"]
                     + [f"{name} {version(name)}" for name in ("numpy", "scipy", "xarray", "netCDF4")])


def finalize(ds: xr.Dataset, title: str, params: dict[str, Any] | None, command: str | None = None) -> xr.Dataset:
    """Set the global attributes required by docs/formats.md#conventions (with ``software``:
    :func:`software_versions`) and check CF metadata."""
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    cmd = command if command is not None else " ".join([os.path.basename(sys.executable), "-m", "analysis"] + sys.argv[1:])
    ds.attrs["Conventions"] = CONVENTIONS
    ds.attrs["title"] = title
    ds.attrs["source"] = f"analysis {__version__} (polypile)"
    prior = ds.attrs.get("history", "")
    ds.attrs["history"] = (f"{now}: {cmd}" + ("\n" + prior if prior and isinstance(prior, str) else ""))[:20000]
    ds.attrs["config"] = json.dumps(params if params is not None else {}, sort_keys=True)
    ds.attrs["software"] = software_versions()
    for k, v in list(ds.attrs.items()):
        if isinstance(v, bool):
            ds.attrs[k] = int(v)
    check_cf(ds)
    return ds


def check_writable(path: str, option: str) -> None:
    """Refuse an output ``path`` that cannot be written, before any work: a file is made and
    removed in its folder, or in the nearest folder above it that exists (the writers make
    the missing ones).

    Raises
    ------
    InputError
        Naming the option, the path and the system's reason (a read-only or
        missing folder that cannot be made, a full disk, no permission).
    """
    from .errors import InputError

    d, b = os.path.split(os.path.abspath(path))
    while not os.path.exists(d):  # the writer makes the missing folders: probe the nearest that exists
        d = os.path.dirname(d)
    probe = os.path.join(d, f".{b}.{os.getpid()}.probe")
    try:
        if not os.path.isdir(d):
            raise NotADirectoryError(20, f"{d} is a file, not a folder")
        with open(probe, "wb") as fh:
            fh.write(b"\0")
        os.remove(probe)
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot be written ({exc.strerror or exc}); nothing was made") from None


def write_dataset(ds: xr.Dataset, path: str, *, title: str, params: dict[str, Any] | None,
                  command: str | None = None) -> None:
    """Finalise ``ds`` and write it to ``path`` atomically (temporary name, then rename)."""
    finalize(ds, title, params, command)
    encoding = {}
    for name, v in ds.variables.items():
        if v.dtype.kind == "f":
            encoding[name] = {"zlib": True, "complevel": 4}
            if name not in ds.coords:
                encoding[name]["_FillValue"] = np.nan
            else:
                encoding[name]["_FillValue"] = None
        elif v.dtype.kind in "iu":
            encoding[name] = {"zlib": True, "complevel": 4, "_FillValue": None}
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, format="NETCDF4", engine="netcdf4", encoding=encoding)
        _write_digest(tmp)


def _write_digest(path: str) -> None:
    """Add to the file ``path`` the global attribute ``data_digest``: the digest of its content as
    :func:`read_dataset` reads it back, so that the reader's computation gives it again bit for bit."""
    import netCDF4

    digest = data_digest(read_dataset(path))
    with netCDF4.Dataset(str(path), "a") as nc:
        nc.setncattr("data_digest", digest)


def write_json(obj: Any, path: str) -> None:
    """Write ``obj`` as JSON atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=2, sort_keys=True, default=_json_default)
        fh.write("\n")


def write_text(text: str, path: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def read_dataset(path: str, check: Callable[[xr.Dataset, str], None] | None = None) -> xr.Dataset:
    """Open a netCDF file, load it into memory, close it and verify its ``data_digest``.

    Parameters
    ----------
    path : str
    check : callable, optional
        ``check(ds, path)``, run before the digest is verified: a reader's own
        check (:func:`analysis.fields.check_units`), whose refusal names the
        cause (a copy converted to other units) where the digest would only
        say that the file changed.

    Raises
    ------
    InputError
        From ``check``, or when the content no longer matches the digest
        written with it (:func:`analysis.states.check_digest`).
    """
    from .states import check_digest

    with xr.open_dataset(path) as ds:
        ds = ds.load()
    if check is not None:
        check(ds, path)
    check_digest(ds, path)
    return ds


def var(dims: tuple[str, ...] | str, data: Any, long_name: str, units: str, **attrs: Any) -> xr.Variable:
    """An ``xr.Variable`` with the CF attributes filled in."""
    return xr.Variable(dims, data, {"long_name": long_name, "units": units, **attrs})
