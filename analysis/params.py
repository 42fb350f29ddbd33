"""The ``analysis`` section of the configuration: defaults and validation.

The keys, defaults and ranges are those of the JSON schema
``analysis/params.schema.yaml`` (:data:`SCHEMA_FILE`), which ships inside the
package and is read when this module is imported: the workflow's
configuration schema refers to it and validates against it before anything
runs, and :data:`DEFAULTS` are built from it and every setting is checked
against it by jsonschema (:func:`_check_setting` on :mod:`sim.schema`), so
both agree by construction (tests/test_settings_single_source.py probes it).
What a schema cannot express (an ordered grid, a grid of at most 10^6 points, the raster pixel
against the RVE size, the bins inside the base-pressure range, the order of the history windows) is checked in
:func:`resolve_params`.

The command line receives the section as JSON text (``--params``); it is
validated here before any long computation, and every error names the
setting, the offending value and what is allowed.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import yaml

from sim.schema import BOUND_OPS, schema_error, schema_types
from sim.settings_file import SettingsDumper, SettingsFileError, read_settings

from .errors import ParamError
from .solid_fraction import RASTER_BYTES_PER_PIXEL, raster_shape

#: The largest raster of the solid fraction the settings may ask for (bytes):
#: half the 2 GB a workflow analysis job asks for.
MAX_RASTER_BYTES = 2**30

#: The JSON schema (YAML) of the ``analysis`` section: the source of every
#: key, default and bound below.
SCHEMA_FILE = Path(__file__).resolve().parent / "params.schema.yaml"

# the section's schema, $defs/analysis (the file's root refers to it)
_SCHEMA = yaml.safe_load(SCHEMA_FILE.read_text(encoding="utf-8"))["$defs"]["analysis"]

#: Every setting's default, ``{section: {key: value}}`` (the schema's ``default``).
DEFAULTS: dict[str, Any] = {
    section: {key: copy.deepcopy(prop["default"]) for key, prop in sub["properties"].items()}
    for section, sub in _SCHEMA["properties"].items()
}

#: Each section's schema, ``{section: schema}``.
_SECTIONS: dict[str, dict[str, Any]] = _SCHEMA["properties"]

_NOT = {"number": "is not a finite number", "integer": "is not an integer",
        "boolean": "is not true/false", "string": "is not a string"}


def _check_setting(name: str, value: Any, schema: dict[str, Any]) -> None:
    """The analysis's one schema checker: ``value`` of the setting ``analysis.name``
    against its JSON schema (:func:`sim.schema.schema_error` decides).

    Raises
    ------
    ParamError
        Naming the setting, its value and what is allowed.
    """
    error = schema_error(value, schema)
    if error is None:
        return
    (kind,) = [k for k in schema_types(schema) if k != "null"]
    where = f"analysis.{name} = {value!r}"
    if kind == "array":  # a list of [x, y] points, or of sizes
        points = schema["items"].get("type") == "array"
        kind, words = ("points", "[x, y] pairs") if points else ("sizes", "positive numbers")
        if value is not None:
            raise ParamError(f"{where} must be a non-empty list of {words} (m)")
    if value is None:
        raise ParamError(f"analysis.{name} = null is not allowed; expected a {kind}")
    if error.validator in BOUND_OPS:
        raise ParamError(f"{where} must be {BOUND_OPS[error.validator]} {error.validator_value}")
    if error.validator == "enum":
        allowed = ", ".join(repr(c) for c in schema["enum"])
        raise ParamError(f"{where} is not allowed; allowed values: {allowed}")
    if error.validator == "pattern":
        raise ParamError(f"{where} is not allowed; allowed: {schema['patternWords']}")
    or_null = " or null" if "null" in schema_types(schema) and kind in ("number", "integer") else ""
    raise ParamError(f"{where} {_NOT[kind]}{or_null}")


def check_memory(params: dict[str, Any]) -> None:
    """Refuse resolved settings whose solid-fraction raster (the grid's RVEs, and
    the largest convergence RVE at its points) would not fit in
    :data:`MAX_RASTER_BYTES`: a limit of the machine, not of the settings'
    ranges, so it is checked by :func:`parse_params` (the command line) and the
    workflow's validation, not by :func:`resolve_params`.

    Raises
    ------
    ParamError
        Naming the settings, the raster's pixels and its memory.
    """
    g, rve, conv = params["grid"], params["rve"], params["convergence"]
    h = rve["raster_pixel"]
    xs, ys = [p[0] for p in conv["points"]], [p[1] for p in conv["points"]]
    for what, (x_lo, x_hi, y_hi), size in (
            (f"analysis.rve.size = {rve['size']} over the grid x {g['x_min']} to {g['x_max']}, y up to "
             f"{g['y_max']}", (g["x_min"], g["x_max"], g["y_max"]), rve["size"]),
            (f"analysis.convergence.sizes up to {max(conv['sizes'])} at its points",
             (min(xs), max(xs), max(ys)), max(conv["sizes"]))):
        try:
            nx, ny = raster_shape(x_lo, x_hi, y_hi, size / 2, h)
        except OverflowError:        # more pixels than a float counts: a pixel of 1e-300 m
            nx = ny = math.inf
        need = float(nx) * ny * RASTER_BYTES_PER_PIXEL
        if need > MAX_RASTER_BYTES:
            raise ParamError(
                f"{what} needs a solid-fraction raster of {nx:.4g} x {ny:.4g} pixels of "
                f"analysis.rve.raster_pixel = {h:.4g} m, about {need / 2**30:.4g} GiB, more than the "
                f"{MAX_RASTER_BYTES / 2**30:g} GiB allowed; shrink the RVE or the grid, or coarsen raster_pixel")


def resolve_params(user: dict[str, Any] | None) -> dict[str, Any]:
    """Merge ``user`` over :data:`DEFAULTS` and validate every setting.

    Unknown keys are refused (a misspelt key would otherwise be silently
    ignored). Returns a new nested dict; raises :class:`ParamError`.
    """
    if user is None:
        user = {}
    if not isinstance(user, dict):
        raise ParamError(f"the analysis parameters must be a mapping, got {type(user).__name__}")
    out = copy.deepcopy(DEFAULTS)
    for section, values in user.items():
        if section not in _SECTIONS:
            raise ParamError(f"unknown setting analysis.{section}; allowed sections: {', '.join(sorted(_SECTIONS))}")
        if values is None:
            continue
        if not isinstance(values, dict):
            raise ParamError(f"analysis.{section} must be a mapping, got {values!r}")
        for key, value in values.items():
            if key not in _SECTIONS[section]["properties"]:
                raise ParamError(f"unknown setting analysis.{section}.{key}; allowed keys: "
                                 f"{', '.join(sorted(_SECTIONS[section]['properties']))}")
            out[section][key] = copy.deepcopy(value)
    for section, sub in _SECTIONS.items():
        for key, schema in sub["properties"].items():
            _check_setting(f"{section}.{key}", out[section][key], schema)
    g = out["grid"]
    if not g["x_min"] <= g["x_max"]:
        raise ParamError(f"analysis.grid.x_min = {g['x_min']} must be <= analysis.grid.x_max = {g['x_max']}")
    if not g["y_min"] <= g["y_max"]:
        raise ParamError(f"analysis.grid.y_min = {g['y_min']} must be <= analysis.grid.y_max = {g['y_max']}")
    # counted in floats first: a spacing of 1e-300 m gives more points than an integer holds
    n = ((g["x_max"] - g["x_min"]) / g["spacing"] + 1) * ((g["y_max"] - g["y_min"]) / g["spacing"] + 1)
    if n <= 2_000_000:
        n = (math.floor((g["x_max"] - g["x_min"]) / g["spacing"] + 1e-9) + 1) * (
            math.floor((g["y_max"] - g["y_min"]) / g["spacing"] + 1e-9) + 1)
    if n > 1_000_000:
        raise ParamError(f"analysis.grid.spacing = {g['spacing']:.4g} gives {n:.4g} grid points (more than 10^6); "
                         "increase the spacing or shrink the grid")
    if out["rve"]["raster_pixel"] > out["rve"]["size"] / 4:
        raise ParamError(f"analysis.rve.raster_pixel = {out['rve']['raster_pixel']} must be <= rve.size/4 = "
                         f"{out['rve']['size'] / 4}")
    b = out["base_pressure"]
    if not b["x_min"] < b["x_max"]:
        raise ParamError(f"analysis.base_pressure.x_min = {b['x_min']} must be < x_max = {b['x_max']}")
    if b["bin_width"] > b["x_max"] - b["x_min"]:
        raise ParamError(f"analysis.base_pressure.bin_width = {b['bin_width']} is wider than the range "
                         f"[{b['x_min']}, {b['x_max']}]")
    h = out["history"]
    if not h["centre"] < h["shoulder_inner"] < h["shoulder_outer"]:
        raise ParamError(f"analysis.history: the windows must be ordered centre < shoulder_inner < shoulder_outer; "
                         f"got {h['centre']}, {h['shoulder_inner']}, {h['shoulder_outer']} (m)")
    if not h["flank_inner"] < h["flank_outer"]:
        raise ParamError(f"analysis.history.flank_inner = {h['flank_inner']} must be < "
                         f"flank_outer = {h['flank_outer']} (m)")
    return out


def settings_from_text(text: str | None, option: str = "--params") -> dict[str, Any]:
    """The mapping of settings in ``text``: JSON, or YAML (such as :func:`params_flow_text`).

    Read by :func:`sim.settings_file.read_settings`, as the project reads
    every setting: numbers as written (``1e-6``, ``2.5E3``), a key given twice
    in one mapping refused.

    Parameters
    ----------
    text : str or None
        JSON text, YAML text, or ``@file`` naming a file of either; empty or
        None is ``{}``.
    option : str
        The command-line option that passed it, for the error messages.

    Returns
    -------
    dict
        The settings as given (not validated).

    Raises
    ------
    ParamError
        One line naming the option or file: the file cannot be read or is
        empty, the text is neither JSON nor YAML, repeats a key, or is not a
        mapping.
    """
    try:
        return read_settings(text, option, example="{rve: {size: 0.08}}")
    except SettingsFileError as exc:
        raise ParamError(str(exc)) from None


def parse_params(text: str | None) -> dict[str, Any]:
    """Parse the ``--params`` text (JSON or YAML, or ``@file``) and validate it.

    See :func:`settings_from_text`; the workflow passes YAML flow text
    (:func:`params_flow_text`), which its report shows as it is.
    """
    params = resolve_params(settings_from_text(text, "--params"))
    check_memory(params)
    return params


def params_flow_text(settings: dict[str, Any]) -> str:
    """``settings`` as one line of YAML flow text, keys sorted: ``{rve: {size: 0.08}}``.

    What the workflow passes as ``--params``: :func:`settings_from_text` reads
    it back to the same values (:class:`sim.settings_file.SettingsDumper`
    writes every float so that it reads it back as that float, and quotes the
    strings that would read as something else, ``'1e7'`` too). Unlike JSON it
    has no double quotes, which ``snakemake --report`` shows backslash-escaped
    (``{\\"rve\\": ...}``) under *Job parameters*: Snakemake escapes the
    quotes of the job's params before it stores them as JSON in the page, so
    they are escaped twice.
    """
    return yaml.dump(settings, Dumper=SettingsDumper, default_flow_style=True, sort_keys=True,
                     width=math.inf).strip()


def params_json(params: dict[str, Any]) -> str:
    """Canonical JSON text of the effective parameters (stored as the ``config`` attribute)."""
    return json.dumps(params, sort_keys=True)
