"""The ``analysis`` section of the configuration: defaults and validation.

The same keys, defaults and ranges are written as a JSON schema in
``workflow/schemas/analysis.schema.yaml`` (Snakemake validates against it
before anything runs); ``tests/test_analysis_params.py`` checks that both agree.
The command line receives the section as JSON text (``--params``); it is
validated here before any long computation, and every error names the
setting, the offending value and what is allowed.
"""

from __future__ import annotations

import copy
import json
import math
import re
from typing import Any

from .errors import ParamError

DEFAULTS: dict[str, Any] = {
    "grid": {
        "x_min": -0.6,
        "x_max": 0.6,
        "y_min": 0.015,
        "y_max": 0.36,
        "spacing": 0.015,
    },
    "rve": {
        "shape": "square",
        "size": 0.08,
        "min_particles": 50,
        "min_solid_fraction": 0.6,
        "raster_pixel": 0.0005,
    },
    "strain": {
        "min_contacts": 20,
        "max_condition": 25.0,
    },
    "surface": {
        "window": 0.02,
    },
    "checks": {
        "support_reaction_rtol": 0.01,
        "love_rtol": 0.02,
        "max_net_force_ratio": 0.05,
        "enforce": True,
    },
    "base_pressure": {
        "x_min": -0.6,
        "x_max": 0.6,
        "bin_width": 0.02,
        "stage": "relaxed",
    },
    "moduli": {
        "min_points": 3,
        "uncertainty": "pile_fits",
        "bootstrap_samples": 200,
        "bootstrap_seed": 0,
        "degenerate_rtol": 1e-12,
    },
    "invariants": {
        "depth_bin": 0.02,
    },
    "convergence": {
        "points": [[0.0, 0.09], [0.1, 0.06], [-0.1, 0.06]],
        "sizes": [0.01, 0.015, 0.02, 0.03, 0.04, 0.05, 0.06, 0.08, 0.1, 0.12, 0.14, 0.16],
        "seed": None,
    },
    "figures": {
        "heights": [0.045, 0.09, 0.135, 0.18, 0.225, 0.27],
        "fabric_protocol": "wedge",
        "moduli_protocol": "wedge",
        "invariants_protocol": "wedge",
        "convergence_protocol": "wedge",
        "dpi": 150,
    },
}

# (type, minimum, maximum, exclusive minimum?, choices)
_NUM = "number"
_INT = "integer"
_BOOL = "boolean"
_STR = "string"
_SPEC: dict[str, dict[str, dict[str, Any]]] = {
    "grid": {
        "x_min": {"type": _NUM},
        "x_max": {"type": _NUM},
        "y_min": {"type": _NUM, "min": 0.0},
        "y_max": {"type": _NUM, "min": 0.0},
        "spacing": {"type": _NUM, "min": 0.0, "exclusive": True},
    },
    "rve": {
        "shape": {"type": _STR, "choices": ["square", "circle"]},
        "size": {"type": _NUM, "min": 0.0, "exclusive": True},
        "min_particles": {"type": _INT, "min": 1},
        "min_solid_fraction": {"type": _NUM, "min": 0.0, "max": 1.0},
        "raster_pixel": {"type": _NUM, "min": 0.0, "exclusive": True},
    },
    "strain": {
        "min_contacts": {"type": _INT, "min": 2},
        "max_condition": {"type": _NUM, "min": 1.0},
    },
    "surface": {
        "window": {"type": _NUM, "min": 0.0, "exclusive": True},
    },
    "checks": {
        "support_reaction_rtol": {"type": _NUM, "min": 0.0, "exclusive": True},
        "love_rtol": {"type": _NUM, "min": 0.0, "exclusive": True},
        "max_net_force_ratio": {"type": _NUM, "min": 0.0, "exclusive": True},
        "enforce": {"type": _BOOL},
    },
    "base_pressure": {
        "x_min": {"type": _NUM},
        "x_max": {"type": _NUM},
        "bin_width": {"type": _NUM, "min": 0.0, "exclusive": True},
        "stage": {"type": _STR, "pattern": r"poured|relaxed|reduced|reduced[0-9][0-9]"},
    },
    "moduli": {
        "min_points": {"type": _INT, "min": 1, "max": 5},
        "uncertainty": {"type": _STR, "choices": ["pile_fits", "bootstrap"]},
        "bootstrap_samples": {"type": _INT, "min": 2},
        "bootstrap_seed": {"type": _INT, "min": 0},
        "degenerate_rtol": {"type": _NUM, "min": 0.0},
    },
    "invariants": {
        "depth_bin": {"type": _NUM, "min": 0.0, "exclusive": True},
    },
    "convergence": {
        "points": {"type": "points"},
        "sizes": {"type": "sizes"},
        "seed": {"type": _INT, "nullable": True, "min": 0},
    },
    "figures": {
        "heights": {"type": "sizes"},
        "fabric_protocol": {"type": _STR},
        "moduli_protocol": {"type": _STR},
        "invariants_protocol": {"type": _STR},
        "convergence_protocol": {"type": _STR},
        "dpi": {"type": _INT, "min": 10, "max": 1200},
    },
}


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_value(name: str, value: Any, spec: dict[str, Any]) -> None:
    kind = spec["type"]
    if value is None:
        if spec.get("nullable"):
            return
        raise ParamError(f"analysis.{name} = null is not allowed; expected a {kind}")
    if kind == _NUM:
        if not _is_number(value):
            raise ParamError(f"analysis.{name} = {value!r} is not a finite number")
    elif kind == _INT:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParamError(f"analysis.{name} = {value!r} is not an integer")
    elif kind == _BOOL:
        if not isinstance(value, bool):
            raise ParamError(f"analysis.{name} = {value!r} is not true/false")
    elif kind == _STR:
        if not isinstance(value, str):
            raise ParamError(f"analysis.{name} = {value!r} is not a string")
        if "choices" in spec and value not in spec["choices"]:
            allowed = ", ".join(repr(c) for c in spec["choices"])
            raise ParamError(f"analysis.{name} = {value!r} is not allowed; allowed values: {allowed}")
        if "pattern" in spec and not re.fullmatch(spec["pattern"], value):
            raise ParamError(f"analysis.{name} = {value!r} is not allowed; allowed: {spec['pattern']}")
        return
    elif kind == "sizes":
        if (not isinstance(value, list) or not value
                or not all(_is_number(v) and v > 0 for v in value)):
            raise ParamError(f"analysis.{name} = {value!r} must be a non-empty list of positive numbers (m)")
        return
    elif kind == "points":
        ok = isinstance(value, list) and value and all(
            isinstance(p, list) and len(p) == 2 and all(_is_number(c) for c in p) for p in value)
        if not ok:
            raise ParamError(f"analysis.{name} = {value!r} must be a non-empty list of [x, y] pairs (m)")
        return
    lo, hi = spec.get("min"), spec.get("max")
    if lo is not None:
        if spec.get("exclusive") and not value > lo:
            raise ParamError(f"analysis.{name} = {value!r} must be > {lo}")
        if not spec.get("exclusive") and not value >= lo:
            raise ParamError(f"analysis.{name} = {value!r} must be >= {lo}")
    if hi is not None and not value <= hi:
        raise ParamError(f"analysis.{name} = {value!r} must be <= {hi}")


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
        if section not in _SPEC:
            raise ParamError(f"unknown setting analysis.{section}; allowed sections: {', '.join(sorted(_SPEC))}")
        if values is None:
            continue
        if not isinstance(values, dict):
            raise ParamError(f"analysis.{section} must be a mapping, got {values!r}")
        for key, value in values.items():
            if key not in _SPEC[section]:
                raise ParamError(f"unknown setting analysis.{section}.{key}; allowed keys: "
                                 f"{', '.join(sorted(_SPEC[section]))}")
            out[section][key] = copy.deepcopy(value)
    for section, keys in _SPEC.items():
        for key, spec in keys.items():
            _check_value(f"{section}.{key}", out[section][key], spec)
    g = out["grid"]
    if not g["x_min"] <= g["x_max"]:
        raise ParamError(f"analysis.grid.x_min = {g['x_min']} must be <= analysis.grid.x_max = {g['x_max']}")
    if not g["y_min"] <= g["y_max"]:
        raise ParamError(f"analysis.grid.y_min = {g['y_min']} must be <= analysis.grid.y_max = {g['y_max']}")
    n = (math.floor((g["x_max"] - g["x_min"]) / g["spacing"] + 1e-9) + 1) * (
        math.floor((g["y_max"] - g["y_min"]) / g["spacing"] + 1e-9) + 1)
    if n > 1_000_000:
        raise ParamError(f"analysis.grid.spacing = {g['spacing']} gives {n} grid points (more than 10^6); "
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
    return out


def parse_params(text: str | None) -> dict[str, Any]:
    """Parse the ``--params`` JSON text (or ``@file.json``) and validate it."""
    if text is None or text.strip() == "":
        return resolve_params({})
    if text.startswith("@"):
        try:
            with open(text[1:], encoding="utf-8") as fh:
                text = fh.read()
        except OSError as exc:
            raise ParamError(f"cannot read the parameter file {text[1:]!r}: {exc}") from exc
    try:
        user = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParamError(f"--params is not valid JSON ({exc}); pass the analysis config section as JSON text") from exc
    return resolve_params(user)


def params_json(params: dict[str, Any]) -> str:
    """Canonical JSON text of the effective parameters (stored as the ``config`` attribute)."""
    return json.dumps(params, sort_keys=True)
