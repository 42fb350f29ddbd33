"""State files: save and load the particle state of docs/formats.md#state-files.

A state file holds exactly the contract's variables plus what a restart needs
to continue the same trajectory: ``integrator_state`` (the scaled time
derivatives the integrator keeps, stored as they are so a restart with the
same dt is exact to the bit) and ``contact_spring`` (the Cundall–Strack history of
each contact); the global attribute ``code_version`` (:func:`code_version`)
names the simulator code that wrote it.  Files are written to a temporary name and renamed when
complete, so a killed job never leaves a file that looks whole.

This module also holds what every file that ``sim`` writes shares: the
writers over the project's one atomic write (:func:`sim.atomic.atomic_path`:
:func:`atomic_write` for netCDF, :func:`atomic_text` and :func:`atomic_figure`)
and the CF global attributes (:func:`cf_attributes`).
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import time as _time
from pathlib import Path

import numpy as np
import xarray as xr

from . import __version__
from .atomic import atomic_path
from .config import STAGE_SECTIONS, ModelParams, result_settings
from .digest import code_digest, data_digest
from .engine import Simulation
from .scene import BODY_BASE, BODY_SUPPORT, place_base
from .shapes import shapes_from_nodes

PARTICLE_VARS = {
    "x": ("m", "x coordinate of the centre of mass"),
    "y": ("m", "y coordinate of the centre of mass (support surface at y = 0)"),
    "theta": ("rad", "orientation"),
    "vx": ("m/s", "x velocity"),
    "vy": ("m/s", "y velocity"),
    "omega": ("rad/s", "angular velocity"),
    "mass": ("kg", "mass (2D density times area)"),
    "inertia": ("kg m2", "moment of inertia about the centre of mass"),
    "area": ("m2", "polygon area"),
}
CONTACT_VARS = {
    "contact_x": ("m", "x of the force point (midpoint of the contact line)"),
    "contact_y": ("m", "y of the force point (midpoint of the contact line)"),
    "force_x": ("N", "x of the total contact force on contact_i"),
    "force_y": ("N", "y of the total contact force on contact_i"),
    "normal_x": ("1", "x of the unit normal from contact_i towards contact_j"),
    "normal_y": ("1", "y of the unit normal from contact_i towards contact_j"),
    "overlap_area": ("m2", "overlap area A"),
    "contact_spring": ("N", "tangential spring force (Cundall-Strack history) of the "
                            "contact, along t = (-normal_y, normal_x), acting on "
                            "contact_i as -contact_spring * t"),
}


class StateFileError(ValueError):
    """A state file cannot be read, is missing a variable or holds invalid values."""


#: Stages written by a pour itself; a state of any other stage descends from a
#: file and carries that file's identity on (:func:`lineage`).
POUR_STAGES = ("poured", "checkpoint")


def pour_digest(config: dict | None) -> str:
    """The settings digest of a pour: which settings made the pile.

    Parameters
    ----------
    config : dict or None
        The pour's effective configuration (:meth:`sim.config.SimConfig.to_dict`).

    Returns
    -------
    str
        The first 16 hex digits of the SHA-256 of the sorted JSON text of its
        result-relevant settings of the pour's sections
        (``sim.config.STAGE_SECTIONS["pour"]``), which decide its result.
    """
    text = json.dumps(result_settings(config or {}, STAGE_SECTIONS["pour"]), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


#: The global attributes of a pile poured on a table (``pour.line_source: table``,
#: docs/formats.md#state-files), carried on to every stage that descends from it.
TABLE_ATTRS = ("released", "left_table", "table_half_width")


#: What a state file of each stage is, in words, for a refusal (docs/formats.md#stages); any other
#: stage is a probe's.
STAGE_MEANING = {
    "poured": "a state not at rest (the pile as poured)",
    "checkpoint": "a state not at rest (a pour's checkpoint: the pour was stopped before its end)",
    "lastgood": "the last good state of a run stopped by the blow-up detector",
    "bench": "a pile of python -m sim bench",
    "relaxed": "the pile at rest under full gravity",
}


def check_input_stage(path, ds: xr.Dataset, accepted, command: str, takes: str) -> None:
    """Refuse a state file whose stage is not one that ``command`` starts from.

    A file without the attribute ``stage`` (not written by ``sim``) is taken
    as it is: its stage is unknown.

    Parameters
    ----------
    path : path
        The input file (named in the error).
    ds : xarray.Dataset
        It, as read (:func:`read_state`).
    accepted : callable
        ``accepted(stage)`` is true for a stage ``command`` starts from.
    command, takes : str
        The command (``python -m sim relax``) and what it takes, in words.

    Raises
    ------
    StateFileError
        In one line naming the file, its stage and what ``command`` takes.
    """
    stage = ds.attrs.get("stage")
    if stage is not None and not accepted(str(stage)):
        meaning = STAGE_MEANING.get(str(stage), "a probe's state")
        raise StateFileError(f"{path}: its stage is {str(stage)!r}, {meaning}; {command} takes {takes}")


def lineage(ds: xr.Dataset) -> dict:
    """The identity a stage run on the state file ``ds`` carries on into its own file.

    ``protocol``, ``seed`` and ``pour_digest`` of the pile and, for a pile
    poured on a table, its :data:`TABLE_ATTRS` (those the file has), and
    ``relaxed_digest``: the ``data_digest`` of the relaxed state the
    new stage descends from, the file's own when it is that relaxed state, else
    the one it carries (none when it has none: a poured pile).

    Parameters
    ----------
    ds : xarray.Dataset
        The input state file, as read (:func:`read_state`).

    Returns
    -------
    dict
        Global attributes for :func:`save_state`.
    """
    a = ds.attrs
    out = {"protocol": a.get("protocol", ""), "seed": int(a.get("seed", -1))}
    for name in ("pour_digest",) + TABLE_ATTRS:
        if name in a:
            out[name] = a[name]
    relaxed = a.get("data_digest") if a.get("stage") == "relaxed" else a.get("relaxed_digest")
    if relaxed:
        out["relaxed_digest"] = relaxed
    return out


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """The code version recorded in every state file: :func:`sim.digest.code_digest`
    of ``sim/*.py``, the code digest the workflow gives the simulation rules.
    A pour resumes a checkpoint only if it was written by the same code.

    Returns
    -------
    str
        16 hex digits.
    """
    return code_digest(Path(__file__).parent)


#: CF version named by the ``Conventions`` attribute of every netCDF file of ``sim``.
CONVENTIONS = "CF-1.10"


def cf_attributes(title: str, config: dict | None, history: str,
                  source: str | None = None) -> dict:
    """The global attributes docs/formats.md#conventions asks of every netCDF file.

    Parameters
    ----------
    title : str
    config : dict or None
        Effective configuration of the run (stored as sorted JSON text).
    history : str
        What wrote the file (a command line, a function); it follows the UTC
        time of writing.
    source : str, optional
        Added in parentheses after the package name and version.

    Returns
    -------
    dict
        ``Conventions`` (:data:`CONVENTIONS`), ``title``, ``source``,
        ``history``, ``config``, ``software`` (:func:`software_versions`).
    """
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "source": f"polypile sim {__version__}" + (f" ({source})" if source else ""),
        "history": f"{_time.strftime('%Y-%m-%dT%H:%M:%SZ', _time.gmtime())} {history}".strip(),
        "config": json.dumps(config or {}, sort_keys=True),
        "software": software_versions(),
    }


@functools.lru_cache(maxsize=1)
def software_versions() -> str:
    """``python 3.11.7, numpy 2.4.6, numba 0.68.1, ...``: what decides the bits of a state file."""
    import platform
    from importlib.metadata import version

    return ", ".join([f"python {platform.python_version()}"]
                     + [f"{name} {version(name)}" for name in ("numpy", "numba", "llvmlite", "xarray", "netCDF4")])


def atomic_write(ds: xr.Dataset, path) -> None:
    """Write a dataset to ``path`` (netCDF-4) atomically (:func:`sim.atomic.atomic_path`).

    Parameters
    ----------
    ds : xarray.Dataset
    path : str or Path
    """
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4")


def atomic_text(text: str, path) -> None:
    """Write ``text`` to ``path`` atomically (:func:`sim.atomic.atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_figure(fig, path, **kwargs) -> None:
    """Save a matplotlib figure to ``path`` atomically (:func:`sim.atomic.atomic_path`).

    The format is that of ``path``'s suffix (the temporary name keeps it)
    unless ``format`` is given; ``kwargs`` go to ``fig.savefig``.
    """
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)


def _kept_contacts(c: dict, keep) -> dict:
    """The contacts `c` (:meth:`Simulation.contacts`) between the particles
    `keep` (a mask) or with a body, their particle indices renumbered as the
    kept particles are (in their order)."""
    number = np.cumsum(keep) - 1
    rows = keep[c["i"]] & ((c["j"] < 0) | keep[np.maximum(c["j"], 0)])
    out = {name: values[rows] for name, values in c.items()}
    out["i"] = number[out["i"]]
    out["j"] = np.where(out["j"] < 0, out["j"], number[np.maximum(out["j"], 0)])
    return out


def state_dataset(sim: Simulation, config: dict | None = None, keep=None,
                  **attrs) -> xr.Dataset:
    """The docs/formats.md#state-files dataset of a simulation's current state.

    Parameters
    ----------
    sim : Simulation
    config : dict, optional
        Effective configuration of the run (stored as JSON text).
    keep : numpy.ndarray of bool, optional
        The particles to write (default all): the others are left out with
        their contacts, and the kept ones numbered in their order (a table's
        pile without the particles that left the table, :mod:`sim.pour`).
    **attrs
        Further global attributes (``stage``, ``protocol``, ``seed``, ...).  A
        pour's own stages (:data:`POUR_STAGES`) get ``pour_digest`` of
        ``config`` (:func:`pour_digest`) unless given; later stages carry their
        input's (:func:`lineage`).

    Returns
    -------
    xarray.Dataset
    """
    keep = np.ones(sim.n, bool) if keep is None else np.asarray(keep, bool)
    sh = sim.shapes
    pos = sim.position[keep]
    vel = sim.velocity[keep]
    nodes = np.repeat(keep, sh.node_count[:sim.n])
    data = {
        "x": pos[:, 0], "y": pos[:, 1], "theta": sim.theta[keep],
        "vx": vel[:, 0], "vy": vel[:, 1], "omega": sim.omega[keep],
        "mass": sh.mass[:sim.n][keep], "inertia": sh.inertia[:sim.n][keep],
        "area": sh.area[:sim.n][keep],
    }
    ds = xr.Dataset()
    for name, (units, long_name) in PARTICLE_VARS.items():
        ds[name] = xr.DataArray(np.asarray(data[name], float), dims="particle",
                                attrs={"units": units, "long_name": long_name})
    ds["node_count"] = xr.DataArray(sh.node_count[:sim.n][keep].astype(np.int32), dims="particle",
                                    attrs={"units": "1", "long_name": "corners of each "
                                           "polygon", "sample_dimension": "node"})
    off = int(sh.node_offset[sim.n])
    ds["node_x"] = xr.DataArray(sh.node_x[:off][nodes], dims="node", attrs={
        "units": "m", "long_name": "corner x in the body frame (centre of mass, theta = 0), "
        "counter-clockwise, polygon after polygon"})
    ds["node_y"] = xr.DataArray(sh.node_y[:off][nodes], dims="node", attrs={
        "units": "m", "long_name": "corner y in the body frame"})
    c = _kept_contacts(sim.contacts(), keep)
    ds["contact_i"] = xr.DataArray(c["i"].astype(np.int32), dims="contact",
                                   attrs={"units": "1", "long_name": "particle index i"})
    ds["contact_j"] = xr.DataArray(c["j"].astype(np.int32), dims="contact", attrs={
        "units": "1", "long_name": "particle index j; -1 support, -2 left wall, "
        "-3 right wall" + ("" if sim.base is None else f", {BODY_BASE} - b base polygon b")})
    values = {"contact_x": c["x"], "contact_y": c["y"], "force_x": c["fx"],
              "force_y": c["fy"], "normal_x": c["nx"], "normal_y": c["ny"],
              "overlap_area": c["area"], "contact_spring": c["spring"]}
    for name, (units, long_name) in CONTACT_VARS.items():
        ds[name] = xr.DataArray(values[name], dims="contact",
                                attrs={"units": units, "long_name": long_name})
    ds["contact_witness"] = xr.DataArray(
        c["witness"].astype(np.int32), dims=("contact", "witness"), attrs={
            "units": "1", "long_name": "edges of i and j crossing where i's boundary enters "
            "j and where it leaves (-1: none); the narrow phase's warm start for the next "
            "step (restart data)"})
    ds["integrator_state"] = xr.DataArray(
        sim.scaled_derivatives()[:, :, keep], dims=("derivative", "dof", "particle"),
        coords={"dof": ["x", "y", "theta"]},
        attrs={"units": "m (rad for theta)", "long_name": "scaled time derivatives "
               "dt^k/k! d^k q/dt^k of x, y, theta kept by the integrator, with dt the "
               "global attribute dt (restart data)"})
    if sim.base is not None:
        _add_base(ds, sim.base)
    m = sim.model
    g = float(np.hypot(*sim.gravity))
    walls = sim.walls if sim.walls is not None else (np.nan, np.nan)
    ds.attrs = {
        **cf_attributes("Particle state of a 2D pile of soft convex polygons", config,
                        "written by sim.io.state_dataset"),
        "code_version": code_version(),
        "time": float(sim.time), "step": int(sim.step),
        "gravity": g, "gravity_x": sim.gravity[0], "gravity_y": sim.gravity[1],
        "youngs_modulus": m.youngs_modulus, "damping": m.damping, "friction": m.friction,
        "support_friction": m.support_friction, "density": m.density,
        "dt": float(sim.dt), "integrator": m.integrator,
        "support": int(BODY_SUPPORT in sim.body_ids.tolist()),
        "wall_left": float(walls[0]), "wall_right": float(walls[1]),
        "rotate": int(sim.rotate),
    }
    ds.attrs.update(attrs)
    if attrs.get("stage") in POUR_STAGES and "pour_digest" not in attrs:
        ds.attrs["pour_digest"] = pour_digest(config)
    return ds


#: The variables of a rough base (docs/formats.md#state-files), with their
#: dimension, units and meaning.
BASE_VARS = {
    "base_x": ("base_polygon", "m", "x of the centre of mass of each base polygon"),
    "base_y": ("base_polygon", "m", "y of the centre of mass of each base polygon"),
    "base_theta": ("base_polygon", "rad", "orientation of each base polygon"),
    "base_node_count": ("base_polygon", "1", "corners of each base polygon"),
    "base_node_x": ("base_node", "m", "base polygon corner x in the body frame, "
                    "counter-clockwise, polygon after polygon"),
    "base_node_y": ("base_node", "m", "base polygon corner y in the body frame"),
}


def _add_base(ds: xr.Dataset, base) -> None:
    """Add the :data:`BASE_VARS` of `base` (:class:`sim.scene.RoughBase`) to `ds`."""
    values = {"base_x": base.x, "base_y": base.y, "base_theta": base.theta,
              "base_node_count": base.shapes.node_count.astype(np.int32),
              "base_node_x": base.shapes.node_x, "base_node_y": base.shapes.node_y}
    for name, (dim, units, long_name) in BASE_VARS.items():
        ds[name] = xr.DataArray(values[name], dims=dim,
                                attrs={"units": units, "long_name": long_name})


def _base_of(ds: xr.Dataset, density: float):
    """The :class:`sim.scene.RoughBase` a state file records, or None."""
    if "base_x" not in ds:
        return None
    shapes = shapes_from_nodes(ds["base_node_count"].values.astype(np.int64),
                               ds["base_node_x"].values, ds["base_node_y"].values, density)
    return place_base(shapes, ds["base_x"].values, ds["base_y"].values, ds["base_theta"].values)


def save_state(sim: Simulation, path, config: dict | None = None, keep=None, **attrs) -> None:
    """Write the simulation's state (of the particles `keep`, default all) to
    ``path`` atomically (see :func:`state_dataset`), with the digest of its
    data (:func:`data_digest`)."""
    ds = state_dataset(sim, config, keep, **attrs)
    ds.attrs["data_digest"] = data_digest(ds)
    atomic_write(ds, path)


REQUIRED = list(PARTICLE_VARS) + ["node_count", "node_x", "node_y", "contact_i",
                                  "contact_j", "integrator_state"] + list(CONTACT_VARS)


def read_state(path) -> xr.Dataset:
    """Open and validate a state file (every variable present, its data those
    written with it (:func:`data_digest`; a file without one is read with a
    warning that it is unverified), finite).

    Raises
    ------
    StateFileError
        Naming the file, the variable and the problem.
    """
    path = Path(path)
    if not path.exists():
        raise StateFileError(f"state file {path} does not exist")
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ds = ds.load()
    except (OSError, ValueError, RuntimeError, KeyError) as exc:
        raise StateFileError(f"state file {path} cannot be read ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}): "
                             "truncated or not a netCDF file; delete it and run the step "
                             "that writes it again") from None
    has_base = any(v in ds for v in BASE_VARS)
    required = REQUIRED + (list(BASE_VARS) if has_base else [])
    missing = [v for v in required if v not in ds]
    if missing:
        raise StateFileError(f"state file {path}: missing variable(s) {missing}")
    for v in required:
        vals = np.asarray(ds[v].values, float)
        if not np.all(np.isfinite(vals)):
            k = int(np.argmax(~np.isfinite(vals.ravel())))
            raise StateFileError(f"state file {path}: variable {v} holds NaN or Inf "
                                 f"(first at flat index {k})")
    if "data_digest" not in ds.attrs:
        logging.getLogger("sim").warning(
            "state file %s: no data_digest attribute, so its data are unverified (every state "
            "the simulator writes has one: this file was written before digests, by other code, "
            "or had it removed); read as it is", path)
    elif data_digest(ds) != ds.attrs["data_digest"]:
        raise StateFileError(f"state file {path}: its data do not match the digest written with them "
                             "(attribute data_digest): the file was damaged after it was written; delete "
                             "it and run the step that writes it again")
    n = ds.sizes["particle"]
    if int(ds["node_count"].sum()) != ds.sizes["node"]:
        raise StateFileError(f"state file {path}: node_count sums to "
                             f"{int(ds['node_count'].sum())} but there are "
                             f"{ds.sizes['node']} nodes")
    ci = ds["contact_i"].values
    cj = ds["contact_j"].values
    lowest = BODY_BASE - ds.sizes["base_polygon"] + 1 if has_base else -3
    if ci.size and (ci.min() < 0 or ci.max() >= n or cj.max() >= n or cj.min() < lowest):
        raise StateFileError(f"state file {path}: contact indices outside 0..{n - 1} "
                             "(contact_j may also be -1, -2, -3"
                             + (f", or {BODY_BASE} .. {lowest} for the base polygons)"
                                if has_base else ")"))
    return ds


def model_from_attrs(ds: xr.Dataset) -> ModelParams:
    """The model parameters a state file was made with (its dt included)."""
    a = ds.attrs
    return ModelParams(youngs_modulus=float(a["youngs_modulus"]),
                       damping=float(a["damping"]), friction=float(a["friction"]),
                       support_friction=float(a["support_friction"]),
                       density=float(a["density"]), integrator=str(a["integrator"]),
                       dt=float(a["dt"]))


def load_simulation(path, model: ModelParams | None = None, capacity_shapes=None):
    """Rebuild a :class:`Simulation` from a state file to continue its run.

    Parameters
    ----------
    path : str or Path
    model : ModelParams, optional
        Parameters to continue with (default: those stored in the file,
        including its time step).  With ``model.dt`` None the file's dt is kept
        so the trajectory continues unchanged.
    capacity_shapes : Shapes, optional
        Shapes of a larger set whose first particles are the file's (a pour
        resumed from a checkpoint); their corners must match the file's.

    Returns
    -------
    (Simulation, xarray.Dataset)
    """
    ds = read_state(path)
    stored = model_from_attrs(ds)
    if model is None:
        model = stored
    elif model.dt is None:
        model = ModelParams(**{**model.__dict__, "dt": stored.dt})
    n = ds.sizes["particle"]
    node_count = ds["node_count"].values.astype(np.int64)
    shapes = shapes_from_nodes(node_count, ds["node_x"].values, ds["node_y"].values,
                               model.density)
    if capacity_shapes is not None:
        off = int(shapes.node_offset[n])
        if not (np.array_equal(capacity_shapes.node_count[:n], node_count) and
                np.allclose(capacity_shapes.node_x[:off], shapes.node_x, rtol=0,
                            atol=1e-12 * float(np.max(shapes.radius)))):
            raise StateFileError(f"state file {path}: its particles are not the first {n} "
                                 "of the requested set (different seed or shapes?)")
        shapes = capacity_shapes
    walls = None
    if np.isfinite(ds.attrs.get("wall_left", np.nan)):
        walls = (float(ds.attrs["wall_left"]), float(ds.attrs["wall_right"]))
    sim = Simulation(shapes, model, gravity=(float(ds.attrs["gravity_x"]),
                                             float(ds.attrs["gravity_y"])),
                     support=bool(ds.attrs.get("support", 1)), walls=walls,
                     rotate=bool(ds.attrs.get("rotate", 1)),
                     base=_base_of(ds, model.density))
    sim.set_scaled_derivatives(ds["integrator_state"].values, float(ds.attrs["dt"]))
    sim.time = float(ds.attrs["time"])
    sim.step = int(ds.attrs["step"])
    sim.set_springs(ds["contact_i"].values.astype(np.int64),
                    ds["contact_j"].values.astype(np.int64),
                    ds["contact_spring"].values,
                    ds["contact_witness"].values.astype(np.int64)
                    if "contact_witness" in ds else None)
    return sim, ds
