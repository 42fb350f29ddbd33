"""The project's check of a setting against its JSON schema, shared by the
simulator and the analysis (each builds its own messages on it:
:func:`sim.config.check_setting`, :func:`analysis.params._check_setting`) and
the workflow's messages.

jsonschema decides (Draft 2020-12), with JSON schema's types read as the
project reads settings: a number is finite, an integer is not a float
(``3500.0``), a list may be a tuple. :func:`schema_error` picks, of a value's
violations, the one a message names; the rest turns a schema's kinds and
bounds into words.
"""

from __future__ import annotations

import math
from typing import Any

from jsonschema import Draft202012Validator, validators


def schema_types(schema: dict) -> list:
    """The ``type`` of a JSON schema as a list (empty when it gives none)."""
    kinds = schema.get("type", [])
    return [kinds] if isinstance(kinds, str) else list(kinds)


#: Each bound keyword of a JSON schema and its comparison, in the order the
#: messages name them.
BOUND_OPS = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}


def number_kind(schema: dict) -> str:
    """``"an integer"`` when the schema allows integers only, else ``"a number"``."""
    kinds = schema_types(schema)
    return "an integer" if "integer" in kinds and "number" not in kinds else "a number"


def bounds_text(schema: dict) -> str:
    """A schema's bounds in words (``">= 0 and <= 10"``; empty when it has none)."""
    return " and ".join(f"{op} {schema[key]}" for key, op in BOUND_OPS.items() if key in schema)


def is_real(value: Any) -> bool:
    """A Python number other than a bool (finite or not)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


# JSON schema's types as the project reads settings: a number is finite, an
# integer is not a float (3500.0), a list may be a tuple (a dataclass's).
_TYPES = Draft202012Validator.TYPE_CHECKER.redefine_many({
    "number": lambda _, v: is_real(v) and math.isfinite(v),
    "integer": lambda _, v: isinstance(v, int) and not isinstance(v, bool),
    "array": lambda _, v: isinstance(v, (list, tuple))})
_SettingValidator = validators.extend(Draft202012Validator, type_checker=_TYPES)


def schema_error(value: Any, schema: dict):
    """The violation of ``schema`` by ``value`` that a message names, or None.

    The schema decides (jsonschema, Draft 2020-12, with a number finite and an
    integer not a float). Of several violations the first of: the value's
    type, the list's own rules (its length), the first item's, repeated items.

    Returns
    -------
    jsonschema.ValidationError or None
        ``validator`` names the broken keyword; ``relative_path`` is empty,
        or the index of the offending item (then ``schema`` and ``instance``
        are the item's).
    """
    errors = _SettingValidator(schema).iter_errors(value)
    return min(errors, key=lambda e: (e.validator == "uniqueItems", tuple(e.relative_path),
                                      e.validator != "type"), default=None)
