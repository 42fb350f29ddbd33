"""A file of settings (YAML or JSON), read strictly, each problem in one line naming the file.

PyYAML reads a mapping that repeats a key by keeping the last value, an empty
file as ``None`` and a list or a number as themselves; a configuration file
is none of these.  :func:`read_settings_file` refuses each of them, and a
syntax error, with the file's name and, where the parser knows it, the line
and column: ``my.yaml:4:3: key 'pour' given twice (first at line 1)``.  The
simulator's command line reads ``--params @FILE`` with it, and the workflow's
validator (:mod:`workflow.validation`) the ``--configfile`` files that reach
the Snakefile and those of ``python -m workflow.validation FILE ...``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml


class SettingsFileError(ValueError):
    """A settings file that cannot be read as a mapping of settings."""


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a mapping that repeats a key."""


def _mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"key {key!r} given twice (first at line {seen[key] + 1})", key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


def _kind(value: Any) -> str:
    return {list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number"}.get(type(value), type(value).__name__)


def read_settings_file(path: str | Path, what: str = "config file") -> dict[str, Any]:
    """The mapping of settings in the YAML or JSON file ``path``.

    Parameters
    ----------
    path : str or Path
        The file (``.json``: JSON; anything else: YAML, of which JSON is a subset).
    what : str
        What the file is to the caller, for the messages (``--params @FILE``).

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
        if path.suffix == ".json":
            data = json.loads(text)
        else:
            data = yaml.load(text, Loader=_StrictLoader)
    except json.JSONDecodeError as exc:
        raise SettingsFileError(f"{path}:{exc.lineno}:{exc.colno}: not valid JSON: {exc.msg}") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = " ".join(str(exc.problem or exc.context or "not valid YAML").split())
        raise SettingsFileError(f"{where}: {problem}") from None
    except yaml.YAMLError as exc:
        raise SettingsFileError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None
    if data is None:
        raise SettingsFileError(f"{what} {path} is empty: it must hold a mapping of settings, "
                                "e.g. 'pour: {n_particles: 800}'")
    if not isinstance(data, dict):
        raise SettingsFileError(f"{what} {path} holds {_kind(data)} at its top, not a mapping of settings "
                                "(section: {setting: value}, e.g. 'pour: {n_particles: 800}')")
    return data
