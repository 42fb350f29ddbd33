"""Reading particle-state files through the data contract (docs/formats.md#state-files).

The analysis never imports the simulator's model: everything it knows about a
pile comes from these files (of ``sim`` it shares only the digest of a file's
content, :func:`sim.digest.data_digest`, which both packages write and check). :func:`load_state` checks names, dimensions, finiteness
and index ranges and raises :class:`~analysis.errors.StateError` with the file,
variable and first offending index, before any computation starts.
:func:`check_identity` checks that a file is the pile and stage the argument
naming it means, :func:`check_distinct_piles` that an ensemble's files are of
one protocol and each pile once (docs/formats.md#which-file-is-which).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from sim.digest import data_digest

from .errors import InputError, StateError

PARTICLE_VARS = ("x", "y", "theta", "vx", "vy", "omega", "mass", "inertia", "area", "node_count")
NODE_VARS = ("node_x", "node_y")
CONTACT_VARS = ("contact_i", "contact_j", "contact_x", "contact_y", "force_x", "force_y",
                "normal_x", "normal_y", "overlap_area")
INTEGER_VARS = ("node_count", "contact_i", "contact_j")
#: ``contact_j`` of the first polygon of a rough base (docs/formats.md#state-files);
#: polygon b is ``BASE_FIRST - b``.
BASE_FIRST = -4
REQUIRED_ATTRS = ("gravity",)
DIMS = {**{v: "particle" for v in PARTICLE_VARS}, **{v: "node" for v in NODE_VARS},
        **{v: "contact" for v in CONTACT_VARS}}


@dataclass(frozen=True)
class State:
    """One particle state as plain numpy arrays (names as in docs/formats.md#state-files)."""

    path: str
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    omega: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    area: np.ndarray
    node_count: np.ndarray
    node_x: np.ndarray
    node_y: np.ndarray
    contact_i: np.ndarray
    contact_j: np.ndarray
    contact_x: np.ndarray
    contact_y: np.ndarray
    force_x: np.ndarray
    force_y: np.ndarray
    normal_x: np.ndarray
    normal_y: np.ndarray
    overlap_area: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def n_particles(self) -> int:
        return int(self.x.size)

    @property
    def gravity(self) -> float:
        """Magnitude of gravity at this stage (m/s²); it points along −y."""
        return float(self.attrs["gravity"])

    @property
    def gravity_vector(self) -> np.ndarray:
        """Gravity as a vector (m/s²): the attributes ``gravity_x``, ``gravity_y``
        when the file has both (tilted-gravity probes), else ``(0, -gravity)``."""
        if "gravity_x" in self.attrs and "gravity_y" in self.attrs:
            return np.array([float(self.attrs["gravity_x"]), float(self.attrs["gravity_y"])])
        return np.array([0.0, -self.gravity])

    @property
    def support(self) -> np.ndarray:
        """Boolean mask of the contacts with the support (``contact_j == -1``)."""
        return self.contact_j < 0

    def world_vertices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Polygon corners in the lab frame, padded to ``(n_particles, k_max)``.

        Each row repeats its last corner up to ``k_max`` (a zero-length edge,
        harmless for convex-polygon tests). Returns ``(vx, vy, node_count)``.
        """
        counts = self.node_count.astype(np.int64)
        kmax = int(counts.max()) if counts.size else 0
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]) if counts.size else counts
        k = np.minimum(np.arange(kmax)[None, :], counts[:, None] - 1)
        idx = offsets[:, None] + k
        bx, by = self.node_x[idx], self.node_y[idx]
        c, s = np.cos(self.theta)[:, None], np.sin(self.theta)[:, None]
        return self.x[:, None] + c * bx - s * by, self.y[:, None] + s * bx + c * by, counts


def _fail(path: str, msg: str) -> StateError:
    return StateError(f"{path}: {msg}")


def check_digest(ds: xr.Dataset, path: str, error: type[InputError] = InputError) -> None:
    """Refuse a file whose content no longer matches the ``data_digest`` written with it.

    Every file the simulator or the analysis writes carries one
    (docs/formats.md#conventions); a file without one (written before it
    existed, or by hand) passes.

    Parameters
    ----------
    ds : xarray.Dataset
        The file as read.
    path : str
        The file, named in the error.
    error : type
        The exception to raise: :class:`StateError` for state files.

    Raises
    ------
    InputError
        (or ``error``) Naming the file: its data or global attributes were
        changed after it was written (:func:`sim.digest.data_digest`).
    """
    if "data_digest" in ds.attrs and data_digest(ds) != ds.attrs["data_digest"]:
        raise error(f"{path}: its content does not match the digest written with it (attribute data_digest): "
                    "the file was damaged after it was written; delete it and run the step that writes it again")


def state_from_dataset(ds: xr.Dataset, path: str = "<dataset>") -> State:
    """Validate a contract dataset and return it as a :class:`State`.

    The fixed polygons of a rough base (dimension ``base_polygon``) are no
    particles of the pile: their contacts (``contact_j`` from
    :data:`BASE_FIRST` down) become contacts with the support
    (``contact_j = -1``), so that the base pressure is the pile's force on
    the base layer and the fields see it as the support.

    A file written with a ``data_digest`` (every state the simulator writes)
    must still match it (:func:`sim.digest.data_digest`): bytes changed inside the
    file after it was written are named as damage, not read as a pile.
    """
    missing = [v for v in DIMS if v not in ds.variables]
    if missing:
        raise _fail(path, f"missing variable(s) {', '.join(missing)} required by docs/formats.md#state-files")
    arrays: dict[str, np.ndarray] = {}
    for name, dim in DIMS.items():
        da = ds[name]
        if da.dims != (dim,):
            raise _fail(path, f"variable {name!r} has dimensions {da.dims}, expected ({dim!r},)")
        a = np.asarray(da.values)
        if not (np.issubdtype(a.dtype, np.number)):
            raise _fail(path, f"variable {name!r} has non-numeric type {a.dtype}")
        bad = ~np.isfinite(a) if np.issubdtype(a.dtype, np.floating) else np.zeros(a.shape, bool)
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise _fail(path, f"variable {name!r} contains {int(bad.sum())} NaN/inf value(s) "
                              f"(first at {dim} index {first}); a state file must be finite everywhere")
        if name in INTEGER_VARS:
            if np.issubdtype(a.dtype, np.floating):
                if np.any(a != np.round(a)):
                    raise _fail(path, f"variable {name!r} must hold integers")
            a = a.astype(np.int64)
        else:
            a = a.astype(np.float64)
        arrays[name] = a
    check_digest(ds, path, StateError)
    for a in REQUIRED_ATTRS:
        if a not in ds.attrs:
            raise _fail(path, f"missing global attribute {a!r} required by docs/formats.md#state-files")
    try:
        g = float(ds.attrs["gravity"])
    except (TypeError, ValueError):
        raise _fail(path, f"global attribute 'gravity' = {ds.attrs['gravity']!r} is not a number") from None
    if not np.isfinite(g) or g < 0:
        raise _fail(path, f"global attribute 'gravity' = {g!r} must be a finite magnitude >= 0 (m/s²)")
    n = arrays["x"].size
    if n == 0:
        raise _fail(path, "the state holds no particles")
    if np.any(arrays["mass"] <= 0) or np.any(arrays["area"] <= 0):
        raise _fail(path, "'mass' and 'area' must be positive for every particle")
    counts = arrays["node_count"]
    if np.any(counts < 3):
        raise _fail(path, f"'node_count' must be >= 3 (first bad particle {int(np.flatnonzero(counts < 3)[0])})")
    if counts.sum() != arrays["node_x"].size:
        raise _fail(path, f"sum of node_count ({int(counts.sum())}) differs from the node dimension "
                          f"({arrays['node_x'].size})")
    ci, cj = arrays["contact_i"], arrays["contact_j"]
    bad = (ci < 0) | (ci >= n)
    if bad.any():
        raise _fail(path, f"contact_i out of range [0, {n}) at contact {int(np.flatnonzero(bad)[0])}")
    n_base = ds.sizes.get("base_polygon", 0)
    on_base = (cj <= BASE_FIRST) & (cj > BASE_FIRST - n_base)
    bad = ((cj < -1) & ~on_base) | (cj >= n)
    if bad.any():
        allowed = f"[-1, {n})" + (f" or [{BASE_FIRST - n_base + 1}, {BASE_FIRST}] (base polygons)"
                                  if n_base else "")
        raise _fail(path, f"contact_j out of range {allowed} at contact {int(np.flatnonzero(bad)[0])}")
    arrays["contact_j"] = np.where(on_base, -1, cj)
    bad = ci == cj
    if bad.any():
        raise _fail(path, f"contact {int(np.flatnonzero(bad)[0])} joins a particle to itself")
    for a in ("gravity_x", "gravity_y"):
        if a in ds.attrs:
            try:
                ok = np.isfinite(float(ds.attrs[a]))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise _fail(path, f"global attribute {a!r} = {ds.attrs[a]!r} is not a finite number")
    attrs = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in ds.attrs.items()}
    return State(path=path, attrs=attrs, **arrays)


def load_state(path: str) -> State:
    """Read and validate one particle-state file (docs/formats.md#state-files)."""
    try:
        with xr.open_dataset(path, decode_times=False) as ds:
            ds = ds.load()
    except FileNotFoundError:
        raise StateError(f"{path}: no such file") from None
    except (OSError, ValueError) as exc:
        raise StateError(f"{path}: cannot be read as netCDF ({exc})") from exc
    return state_from_dataset(ds, str(path))


def check_same_particles(a: State, b: State) -> None:
    """Refuse two stages that do not hold the same particles in the same order."""
    if a.n_particles != b.n_particles:
        raise StateError(f"{b.path}: holds {b.n_particles} particles but {a.path} holds {a.n_particles}; "
                         "the two stages of one pile must hold the same particles")
    if not (np.allclose(a.mass, b.mass, rtol=1e-9, atol=0) and np.allclose(a.area, b.area, rtol=1e-9, atol=0)):
        raise StateError(f"{b.path}: particle masses/areas differ from {a.path}; "
                         "the two stages of one pile must hold the same particles in the same order")


#: Stages of a gravity reduction of a relaxed pile (docs/formats.md#stages), a regular expression.
REDUCTION_STAGES = r"reduced(\d\d)?"
#: Stages of every probe of a relaxed pile, a regular expression.
PROBE_STAGES = r"reduced(\d\d)?|tilt[pm]\d\d|restored|stretched"
#: The global attributes that say which pile a file is of and where it comes
#: from (docs/formats.md#state-files): its identity.
IDENTITY = ("protocol", "seed", "stage", "pour_digest", "relaxed_digest", "data_digest")


def identity(attrs: dict[str, Any]) -> dict[str, str]:
    """The identity attributes (:data:`IDENTITY`) a state or fields file has, as text.

    An attribute the file lacks or holds empty (files written before it
    existed, hand-made ones) is left out: unknown, so nothing is checked
    against it.
    """
    return {k: str(attrs[k]) for k in IDENTITY if str(attrs.get(k, "")) != ""}


def pile_name(ident: dict[str, str]) -> str:
    """``wedge seed 1 (pour digest 0123abcd4567ef89)``: a pile as far as its identity names it."""
    name = f"{ident.get('protocol', '(protocol unknown)')} seed {ident.get('seed', '(unknown)')}"
    return name + (f" (pour digest {ident['pour_digest']})" if "pour_digest" in ident else "")


def pile_attributes(relaxed: State) -> dict[str, str]:
    """The identity a file computed from the relaxed state ``relaxed`` carries (fields, probe increments).

    ``protocol`` and ``seed`` (empty where unknown), and where ``relaxed``
    has them ``pour_digest`` and ``relaxed_digest``: its ``data_digest``,
    which names the very state the file was computed from.
    """
    ident = identity(relaxed.attrs)
    out = {"protocol": ident.get("protocol", ""), "seed": ident.get("seed", "")}
    if "pour_digest" in ident:
        out["pour_digest"] = ident["pour_digest"]
    if "data_digest" in ident:
        out["relaxed_digest"] = ident["data_digest"]
    return out


def check_identity(path: str, attrs: dict[str, Any], argument: str, stages: str, takes: str,
                   relaxed: tuple[str, dict[str, Any]] | None = None) -> None:
    """Refuse a file that is not what the command-line argument naming it means.

    Every reader of state files checks each input with this before it
    computes anything.  Only what the file carries is checked
    (:func:`identity`): a file without a ``stage`` passes the stage check.

    Parameters
    ----------
    path : str
    attrs : dict
        The file's global attributes.
    argument : str
        The argument that named it (``--reduced``; ``--probes reduced=``
        when the path follows it without a space), in the error.
    stages : str
        A regular expression that the whole of the file's ``stage`` must match
        (:data:`REDUCTION_STAGES`, :data:`PROBE_STAGES`, ``"relaxed"``).
    takes : str
        What ``argument`` takes, in words, for the error.
    relaxed : (str, dict), optional
        Path and attributes of the relaxed state (``--relaxed``) the file must
        be a later stage of: another file with another ``data_digest``, of the
        same pile (``protocol``, ``seed``, ``pour_digest``), and descending
        from that very state (its ``relaxed_digest`` that state's
        ``data_digest``).

    Raises
    ------
    StateError
        In one line naming the argument, the file, what it is and what was expected.
    """
    ident = identity(attrs)
    named = f"{argument}{path}" if argument.endswith("=") else f"{argument} {path}"
    stage = ident.get("stage")
    if stage is not None and not re.fullmatch(stages, stage):
        raise StateError(f"{named}: its stage is {stage!r}; {argument} takes {takes}")
    if relaxed is None:
        return
    relaxed_path, parent = relaxed[0], identity(relaxed[1])
    same_file = os.path.exists(path) and os.path.exists(relaxed_path) and os.path.samefile(path, relaxed_path)
    if same_file or ident.get("data_digest", "-") == parent.get("data_digest"):
        raise StateError(f"{named}: the same state as --relaxed {relaxed_path}; {argument} takes {takes}")
    differ = [k for k in ("protocol", "seed", "pour_digest") if _known_and_differ(ident, parent, k)]
    if differ:
        raise StateError(f"{named}: a state of pile {pile_name(ident)}, but --relaxed {relaxed_path} is of pile "
                         f"{pile_name(parent)} (another {' and '.join(differ)}); {argument} takes {takes}")
    if "relaxed_digest" in ident and "data_digest" in parent and ident["relaxed_digest"] != parent["data_digest"]:
        raise StateError(f"{named}: it descends from the relaxed state with data_digest "
                         f"{ident['relaxed_digest'][:16]}..., not from --relaxed {relaxed_path} (data_digest "
                         f"{parent['data_digest'][:16]}...); {argument} takes {takes}")


def check_distinct_piles(files: list[tuple[str, dict[str, Any]]], argument: str) -> None:
    """Refuse an ensemble whose files mix protocols or hold one pile twice.

    Two files are of the same pile when they descend from the same relaxed
    state (``relaxed_digest``), or when their ``protocol`` and ``seed`` agree
    and their ``pour_digest`` does too or is unknown in either (a pile's
    shapes and pour follow from its seed and settings alone).

    Parameters
    ----------
    files : list of (str, dict)
        Each file's path and global attributes (state, fields or probe files).
    argument : str
        The argument that named them (``--fields``), in the error.

    Raises
    ------
    InputError
        In one line naming both files and their piles.
    """
    seen: list[tuple[str, dict[str, str]]] = []
    for path, attrs in files:
        ident = identity(attrs)
        for other_path, other in seen:
            if _known_and_differ(ident, other, "protocol"):
                raise InputError(f"{argument} {path}: pile {pile_name(ident)}, but {other_path} is pile "
                                 f"{pile_name(other)}; an ensemble is of one protocol: give the files of one")
            same_pile = (all(k in ident and ident[k] == other.get(k) for k in ("protocol", "seed"))
                         and not _known_and_differ(ident, other, "pour_digest"))
            if same_pile or ("relaxed_digest" in ident and ident["relaxed_digest"] == other.get("relaxed_digest")):
                raise InputError(f"{argument} {path}: pile {pile_name(ident)}, the same pile as {other_path}; an "
                                 "ensemble counts each pile once: give each pile's file once")
        seen.append((path, ident))


def _known_and_differ(a: dict[str, str], b: dict[str, str], key: str) -> bool:
    """Whether both identities name ``key`` and name it differently."""
    return key in a and key in b and a[key] != b[key]
