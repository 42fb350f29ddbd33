"""Configurations drawn from the schemas: each is refused in one line before
any job, or planned cleanly.

Hypothesis draws a configuration by laying one to three settings over the
smoke configuration (config/smoke.yaml): the setting anywhere in the
workflow's schema (workflow/schemas/config.schema.yaml and the packages'
schemas it refers to), its value drawn from what that setting's schema allows
(its bounds, its enum) and from what it does not (just past a bound, 0, ±1e308,
1e-308, NaN, text, a number written as text, a list, a mapping, null).  Each
configuration then goes the way the Snakefile takes it (workflow/rules/common.smk
builds the same :class:`workflow.study.Study`):

* refused: the one validator (:func:`workflow.validation.validate_config`) or
  the workflow's own checks raise a ``ValueError`` whose message names a
  setting that was drawn, each of its lines short and none a traceback;
* or planned: every object the rules read is built, with every target and
  resource, and nothing raises.

Anything else (another exception, a message naming no drawn setting) is a
defect.  A few drawn configurations, refused and accepted, also go through a
real ``snakemake -n``, which must refuse with the same one line, or plan.
"""

import copy
import math
import subprocess
import sys

import pytest
import yaml
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st
from workflow_config import REPO

from sim.settings_file import read_settings_file
from workflow.study import Study
from workflow.validation import CONFIG_SCHEMA, _resolve, load_schema

BASE = read_settings_file(REPO / "config" / "smoke.yaml")
#: Drawn settings are laid over these, inside results/ so that nothing leaves it.
BASE["results"] = "results/fuzz"
#: The longest line a refusal may print: one sentence a person reads.
LONGEST_LINE = 600


def _leaves(schema, root, path=()):
    """Every setting of the schema: ``(path of keys, its schema)``, mappings entered."""
    schema, root = _resolve(schema, root)
    if schema.get("properties"):
        for name, sub in schema["properties"].items():
            yield from _leaves(sub, root, (*path, name))
    elif path:
        yield path, schema


ROOT = load_schema(CONFIG_SCHEMA)
LEAVES = sorted(set((p, yaml.safe_dump(s)) for p, s in _leaves(ROOT, ROOT)))
LEAVES = [(p, yaml.safe_load(s)) for p, s in LEAVES]


def _types(schema):
    kinds = schema.get("type", [])
    return {kinds} if isinstance(kinds, str) else set(kinds)


def _inside(schema):
    """Values that the setting's own schema allows (bounds and enum kept)."""
    kinds, options = _types(schema), []
    if "enum" in schema:
        return st.sampled_from(schema["enum"])
    if kinds & {"number", "integer"}:
        low = schema.get("minimum", schema.get("exclusiveMinimum", -1e6))
        high = schema.get("maximum", schema.get("exclusiveMaximum", 1e6))
        if "integer" in kinds and "number" not in kinds:
            options.append(st.integers(math.ceil(low), math.floor(min(high, low + 10 ** 6))))
        else:
            options.append(st.floats(low, high, exclude_min="exclusiveMinimum" in schema,
                                     exclude_max="exclusiveMaximum" in schema, allow_nan=False))
    if "boolean" in kinds:
        options.append(st.booleans())
    if "string" in kinds:
        options.append(st.text("abcxyz_0123456789/.", min_size=1, max_size=12))
    if "null" in kinds:
        options.append(st.none())
    if "array" in kinds:
        item = schema.get("items") if isinstance(schema.get("items"), dict) else {}
        options.append(st.lists(_inside(item) if item else st.integers(1, 5), max_size=3))
    return st.one_of(options) if options else st.none()


#: What no setting's schema asks for, or only at its edge: extremes of double
#: precision, not-a-number, numbers written as text (which must still read as
#: numbers), text that is no number, containers and null.
OUTSIDE = st.sampled_from([0, -1, 1e308, -1e308, 1e-308, float("nan"), float("inf"), "1e7", "2.5e-3",
                           "1e7x", "fast", [], [1, 2], {}, {"a": 1}, None, True, 2 ** 64, 3500.5])


def _edge(schema):
    """Just past each bound of a numeric setting."""
    values = []
    for key, sign in (("minimum", -1), ("exclusiveMinimum", 0), ("maximum", 1), ("exclusiveMaximum", 0)):
        if key in schema:
            values.append(schema[key] + sign * max(1e-9, abs(schema[key]) * 1e-9))
    return st.sampled_from(values) if values else OUTSIDE


@st.composite
def configurations(draw):
    """A configuration with one to three drawn settings, and their dotted names."""
    config, names = copy.deepcopy(BASE), []
    for _ in range(draw(st.integers(1, 3))):
        path, schema = draw(st.sampled_from(LEAVES))
        value = draw(st.one_of(_inside(schema), _edge(schema), OUTSIDE))
        node = config
        for key in path[:-1]:
            if not isinstance(node.get(key), dict):
                node[key] = {}
            node = node[key]
        node[path[-1]] = value
        names.append(".".join(path))
    return config, names


def plan(config):
    """What workflow/rules/common.smk does with a configuration before any rule:
    build the same :class:`workflow.study.Study` (validation and every check, in
    its order), ask it for the scene's targets and each stage's resources;
    raises ``ValueError`` for a refused one."""
    study = Study(config, REPO, sys.executable, warn=lambda text: None)
    targets = study.outputs.targets(study.analysis.targets(), study.numerics.targets())
    for stage in study.stages.all_stages():
        assert study.resources.stage_runtime_min(stage, 1) > 0
        assert math.isfinite(study.resources.stage_cpu_s(stage))
    return targets


def _refusal_is_one_line_naming(message, names):
    lines = message.splitlines()
    assert lines and "Traceback" not in message, message
    assert all(len(line) <= LONGEST_LINE for line in lines), message
    # the problem names a drawn setting (its last key, or a section above it)
    keys = {part for name in names for part in name.split(".")} | {"results", "configuration"}
    assert any(key in message for key in keys), (names, message)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@seed(43)
@given(configurations())
def test_a_drawn_configuration_is_refused_in_one_line_or_planned(drawn):
    config, names = drawn
    try:
        targets = plan(copy.deepcopy(config))
    except ValueError as exc:
        _refusal_is_one_line_naming(str(exc), names)
    else:
        assert targets


def _snakemake_n(tmp_path, config):
    path = tmp_path / "drawn.yaml"
    path.write_text(yaml.safe_dump(config))
    return subprocess.run([sys.executable, "-m", "snakemake", "-n", "--cores", "1", "--configfile", str(path),
                           "--replace-workflow-config", "--directory", str(REPO)], cwd=REPO,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("changes", [
    {"model": {"youngs_modulus": "fast"}},
    {"pour": {"n_particles": -3}},
    {"results": "docs/fuzz"},
    {"model": {"youngs_modulus": 1e7}, "pour": {"n_particles": 60}},
])
def test_snakemake_n_refuses_in_the_validators_line_or_plans(tmp_path, changes):
    config = copy.deepcopy(BASE)
    for section, value in changes.items():
        config[section] = {**config[section], **value} if isinstance(value, dict) else value
    try:
        plan(copy.deepcopy(config))
        refusal = None
    except ValueError as exc:
        refusal = str(exc)
    proc = _snakemake_n(tmp_path, config)
    if refusal is None:
        assert proc.returncode == 0, proc.stderr[-3000:]
    else:
        assert proc.returncode != 0
        problem = refusal.splitlines()[-1].strip().removeprefix("invalid configuration: ")
        assert problem in proc.stderr, (refusal, proc.stderr[-3000:])
        assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
