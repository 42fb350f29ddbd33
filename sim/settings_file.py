"""Settings in YAML or JSON, read strictly, each problem in one line naming the file.

One reading for every place that reads settings: the simulator's
``--params`` (text or ``@FILE``, merged in order by :func:`merge_settings`),
the analysis' ``--params`` (:func:`analysis.params.settings_from_text`), the
numerical checks' ``--params`` and the workflow's validator
(:mod:`workflow.validation`), which reads the ``--configfile`` files again.

Numbers are read as physicists write them.  PyYAML follows YAML 1.1, where a
float needs a dot and a signed exponent: ``1e7``, ``1.0e6``, ``1E-3``,
``-.5`` and ``+1e2`` are text there, and ``youngs_modulus: 1e7`` was
refused as "'1e7' is not of type 'number'".  :class:`SettingsLoader` reads
them as the floats they are (as YAML 1.2 and JSON do); what YAML 1.1 reads as
a number it reads the same (``1_000`` is 1000, ``.inf`` infinity), so a
file means the same here as in Snakemake, whose own loader reads the
configuration before the Snakefile runs (where the schema asks for a number,
the validator turns the text it left into the number,
:func:`number_from_text`).  ``e7``, ``1e``, ``inf`` and ``1e7x`` stay text,
which a numeric setting refuses; JSON's own numbers are JSON's.

PyYAML reads a mapping that repeats a key by keeping the last value, and
Python's JSON reader likewise; an empty file is ``None``, a list or a number
themselves; a configuration is none of these.  :func:`read_settings_file`
and :func:`read_settings` refuse each of them, and a syntax error, naming the
file (or the option) and, where the parser knows it, the line and column, in
the same form for YAML and JSON: ``my.yaml:4:3: key 'pour' given twice
(first at line 1)``.
"""

from __future__ import annotations

import json
import re
from json.decoder import WHITESPACE, JSONObject, scanstring
from json.scanner import py_make_scanner
from pathlib import Path
from typing import Any

import yaml

FLOAT_TAG = "tag:yaml.org,2002:float"

#: A float in settings: YAML 1.1's forms (PyYAML's resolver: ``1.5``, ``5.``,
#: ``.5``, ``1.0e+7``, ``1_000.5``, ``.inf``, ``.nan``, sexagesimal ``1:30.0``)
#: and those of YAML 1.2 and JSON that 1.1 leaves as text: an exponent
#: without a dot or a sign (``1e7``, ``1E-3``, ``2.5e6``) and a sign before a
#: leading dot (``-.5``).
FLOAT = re.compile(r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
                    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X)

# One plain YAML scalar of the characters a number may have.
_TOKEN = re.compile(r"[-+.0-9A-Za-z_:]+")


def _numbers_as_written(cls):
    """`cls` (a PyYAML loader or dumper) resolving plain scalars by :data:`FLOAT`
    instead of YAML 1.1's float pattern; its other resolvers as they are."""
    cls.yaml_implicit_resolvers = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag != FLOAT_TAG]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
    cls.add_implicit_resolver(FLOAT_TAG, FLOAT, list("-+.0123456789"))
    return cls


class SettingsFileError(ValueError):
    """Settings that cannot be read as a mapping of settings."""


class _RepeatedKey(yaml.constructor.ConstructorError):
    """A mapping of YAML that gives a key twice."""


@_numbers_as_written
class SettingsLoader(yaml.SafeLoader):
    """PyYAML's safe loader reading numbers by :data:`FLOAT` and refusing a
    mapping that repeats a key."""


def _mapping(loader: SettingsLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise _RepeatedKey(None, None, f"key {key!r} given twice (first at line {seen[key] + 1})",
                               key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


SettingsLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


@_numbers_as_written
class SettingsDumper(yaml.SafeDumper):
    """PyYAML's safe dumper that quotes every string :class:`SettingsLoader`
    would read as a number (``'1e7'``), so that what it writes reads back the same."""


class _RepeatedJSONKey(ValueError):
    """A JSON object that gives a key twice, at the offsets of its second and first keys."""

    def __init__(self, key: str, offset: int, first: int):
        super().__init__(key)
        self.key, self.offset, self.first = key, offset, first


def _key_offsets(s: str, start: int, scan_once) -> list[int]:
    """The offsets of the keys of the JSON object whose text starts before `start`
    (just after its ``{``), in order."""
    offsets, pos = [], WHITESPACE.match(s, start).end()
    while s[pos] == '"':
        offsets.append(pos)
        _, pos = scanstring(s, pos + 1)
        pos = WHITESPACE.match(s, WHITESPACE.match(s, pos).end() + 1).end()  # past the ':'
        _, pos = scan_once(s, pos)
        pos = WHITESPACE.match(s, pos).end()
        if s[pos] == ",":
            pos = WHITESPACE.match(s, pos + 1).end()
    return offsets


def _json_object(s_and_end, strict, scan_once, object_hook, object_pairs_hook, memo=None, *args):
    """The parser of a JSON object, as :func:`json.decoder.JSONObject`, refusing a repeated key."""
    pairs, end = JSONObject(s_and_end, strict, scan_once, None, list, memo, *args)
    keys = [key for key, _ in pairs]
    for k, key in enumerate(keys):
        if key in keys[:k]:
            offsets = _key_offsets(*s_and_end, scan_once)
            raise _RepeatedJSONKey(key, offsets[k], offsets[keys.index(key)])
    return dict(pairs), end


class _StrictJSONDecoder(json.JSONDecoder):
    """Python's JSON decoder (its Python scanner) refusing an object that repeats a key."""

    def __init__(self):
        super().__init__()
        self.parse_object = _json_object
        self.scan_once = py_make_scanner(self)


def _line_col(text: str, offset: int) -> tuple[int, int]:
    """Line and column (from 1) of `offset` in `text`, as the JSON reader counts them."""
    return text.count("\n", 0, offset) + 1, offset - text.rfind("\n", 0, offset)


def _read_json(text: str, name: str) -> Any:
    """The value of the JSON `text`; SettingsFileError naming `name`, line and column for a
    repeated key; :class:`json.JSONDecodeError` for bad syntax."""
    try:
        return _StrictJSONDecoder().decode(text)
    except _RepeatedJSONKey as exc:
        line, col = _line_col(text, exc.offset)
        raise SettingsFileError(f"{name}:{line}:{col}: key {exc.key!r} given twice "
                                f"(first at line {_line_col(text, exc.first)[0]})") from None


def _yaml_problem(exc: yaml.YAMLError, name: str) -> str:
    """`exc` in one line, ``NAME:LINE:COL: problem`` where the parser knows where."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    if mark is None:
        return f"{name}: not valid YAML: {' '.join(str(exc).split())}"
    problem = " ".join(str(exc.problem or exc.context or "not valid YAML").split())
    return f"{name}:{mark.line + 1}:{mark.column + 1}: {problem}"


def _kind(value: Any) -> str:
    return {list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number"}.get(type(value), type(value).__name__)


def yaml_value(text: str) -> Any:
    """The value of the YAML `text` (a value given on a command line, ``1e7``), numbers
    read as in settings files (:class:`SettingsLoader`)."""
    return yaml.load(text, Loader=SettingsLoader)


def number_from_text(value: Any) -> int | float | None:
    """The number that the text `value` is, read as :class:`SettingsLoader` reads it; else None.

    ``'1e7'``, ``'1E-3'``, ``'-.5'``, ``'800'`` give 1e7, 0.001, -0.5, 800;
    ``'1e7x'``, ``'fast'``, ``'true'``, ``'{a: 1}'`` and anything not a string
    give None.  For configurations that a reader outside this module made:
    Snakemake reads ``--configfile`` after YAML 1.1 (``1e7`` stays text) and
    the values in a mapping of ``--config`` as text altogether.
    """
    if not (isinstance(value, str) and _TOKEN.fullmatch(value)):
        return None
    number = yaml_value(value)
    return number if isinstance(number, (int, float)) and not isinstance(number, bool) else None


def read_settings_file(path: str | Path, what: str = "config file") -> dict[str, Any]:
    """The mapping of settings in the YAML or JSON file ``path``.

    Parameters
    ----------
    path : str or Path
        The file (``.json``: JSON; anything else: YAML, of which JSON is a
        subset), its numbers read as :data:`FLOAT` says.
    what : str
        What the file is to the caller, for the messages (``--params file``).

    Returns
    -------
    dict
        Its top-level mapping.

    Raises
    ------
    SettingsFileError
        One line naming the file: it cannot be read, it is empty, it holds no
        mapping at its top (a list, a number, a string), a key is repeated
        within one mapping, or its syntax is wrong (with line and column).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SettingsFileError(f"{what} {path}: cannot be read ({exc.__class__.__name__}: "
                                f"{getattr(exc, 'strerror', None) or exc})") from None
    try:
        data = _read_json(text, str(path)) if path.suffix == ".json" else yaml_value(text)
    except json.JSONDecodeError as exc:
        raise SettingsFileError(f"{path}:{exc.lineno}:{exc.colno}: not valid JSON: {exc.msg}") from None
    except yaml.YAMLError as exc:
        raise SettingsFileError(_yaml_problem(exc, str(path))) from None
    if data is None:
        raise SettingsFileError(f"{what} {path} is empty: it must hold a mapping of settings, "
                                "e.g. 'pour: {n_particles: 800}'")
    if not isinstance(data, dict):
        raise SettingsFileError(f"{what} {path} holds {_kind(data)} at its top, not a mapping of settings "
                                "(section: {setting: value}, e.g. 'pour: {n_particles: 800}')")
    return data


def read_settings(text: str | None, what: str = "--params",
                  example: str = "{pour: {n_particles: 800}}") -> dict[str, Any]:
    """The mapping of settings given on a command line: JSON or YAML text, or ``@FILE``.

    Parameters
    ----------
    text : str or None
        ``@FILE`` (read by :func:`read_settings_file`), or the settings as
        JSON or YAML text (JSON is tried first); None, empty text or YAML's
        null give no settings.
    what : str
        The option that gave it, for the messages.
    example : str
        A mapping of settings the messages show.

    Returns
    -------
    dict
        The settings as given (not validated).

    Raises
    ------
    SettingsFileError
        One line naming `what`: a file as :func:`read_settings_file` refuses
        it, a key repeated in one mapping (``--params:1:24: key 'pour' given
        twice (first at line 1)``), text that is neither JSON nor YAML, or
        that holds no mapping.
    """
    if text is None or not text.strip():
        return {}
    if text.startswith("@"):
        return read_settings_file(text[1:], f"{what} file")
    try:
        data = _read_json(text, what)
    except json.JSONDecodeError as exc:
        try:
            data = yaml_value(text)
        except _RepeatedKey as yexc:
            raise SettingsFileError(_yaml_problem(yexc, what)) from None
        except yaml.YAMLError as yexc:
            raise SettingsFileError(f"{what} is neither JSON ({exc}) nor YAML ({_yaml_problem(yexc, what)}); "
                                    f"give a mapping of settings, e.g. {example}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SettingsFileError(f"{what} = {text[:80]!r} holds {_kind(data)}, not a mapping of settings "
                                f"(section: {{setting: value}}, e.g. {example})")
    return data


def merge_settings(base: dict, layer: dict) -> dict:
    """`base` updated by `layer` key by key into nested mappings (a new dict; later wins).

    How Snakemake merges its ``--configfile`` files, and how a second
    ``--params`` of the simulator is laid over the first.
    """
    out = dict(base)
    for key, value in layer.items():
        out[key] = (merge_settings(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict)
                    else value)
    return out
