"""The project's digests: of a package's sources, and of a file's content.

:func:`code_digest` is the one rule for every code digest: the simulator
records it for ``sim/`` in every state file (:func:`sim.io.code_version`), a
pour resumes a checkpoint only under the same one, the workflow carries it
for ``sim/`` and ``analysis/`` as the param ``code`` of its rules (an edit
re-runs the jobs that run that code), and ``python -m sim --version`` and
``python -m analysis --version`` print it.  The Numba cache is named by the
same rule over the kernels' sources alone (:func:`sim.kernel_cache.source_digest`).

:func:`data_digest` is the one rule for the ``data_digest`` attribute that
every netCDF file of the simulator and of the analysis carries
(docs/formats.md#conventions): each package writes it and checks it on
reading, by this function.
"""

import hashlib
from pathlib import Path

import numpy as np


def files_digest(files, root) -> str:
    """SHA-256 (hex) of files: for each, in the order given, its path relative
    to `root` (with ``/``), a NUL byte and its content.

    Parameters
    ----------
    files : iterable of path-like
        Files under `root`.
    root : path-like

    Returns
    -------
    str
        64 hex digits.
    """
    digest = hashlib.sha256()
    for path in files:
        digest.update(Path(path).relative_to(root).as_posix().encode() + b"\0" + Path(path).read_bytes())
    return digest.hexdigest()


def code_digest(folder) -> str:
    """The first 16 hex digits of :func:`files_digest` of the ``*.py`` files of
    `folder`, in sorted order; the files of subfolders do not count.
    Computed from the files in `folder`, not from an imported package, which
    need not be the one there.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    str
    """
    return files_digest(sorted(Path(folder).glob("*.py")), folder)[:16]


def data_digest(ds) -> str:
    """SHA-256 of a dataset's content: its data variables (name, dtype, shape,
    bytes) and its global attributes but ``data_digest`` (name and value),
    each in the order of their names.

    Written with every state file and every analysis file as the attribute
    ``data_digest`` and checked when they are read, so that bytes changed
    inside a file after it was written (which netCDF reads without complaint
    when they fall in the data or an attribute's value) are named as damage
    instead of passing as a result.  A data variable enters as
    ``name|dtype|shape|`` and its C-order bytes; an attribute as ``@name|``
    and its value: a text as UTF-8, a number as its 8 bytes (int64 or
    float64, as netCDF stores a Python int or float).

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset as read (its values loaded).

    Returns
    -------
    str
        64 hex digits.
    """
    h = hashlib.sha256()
    for name in sorted(ds.data_vars):
        a = np.ascontiguousarray(ds[name].values)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    for name in sorted(k for k in ds.attrs if k != "data_digest"):
        value = ds.attrs[name]
        a = np.asarray(value)
        raw = (str(value).encode() if a.dtype.kind in "US" else
               a.astype(np.float64 if a.dtype.kind == "f" else np.int64).tobytes())
        h.update(f"@{name}|".encode() + raw)
    return h.hexdigest()
