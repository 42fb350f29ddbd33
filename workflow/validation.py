"""The one validator of the workflow configuration, run by the Snakefile
before any job.

Snakemake reads the configuration files itself, with PyYAML after YAML 1.1,
which leaves ``1e7``, ``1E-3`` or ``-.5`` as text (and a mapping given to
``--config`` all as text); :func:`coerce_numbers` first turns such text into
the number it is where the schema asks for a number, so that a file means what
:mod:`sim.settings_file` reads everywhere else. Then the validator decides in three passes, each naming the setting,
its value and what is allowed:

1. :func:`number_problems`: every number is a number (not text such as
   ``1e7x``) and finite, and a setting the schema
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

Between the last two, :func:`check_results_folder` refuses a ``results``
folder in the project's own source (sim/, docs/, ..., the repository itself).
A job therefore never meets a setting that its program would refuse. The
workflow's own checks (its stage names, scenes and pile numerics:
``problems()`` of the classes in workflow/piles.py, outputs.py and
numerics_piles.py) are raised by :func:`check_problems`.

Before them, :func:`check_config_files` reads each ``--configfile`` again
strictly (:func:`sim.settings_file.read_settings_file`): a key repeated in one
mapping, which YAML and JSON read as its last value, and an empty section laid
over another file, which Snakemake's merge ignores, are refused naming the
file and line, and a number that :func:`number_problems` refuses, naming the
file. A file Snakemake itself cannot read (empty, a list, bad syntax, missing)
stops Snakemake before the Snakefile with a message that does not name it;
``python -m workflow.validation FILE ...`` checks such files alone, then their
merged configuration, and names the file and line. :func:`load_config` reads,
merges and validates files so (that command and
workflow/tools/study_progress.py use it).
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
from sim.config import SECTIONS, SimConfig
from sim.schema import bounds_text, number_kind, schema_types
from sim.settings_file import SettingsFileError, number_from_text, read_settings_file
from sim.settings_file import merge_settings as merge_configs  # the workflow's name for it

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
# The repository, and its folders of source (code, configuration, docs,
# tests, CI, git): the results folder is none of them, nor inside one, nor
# the repository itself.
REPO = Path(__file__).resolve().parents[1]
SOURCE_FOLDERS = ("sim", "analysis", "workflow", "config", "docs", "tests", ".ci", ".git")


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
    if error.validator == "pattern":     # the rule in words (patternWords beside it), not the regex
        return f"{where} = {error.instance!r}: allowed: {error.schema['patternWords']}"
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
    return " ".join(filter(None, (number_kind(schema), bounds_text(schema))))


def _number_slots(value, schema, root, key=""):
    """Each place in `value` that the schema types as a number or an integer.

    Yields ``(holder, name, dotted key, schema)``: ``holder[name]`` is a value
    other than a mapping or a list at a setting whose schema (``$ref``
    followed) allows a number or an integer.
    """
    schema, root = _resolve(schema, root)
    if isinstance(value, dict):
        properties = schema.get("properties", {})
        children = [(name, properties[name], f"{key}.{name}" if key else str(name))
                    for name in value if name in properties]
    elif isinstance(value, list) and isinstance(schema.get("items"), dict):
        children = [(k, schema["items"], f"{key}[{k}]") for k in range(len(value))]
    else:
        return
    for name, sub, where in children:
        sub, sub_root = _resolve(sub, root)
        if not isinstance(value[name], (dict, list)) and {"number", "integer"} & set(schema_types(sub)):
            yield value, name, where, sub
        else:
            yield from _number_slots(value[name], sub, sub_root, where)


def coerce_numbers(value, schema):
    """Turn into numbers, in place, the numbers of `value` that Snakemake left as text.

    Snakemake reads a ``--configfile`` with PyYAML, after YAML 1.1, which
    reads ``1e7``, ``1E-3`` or ``-.5`` as text, and the values in a mapping
    of ``--config`` (``--config 'model={youngs_modulus: 1e7}'``) all as text;
    where the schema asks for a number, text that is one becomes it
    (:func:`sim.settings_file.number_from_text`), as the settings files are
    read everywhere else.  Other text stays (``1e7x``, ``fast``), for
    :func:`number_problems` to refuse.

    Parameters
    ----------
    value : dict
        A configuration.
    schema : dict
        Its JSON schema.
    """
    for holder, name, _, sub in _number_slots(value, schema, schema):
        number = number_from_text(holder[name])
        if number is not None and "string" not in schema_types(sub):
            holder[name] = number


def number_problems(value, schema, root=None, key=""):
    """Text, non-finite numbers and floats given for integers in `value`.

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
    problems = []
    for holder, name, where, sub in _number_slots(value, schema, schema if root is None else root, key):
        number = holder[name]
        if isinstance(number, str) and "string" not in schema_types(sub):
            problems.append(f"{where} = {number!r}: must be {_allowed(sub)}, not text (numbers are "
                            "written unquoted: 800, 0.5, 2.5e-3, 1e7)")
        elif isinstance(number, float) and not math.isfinite(number):
            problems.append(f"{where} = {number!r}: must be finite, {_allowed(sub)}")
        elif isinstance(number, float) and "integer" in schema_types(sub) and "number" not in schema_types(sub):
            problems.append(f"{where} = {number!r}: must be an integer (write "
                            f"{int(number) if number.is_integer() else 'a whole number'}), "
                            f"{_allowed(sub)}")
    return problems


def check_results_folder(results):
    """Refuse a results folder in the project's own source.

    Parameters
    ----------
    results : str
        The setting ``results``, relative to the working directory.

    Raises
    ------
    ConfigurationError
        One line naming the setting and the folder: it is the repository
        (:data:`REPO`), or one of its :data:`SOURCE_FOLDERS` or inside one,
        where the workflow would write its piles and logs among the sources
        (symbolic links followed).
    """
    folder = Path(results).resolve()
    source = [REPO / name for name in SOURCE_FOLDERS if REPO / name in (folder, *folder.parents)]
    if folder == REPO:
        where = f"the repository itself ({REPO})"
    elif source and folder == source[0]:
        where = f"the source folder {folder}"
    elif source:
        where = f"{folder}, in the source folder {source[0]}"
    else:
        return
    raise ConfigurationError(
        f"invalid configuration: results = {results!r} is {where}, where the workflow would write its "
        f"piles and logs among the sources; give a folder under results/ (e.g. results/my_study) or outside {REPO}")


def validate_config(config):
    """Check `config` (modified in place: defaults filled in) or raise.

    Parameters
    ----------
    config : dict
        The workflow configuration.

    Returns
    -------
    sim.config.SimConfig
        The simulator's sections, as the simulator reads them: the object
        that passed its checks, which the workflow keeps
        (:attr:`workflow.study.Study.sim`) instead of building it again.

    Raises
    ------
    ConfigurationError
        Naming the setting, its value and what is allowed.
    """
    coerce_numbers(config, load_schema(CONFIG_SCHEMA))
    problems = number_problems(config, load_schema(CONFIG_SCHEMA))
    if problems:
        raise ConfigurationError("invalid configuration:\n  " + "\n  ".join(problems))
    problem = schema_problem(config, CONFIG_SCHEMA)
    if problem:
        raise ConfigurationError(f"invalid configuration: {problem}")
    check_results_folder(config["results"])
    try:
        sim = SimConfig.from_dict({k: config[k] for k in SECTIONS})
        check_memory(resolve_params(config["analysis"]))
    except ValueError as exc:
        raise ConfigurationError(f"invalid configuration: {exc}") from None
    return sim


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
        a repeated key, bad syntax), a numeric setting holds text (which the
        file quoted: ``'1e7'``), or a number not finite or not whole where it
        must be (:func:`number_problems`), or
        a file after the first gives a section as an empty mapping
        (``protocols: {}``), which the merge ignores, so the earlier files'
        settings would run unseen.
    """
    layers = []
    for k, path in enumerate(paths):
        try:
            layer = read_settings_file(path)
        except SettingsFileError as exc:
            raise ConfigurationError(str(exc)) from None
        problems = number_problems(layer, load_schema(CONFIG_SCHEMA))  # text here was quoted
        if problems:
            raise ConfigurationError(f"{path}: " + "; ".join(problems))
        empty = [key for key, value in layer.items() if value == {}]
        if k > 0 and empty:
            raise ConfigurationError(
                f"{path}: {empty[0]}: {{}} is an empty mapping, which Snakemake's merge of config files "
                f"ignores (the {empty[0]} of {paths[k - 1]} stays); give the settings to change, or leave "
                f"{empty[0]} out")
        layers.append(layer)
    return layers


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
