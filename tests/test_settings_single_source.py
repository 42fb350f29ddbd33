"""Every setting has one source: its JSON schema.

sim/config.schema.yaml holds the default and the allowed values of every
simulator setting, analysis/params.schema.yaml those of every analysis
setting (each package ships its own; the workflow's schema refers to both).  These tests read the schema files themselves (never
the copies the packages load) and hold against them:

* the dataclasses of sim/config.py, one per section with a field per
  setting (sim/config.py refuses one that names other settings);
* their defaults and those of ``DEFAULTS`` of analysis/params.py, value and
  type;
* their validation, probed at and just beyond every bound the schema gives
  (minimum / maximum, exclusiveMinimum / exclusiveMaximum), on the
  unbounded side far out, with the wrong types, with integer-valued floats
  for integers, with the choices of an enum and a value outside them, with
  null, and for lists with their items, lengths and repeats: a value the
  schema allows must be accepted, one it forbids refused (ConfigError /
  ParamError naming the setting).  The schema decides (jsonschema), plus the
  two rules the workflow adds to JSON schema (workflow/validation.py): a
  number must be finite, and an integer setting takes no float;
* the keyword defaults of the public functions whose keywords mirror
  settings (sim.shapes.make_shapes and sim.polygon.random_polygon, the physics keywords
  of sim.engine.Simulation, sim.numerics.polygons.shapes_of), and the
  ranges that make_shapes accepts;
* config/config.yaml writes out every simulator and analysis setting, the
  analysis ones at their defaults.
"""

import copy
import dataclasses
import inspect
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from jsonschema import Draft202012Validator

from analysis.errors import ParamError
from analysis.params import DEFAULTS, resolve_params
import sim.config as sim_config
from sim.config import ConfigError, SimConfig

REPO = Path(__file__).resolve().parents[1]


def _load(path):
    return yaml.safe_load(Path(path).read_text())


#: The simulator's sections and the analysis section, as the packages ship them.
SIM = _load(REPO / "sim" / "config.schema.yaml")["$defs"]
ANALYSIS = _load(REPO / "analysis" / "params.schema.yaml")["$defs"]["analysis"]

#: The simulator's sections: name -> dataclass.
SECTIONS = {f.name: f.default_factory for f in dataclasses.fields(SimConfig)}
SIM_SETTINGS = [(section, f.name) for section, klass in SECTIONS.items()
                for f in dataclasses.fields(klass)]
ANALYSIS_SETTINGS = [(section, key) for section, sub in ANALYSIS["properties"].items()
                     for key in sub["properties"]]


def sim_schema(section, name):
    return SIM[section]["properties"][name]


def analysis_schema(section, key):
    return ANALYSIS["properties"][section]["properties"][key]


def _ids(settings):
    return [".".join(s) for s in settings]


# --- what the schema allows ---------------------------------------------------

def _types(schema):
    kinds = schema.get("type", [])
    return [kinds] if isinstance(kinds, str) else list(kinds)


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _workflow_rules(schema, value):
    """The workflow's two rules beyond JSON schema: finite numbers, no floats for
    integers (workflow/validation.py, number_problems)."""
    if isinstance(value, list) and isinstance(schema.get("items"), dict):
        return all(_workflow_rules(schema["items"], v) for v in value)
    if isinstance(value, float):
        kinds = _types(schema)
        return math.isfinite(value) and not ("integer" in kinds and "number" not in kinds)
    return True


def schema_allows(schema, value):
    return Draft202012Validator(schema).is_valid(value) and _workflow_rules(schema, value)


# --- probes derived from a setting's schema --------------------------------------

LARGE = 10**12  # far out on an unbounded side


def _scalar_probes(schema):
    kinds = _types(schema)
    probes = [None]
    if "enum" in schema:
        return probes + list(schema["enum"]) + [f"not-{schema['enum'][0]}", 1, True]
    if "boolean" in kinds:
        return probes + [True, False, 0, 1, "true"]
    if "string" in kinds:
        default = schema.get("default") or ""
        probes += [default, "", 1, True]
        if "pattern" in schema:
            probes += [default + "0", default + "00", default + ";", " " + default,
                       default.upper(), "poured", "relaxed", "reduced", "reduced10",
                       "reduced5", "reduced100", "reducedXX", "relaxed.nc"]
        return probes
    assert "number" in kinds or "integer" in kinds, schema
    integer = "number" not in kinds

    def beyond(bound, up):  # the nearest value past an inclusive bound
        if integer:
            return bound + (1 if up else -1)
        return math.nextafter(bound, math.inf if up else -math.inf)

    def inside(bound, up):  # a value just inside an exclusive bound
        if integer:
            return bound + (1 if up else -1)
        return bound + (1e-9 * max(1.0, abs(bound))) * (1 if up else -1)

    if "minimum" in schema:
        probes += [schema["minimum"], beyond(schema["minimum"], up=False)]
    if "exclusiveMinimum" in schema:
        probes += [schema["exclusiveMinimum"], inside(schema["exclusiveMinimum"], up=True)]
    if "maximum" in schema:
        probes += [schema["maximum"], beyond(schema["maximum"], up=True)]
    if "exclusiveMaximum" in schema:
        probes += [schema["exclusiveMaximum"], inside(schema["exclusiveMaximum"], up=False)]
    if "minimum" not in schema and "exclusiveMinimum" not in schema:
        probes.append(-LARGE if integer else -float(LARGE))
    if "maximum" not in schema and "exclusiveMaximum" not in schema:
        probes.append(LARGE if integer else float(LARGE))
    probes += [math.inf, -math.inf, math.nan, True, "1"]
    if integer:  # an integer-valued float of an allowed integer
        allowed = [p for p in probes if _number(p) and schema_allows(schema, p)]
        probes.append(float(allowed[0]))
    return probes


def _filled(item, n):
    """A list of `n` items starting with `item`: numbers counting up from it (so
    that they are distinct and increasing), anything else repeated."""
    return [item + k if _number(item) else copy.deepcopy(item) for k in range(n)]


def probes(schema, default=None):
    """Values to try on a setting with this schema."""
    if "array" not in _types(schema):
        return _scalar_probes(schema)
    items = schema["items"]
    n = max(1, schema.get("minItems", 0))
    out = [None, 0.0, []]  # not a list, and the empty list
    item_probes = probes(items)
    out += [_filled(item, n) for item in item_probes]
    valid = (default[0] if default else
             next(item for item in item_probes if schema_allows(items, item)))
    if schema.get("minItems", 0) > 1:
        out.append(_filled(valid, schema["minItems"] - 1))
    if "maxItems" in schema:
        out.append(_filled(valid, schema["maxItems"] + 1))
    if schema.get("uniqueItems"):
        out.append([valid, copy.deepcopy(valid)])
    return out


def _with_companions(value, companions, schema_of):
    """Other settings that make `value` feasible under the checks a schema cannot
    express (corners_max >= corners_min, ...); each kept only where its own
    schema allows it."""
    extra = companions(value) if _number(value) and math.isfinite(value) else {}
    return {k: v for k, v in extra.items() if schema_allows(schema_of(k), v)}


# --- the simulator's dataclasses ----------------------------------------------

SIM_DEFAULTS = {section: klass() for section, klass in SECTIONS.items()}


def _sim_default(section, name):
    return getattr(SIM_DEFAULTS[section], name)


#: Cross-setting checks of sim/config.py: what to set beside a probed value.
SIM_COMPANIONS = {
    ("particles", "corners_min"): lambda v: (
        {"corners_max": v} if v > _sim_default("particles", "corners_max") else {}),
    ("particles", "corners_max"): lambda v: (
        {"corners_min": v} if v < _sim_default("particles", "corners_min") else {}),
    ("relax", "max_time"): lambda v: {"hold_time": min(v, _sim_default("relax", "hold_time"))},
    ("relax", "hold_time"): lambda v: {"max_time": max(v, _sim_default("relax", "max_time"))},
}


def _plain(value):
    """Tuples (the dataclasses' immutable lists) as lists."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _same(a, b):
    """Equal, and of the same types (6 is not 6.0)."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def test_the_dataclasses_are_the_schema_sections():
    assert list(SECTIONS) == list(SIM) == list(sim_config.SECTIONS)


@pytest.mark.parametrize("section", sorted(SECTIONS))
def test_the_dataclass_fields_are_the_schema_settings(section):
    fields = [f.name for f in dataclasses.fields(SECTIONS[section])]
    assert set(fields) == set(SIM[section]["properties"]), section


def test_a_dataclass_that_names_other_settings_than_the_schema_is_refused():
    class Model:
        youngs_modulus: float
        young_modulus: float

    with pytest.raises(TypeError, match=r"Model: fields \['young_modulus'\] are no settings of model .*"
                                        r"settings \['damping', .*\] have no field"):
        sim_config._settings("model")(Model)


@pytest.mark.parametrize("section, name", SIM_SETTINGS, ids=_ids(SIM_SETTINGS))
def test_the_dataclass_default_is_the_schema_default(section, name):
    expected = sim_schema(section, name)["default"]
    field = {f.name: f for f in dataclasses.fields(SECTIONS[section])}[name]
    assert _same(_plain(field.default), expected), (field.default, expected)
    assert _same(_plain(_sim_default(section, name)), expected)


def _disagreement(value, expected, call, error_type, name):
    """None if ``call()`` accepts `value` exactly when the schema allows it (and a
    refusal names the setting `name`), else what went wrong."""
    try:
        call()
    except error_type as err:
        if expected:
            return f"{value!r} refused, but the schema allows it: {err}"
        if name not in str(err):
            return f"{value!r} refused, but the message does not name {name}: {err}"
        return None
    except Exception as err:  # noqa: BLE001 - a crash is a disagreement too
        return f"{value!r} raised {type(err).__name__} ({err}), not {error_type.__name__}"
    return None if expected else f"{value!r} accepted, but the schema forbids it"


@pytest.mark.parametrize("section, name", SIM_SETTINGS, ids=_ids(SIM_SETTINGS))
def test_the_dataclass_accepts_what_the_schema_allows(section, name):
    schema = sim_schema(section, name)
    companions = SIM_COMPANIONS.get((section, name), lambda v: {})
    wrong = []
    for value in probes(schema, schema.get("default")):
        extra = _with_companions(value, companions, lambda key: sim_schema(section, key))
        wrong.append(_disagreement(
            value, schema_allows(schema, value),
            lambda: SECTIONS[section](**{name: value, **extra}), ConfigError,
            f"{section}.{name}"))
    wrong = [w for w in wrong if w]
    assert not wrong, f"{section}.{name}:\n  " + "\n  ".join(wrong)


# --- the analysis parameters -------------------------------------------------

def _analysis_defaults():
    return {section: {key: sub_schema["default"]
                      for key, sub_schema in sub["properties"].items()}
            for section, sub in ANALYSIS["properties"].items()}


def test_analysis_defaults_are_the_schema_defaults():
    expected = _analysis_defaults()
    assert set(DEFAULTS) == set(expected)
    for section, values in expected.items():
        assert set(DEFAULTS[section]) == set(values), section
        for key, value in values.items():
            assert _same(DEFAULTS[section][key], value), f"{section}.{key}"
    assert resolve_params({}) == expected


def _analysis_default(section, key):
    return analysis_schema(section, key)["default"]


#: Cross-setting checks of resolve_params: what to set beside a probed value.
ANALYSIS_COMPANIONS = {
    ("grid", "x_min"): lambda v: {"x_max": v},
    ("grid", "x_max"): lambda v: {"x_min": v},
    ("grid", "y_min"): lambda v: {"y_max": v},
    ("grid", "y_max"): lambda v: {"y_min": v},
    ("grid", "spacing"): lambda v: {"x_min": 0.0, "x_max": 0.0, "y_min": 0.0, "y_max": 0.0},
    ("rve", "size"): lambda v: {"raster_pixel": min(v / 4, _analysis_default("rve", "raster_pixel"))},
    ("rve", "raster_pixel"): lambda v: {"size": max(4 * v, _analysis_default("rve", "size"))},
    ("base_pressure", "x_min"): lambda v: {"x_max": v + 1},
    ("base_pressure", "x_max"): lambda v: {"x_min": v - 1},
    ("base_pressure", "bin_width"): lambda v: {"x_min": -v, "x_max": v},
    ("history", "centre"): lambda v: {"shoulder_inner": 2 * v, "shoulder_outer": 3 * v},
    ("history", "shoulder_inner"): lambda v: {"centre": v / 2, "shoulder_outer": 2 * v},
    ("history", "shoulder_outer"): lambda v: {"centre": v / 4, "shoulder_inner": v / 2},
    ("history", "flank_inner"): lambda v: {"flank_outer": 2 * v + 1},
    ("history", "flank_outer"): lambda v: {"flank_inner": v / 2},
}


@pytest.mark.parametrize("section, key", ANALYSIS_SETTINGS, ids=_ids(ANALYSIS_SETTINGS))
def test_the_analysis_accepts_what_the_schema_allows(section, key):
    schema = analysis_schema(section, key)
    companions = ANALYSIS_COMPANIONS.get((section, key), lambda v: {})
    wrong = []
    for value in probes(schema, schema.get("default")):
        extra = _with_companions(value, companions, lambda k: analysis_schema(section, k))
        wrong.append(_disagreement(
            value, schema_allows(schema, value),
            lambda: resolve_params({section: {key: value, **extra}}), ParamError,
            f"analysis.{section}.{key}"))
    wrong = [w for w in wrong if w]
    assert not wrong, f"analysis.{section}.{key}:\n  " + "\n  ".join(wrong)


# --- public functions whose keywords mirror settings ------------------------------

def _keyword_defaults():
    from sim.engine import Simulation
    from sim.numerics.polygons import shapes_of
    from sim.polygon import random_polygon
    from sim.shapes import make_shapes

    particles = {name: ("particles", name) for name in SIM["particles"]["properties"]}
    return [
        (make_shapes, {**particles, "density": ("model", "density")}),
        (random_polygon, {"min_edge_fraction": ("particles", "min_edge_fraction"),
                          "min_angle_deg": ("particles", "min_angle_deg")}),
        (Simulation, {"support": ("physics", "support"), "walls": ("physics", "walls"),
                      "rotate": ("physics", "rotation")}),
        (shapes_of, {"density": ("model", "density")}),
    ]


def test_keyword_defaults_are_the_schema_defaults():
    wrong = []
    for function, keywords in _keyword_defaults():
        parameters = inspect.signature(function).parameters
        for keyword, (section, name) in keywords.items():
            default = parameters[keyword].default
            expected = sim_schema(section, name)["default"]
            if not _same(_plain(default), expected):
                wrong.append(f"{function.__qualname__}({keyword}={default!r}): the schema's "
                             f"{section}.{name} is {expected!r}")
    assert not wrong, "\n".join(wrong)


MAKE_SHAPES = {**{name: ("particles", name) for name in SIM["particles"]["properties"]},
               "density": ("model", "density")}


@pytest.mark.parametrize("keyword", sorted(MAKE_SHAPES))
def test_make_shapes_accepts_the_ranges_of_the_settings(keyword):
    """make_shapes takes the particles settings (and model.density): at and beyond
    each bound it agrees with the schema (numbers only: as a Python function it
    may convert other types)."""
    from sim.shapes import make_shapes

    section, name = MAKE_SHAPES[keyword]
    schema = sim_schema(section, name)
    companions = {"corners_min": SIM_COMPANIONS[("particles", "corners_min")],
                  "corners_max": SIM_COMPANIONS[("particles", "corners_max")]}
    wrong = []
    for value in probes(schema):
        if not _number(value):
            continue
        extra = _with_companions(value, companions.get(keyword, lambda v: {}),
                                 lambda k: sim_schema("particles", k))
        wrong.append(_disagreement(
            value, schema_allows(schema, value),
            lambda: make_shapes(np.random.default_rng(0), 0, **{keyword: value, **extra}),
            ValueError, keyword))
    wrong = [w for w in wrong if w]
    assert not wrong, f"make_shapes({keyword}=...) against {section}.{name}:\n  " \
                      + "\n  ".join(wrong)


# --- the study's configuration --------------------------------------------------

def test_the_study_config_writes_out_every_setting():
    study = _load(REPO / "config" / "config.yaml")
    for section in SECTIONS:
        assert set(study[section]) == set(SIM[section]["properties"]), section
    expected = _analysis_defaults()
    assert set(study["analysis"]) == set(expected)
    for section, values in expected.items():
        assert set(study["analysis"][section]) == set(values), section
        for key, value in values.items():
            assert _same(study["analysis"][section][key], value), f"analysis.{section}.{key}"
