"""The one validator of the workflow configuration, run by the Snakefile
before any job.

It decides in three passes, each naming the setting, its value and what is
allowed:

1. :func:`number_problems`: every number is finite, and a setting the schema
   declares an integer holds an integer, not 3500.0 (JSON schema counts an
   integer-valued float as an integer; the simulator and the analysis do not).
2. The JSON schema ``workflow/schemas/config.schema.yaml`` (draft 2020-12),
   which also fills in the defaults (as ``snakemake.utils.validate`` does). It
   refers, by a ``$ref`` to another file, to the schema each package ships
   for its own settings (sim/config.schema.yaml for the simulator's
   sections, analysis/params.schema.yaml for ``analysis``) and to
   numerics.schema.yaml beside it for ``numerics``: one pass validates all.
3. The simulator's and the analysis' own checks (:class:`sim.config.SimConfig`,
   :func:`analysis.params.resolve_params`): what a schema cannot express,
   such as ``relax.hold_time <= relax.max_time`` or an ordered grid.

A job therefore never meets a setting that its program would refuse. The
workflow's own checks (its stage names, scenes and pile numerics:
``problems()`` of the classes in workflow/piles.py, scene.py and
numerics_piles.py) are raised by :func:`check_problems`.

Before them, :func:`check_config_files` reads each ``--configfile`` again
strictly (:func:`sim.settings_file.read_settings_file`): a key repeated in one
mapping, which YAML reads as its last value, and an empty section laid over
another file, which Snakemake's merge ignores, are refused naming the file and
line. A file Snakemake itself cannot read (empty, a list, bad syntax, missing)
stops Snakemake before the Snakefile with a message that does not name it;
``python -m workflow.validation FILE ...`` checks such files alone, then their
merged configuration, and names the file and line. :func:`load_config` reads,
merges and validates files so (that command and
workflow/scripts/study_progress.py use it).
"""

from __future__ import annotations

import copy
import functools
import math
from pathlib import Path

import yaml
from jsonschema import Draft202012Validator, validators
from referencing import Registry, Resource

from analysis.params import SCHEMA_FILE as ANALYSIS_SCHEMA
from analysis.params import check_memory, resolve_params
from sim.config import SCHEMA_FILE as SIM_SCHEMA
from sim.config import SimConfig
from sim.settings_file import SettingsFileError, read_settings_file

SCHEMAS = Path(__file__).resolve().parent / "schemas"
CONFIG_SCHEMA = SCHEMAS / "config.schema.yaml"
NUMERICS_SCHEMA = SCHEMAS / "numerics.schema.yaml"
# The files that config.schema.yaml refers to, by the paths its $ref give
# (relative to SCHEMAS): the packages' own schemas are those of the packages
# imported here, whose checks run next (a checkout's, or an installed sim
# beside a working directory that has no sim/).
REFERRED_SCHEMAS = {"../../sim/config.schema.yaml": SIM_SCHEMA,
                    "../../analysis/params.schema.yaml": ANALYSIS_SCHEMA,
                    "numerics.schema.yaml": NUMERICS_SCHEMA}
# The sections of the configuration that the simulator reads.
SIM_SECTIONS = ("model", "particles", "pour", "relax", "probe", "physics")


class ConfigurationError(ValueError):
    """The configuration holds settings that no job could run with."""


@functools.lru_cache(maxsize=None)
def load_schema(path):
    """The JSON schema in the YAML file `path` (parsed once)."""
    return yaml.load(Path(path).read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def _filling_defaults(validator_class):
    """`validator_class` that also sets every missing property's ``default``."""
    check_properties = validator_class.VALIDATORS["properties"]

    def properties(validator, props, instance, schema):
        if isinstance(instance, dict):
            for name, sub in props.items():
                if "default" in sub:
                    instance.setdefault(name, copy.deepcopy(sub["default"]))
        yield from check_properties(validator, props, instance, schema)

    return validators.extend(validator_class, {"properties": properties})


_Validator = _filling_defaults(Draft202012Validator)


def _schema_file(ref):
    """The schema file that the ``$ref`` `ref` (``file.yaml`` or ``file.yaml#/...``,
    relative to workflow/schemas) names: one of :data:`REFERRED_SCHEMAS`."""
    try:
        return REFERRED_SCHEMAS[ref.partition("#")[0]]
    except KeyError:
        raise ValueError(f"$ref {ref!r}: only {', '.join(REFERRED_SCHEMAS)} can be referred to") from None


# The schema files that a $ref to another file (config.schema.yaml's
# simulator sections, analysis and numerics) loads, by :func:`_schema_file`:
# in a checkout the files that snakemake.utils.validate finds by the same
# paths from the referring file's folder (only config.schema.yaml refers to
# other files).
_REGISTRY = Registry(retrieve=lambda uri: Resource.from_contents(load_schema(_schema_file(uri))))


def schema_problem(value, path):
    """The first violation of the schema in `path` by `value`, as text, or None.

    Fills in `value`'s defaults.  The text names the setting (dotted key),
    its value and the rule it breaks.
    """
    error = next(iter(_Validator(load_schema(path), registry=_REGISTRY).iter_errors(value)),
                 None)
    if error is None:
        return None
    where = ".".join(str(p) for p in error.absolute_path) or "(top level)"
    return f"{where}: {error.message}"


def _resolve(schema, root):
    """`schema` with a ``$ref`` replaced by its target, and the schema holding
    the target's ``$defs``: `root` for a local ``$ref`` (``#/$defs/...``), the
    file for one to another file (``numerics.schema.yaml``,
    ``../../sim/config.schema.yaml``, optionally ``#/...`` in it)."""
    while "$ref" in schema:
        file, _, pointer = schema["$ref"].partition("#")
        if file:
            root = load_schema(_schema_file(file))
        node = root
        for part in filter(None, pointer.split("/")):
            node = node[part]
        schema = node
    return schema, root


def _allowed(schema):
    """What a numeric schema allows, in words ("a number >= 0 and <= 10")."""
    kinds = schema.get("type", "number")
    kind = "an integer" if "integer" in kinds and "number" not in kinds else "a number"
    bounds = [f"{op} {schema[key]}" for key, op in (
        ("minimum", ">="), ("exclusiveMinimum", ">"), ("maximum", "<="),
        ("exclusiveMaximum", "<")) if key in schema]
    return " ".join([kind] + [" and ".join(bounds)] if bounds else [kind])


def number_problems(value, schema, root=None, key=""):
    """Non-finite numbers and floats given for integers in `value`.

    Parameters
    ----------
    value : object
        A configuration (or part of one) as loaded from YAML.
    schema : dict
        Its JSON schema (local ``$ref`` are followed).
    root : dict, optional
        The schema holding the ``$defs`` (default: `schema`).
    key : str
        Dotted name of `value` in the configuration, for the messages.

    Returns
    -------
    list of str
        One message per bad number, naming its key, value and what is allowed.
    """
    root = schema if root is None else root
    schema, root = _resolve(schema, root)
    problems = []
    if isinstance(value, dict):
        properties = schema.get("properties", {})
        for name, sub in value.items():
            if name in properties:
                problems += number_problems(sub, properties[name], root,
                                            f"{key}.{name}" if key else str(name))
    elif isinstance(value, list) and isinstance(schema.get("items"), dict):
        for k, item in enumerate(value):
            problems += number_problems(item, schema["items"], root, f"{key}[{k}]")
    elif isinstance(value, float):
        kinds = schema.get("type", [])
        kinds = [kinds] if isinstance(kinds, str) else kinds
        if not math.isfinite(value):
            problems.append(f"{key} = {value!r}: must be finite, {_allowed(schema)}")
        elif "integer" in kinds and "number" not in kinds:
            problems.append(f"{key} = {value!r}: must be an integer (write "
                            f"{int(value) if value.is_integer() else 'a whole number'}), "
                            f"{_allowed(schema)}")
    return problems


def validate_config(config):
    """Check `config` (modified in place: defaults filled in) or raise.

    Parameters
    ----------
    config : dict
        The workflow configuration.

    Raises
    ------
    ConfigurationError
        Naming the setting, its value and what is allowed.
    """
    problems = number_problems(config, load_schema(CONFIG_SCHEMA))
    if problems:
        raise ConfigurationError("invalid configuration:\n  " + "\n  ".join(problems))
    problem = schema_problem(config, CONFIG_SCHEMA)
    if problem:
        raise ConfigurationError(f"invalid configuration: {problem}")
    for check in (lambda: SimConfig.from_dict({k: config[k] for k in SIM_SECTIONS}),
                  lambda: check_memory(resolve_params(config["analysis"]))):
        try:
            check()
        except ValueError as exc:
            raise ConfigurationError(f"invalid configuration: {exc}") from None


def check_problems(problems, what="configuration"):
    """Raise when `problems` is not empty, listing each on its own line.

    Parameters
    ----------
    problems : list of str
    what : str
        What is invalid, for the first line ("configuration", "scene").

    Raises
    ------
    ValueError
        ``invalid WHAT:`` followed by the problems.
    """
    if problems:
        raise ValueError(f"invalid {what}:\n  " + "\n  ".join(problems))


def check_config_files(paths):
    """Read each configuration file strictly, in the order Snakemake merges them, or raise.

    Parameters
    ----------
    paths : list of str or Path
        The ``--configfile`` files, first to last.

    Returns
    -------
    list of dict
        Their mappings.

    Raises
    ------
    ConfigurationError
        One line naming the file (and line): it cannot be read as a mapping of
        settings (:func:`sim.settings_file.read_settings_file`: empty, a list,
        a repeated key, bad syntax), or a file after the first gives a section
        as an empty mapping (``protocols: {}``), which the merge ignores, so
        the earlier files' settings would run unseen.
    """
    layers = []
    for k, path in enumerate(paths):
        try:
            layer = read_settings_file(path)
        except SettingsFileError as exc:
            raise ConfigurationError(str(exc)) from None
        empty = [key for key, value in layer.items() if value == {}]
        if k > 0 and empty:
            raise ConfigurationError(
                f"{path}: {empty[0]}: {{}} is an empty mapping, which Snakemake's merge of config files "
                f"ignores (the {empty[0]} of {paths[k - 1]} stays); give the settings to change, or leave "
                f"{empty[0]} out")
        layers.append(layer)
    return layers


def merge_configs(base, layer):
    """``base`` updated by ``layer`` key by key into nested mappings, as Snakemake merges config files."""
    out = dict(base)
    for key, value in layer.items():
        out[key] = merge_configs(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def load_config(paths):
    """The workflow configuration of the ``--configfile`` files `paths` as the
    Snakefile sees it: each file read strictly (:func:`check_config_files`),
    merged in order (:func:`merge_configs`) and validated with every default
    filled in (:func:`validate_config`).

    Parameters
    ----------
    paths : list of str or Path
        The files, first to last.

    Returns
    -------
    dict

    Raises
    ------
    ConfigurationError
        As :func:`check_config_files` and :func:`validate_config` raise it.
    """
    config = {}
    for layer in check_config_files(paths):
        config = merge_configs(config, layer)
    validate_config(config)
    return config


def main(argv=None):
    """``python -m workflow.validation FILE ...``: the files, then their merged configuration.

    Prints ``ok: FILE ...`` and exits 0, or prints the one-line problem and exits 2.
    """
    import sys

    paths = list(sys.argv[1:] if argv is None else argv)
    if not paths:
        print("usage: python -m workflow.validation CONFIGFILE [CONFIGFILE ...]  "
              "(the files of snakemake --configfile, in their order)", file=sys.stderr)
        return 2
    try:
        load_config(paths)
    except ConfigurationError as exc:
        print(exc, file=sys.stderr)
        return 2
    print("ok: " + " ".join(str(p) for p in paths))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
