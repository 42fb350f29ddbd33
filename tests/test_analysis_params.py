"""The analysis config: Python defaults and the workflow schema agree (the imports of the package: tests/test_layering.py)."""

import copy
import glob
import os

import jsonschema
import numpy as np
import pytest
import yaml

from analysis.errors import ParamError
from analysis.params import DEFAULTS, resolve_params

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCHEMA = os.path.join(REPO, "analysis", "params.schema.yaml")


def _schema():
    """The schema of the ``analysis`` section ($defs/analysis of :data:`SCHEMA`)."""
    with open(SCHEMA, encoding="utf-8") as fh:
        return yaml.safe_load(fh)["$defs"]["analysis"]


def _fill_defaults(schema, instance):
    """What Snakemake's validate(set_default=True) does: fill defaults, recursively."""
    for key, sub in schema.get("properties", {}).items():
        if "default" in sub and key not in instance:
            instance[key] = copy.deepcopy(sub["default"])
        if sub.get("type") == "object" and isinstance(instance.get(key), dict):
            _fill_defaults(sub, instance[key])
    return instance


def test_schema_defaults_equal_python_defaults():
    assert _fill_defaults(_schema(), {}) == DEFAULTS


def test_defaults_valid_against_schema_and_every_key_described():
    schema = _schema()
    jsonschema.validate(DEFAULTS, schema)
    assert set(schema["properties"]) == set(DEFAULTS)
    for sec, sub in schema["properties"].items():
        assert set(sub["properties"]) == set(DEFAULTS[sec]), sec
        for key, spec in sub["properties"].items():
            assert spec.get("description"), f"{sec}.{key} lacks a description"


@pytest.mark.parametrize("bad", [
    {"rve": {"shape": "hexagon"}}, {"rve": {"size": 0}}, {"rve": {"min_solid_fraction": 1.5}},
    {"moduli": {"uncertainty": "jackknife"}}, {"grid": {"spacing": -0.01}}, {"unknown": {}},
    {"rve": {"unknown": 1}}, {"convergence": {"points": [[0.0]]}}, {"figures": {"heights": []}},
    {"base_pressure": {"stage": "relaxed; touch pwned"}}, {"base_pressure": {"stage": "reduced5"}},
])
def test_schema_and_python_refuse_the_same_bad_settings(bad):
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, _schema())
    with pytest.raises(ParamError):
        resolve_params(bad)


def test_resolve_merges_partial_sections():
    p = resolve_params({"rve": {"size": 0.1}, "checks": None})
    assert p["rve"]["size"] == 0.1 and p["rve"]["shape"] == DEFAULTS["rve"]["shape"]
    assert p["checks"] == DEFAULTS["checks"]


@pytest.mark.parametrize("user, words", [
    ({"rve": {"size": 50.0}}, ["analysis.rve.size = 50.0", "GiB", "raster_pixel = 0.0005"]),
    ({"grid": {"x_min": -50.0, "x_max": 50.0, "y_min": 0.0, "y_max": 50.0, "spacing": 0.1}},
     ["analysis.rve.size = 0.08 over the grid x -50.0 to 50.0", "GiB"]),
])
def test_settings_whose_raster_cannot_fit_are_refused_before_any_computation(user, words):
    """Both passed the checks once and then died in the solid fraction with a
    MemoryError (39 and 149 GiB): the raster grows with the grid's extent and
    the RVE, not with the number of RVEs."""
    import json

    from analysis.params import parse_params

    resolve_params(user)  # within every setting's range
    with pytest.raises(ParamError) as err:
        parse_params(json.dumps(user))
    assert all(w in str(err.value) for w in words), str(err.value)


def test_the_raster_estimate_bounds_what_the_solid_fraction_allocates():
    """tracemalloc's peak while rastering square RVEs over a grid lies within the
    estimate RASTER_BYTES_PER_PIXEL x pixels (and above half of it)."""
    import tracemalloc

    from analysis.solid_fraction import RASTER_BYTES_PER_PIXEL, Raster, raster_shape

    centres = np.array([[x, y] for x in np.linspace(-0.3, 0.3, 21) for y in np.linspace(0.015, 0.2, 7)])
    half, h = 0.04, 0.0005
    nx, ny = raster_shape(-0.3, 0.3, 0.2, half, h)
    tracemalloc.start()
    raster = Raster.covering(centres, half, h)
    raster.solid[::3, ::2] = True
    raster.window_fraction(centres, "square", 2 * half)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert (raster.nx, raster.ny) == (nx, ny)
    estimate = nx * ny * RASTER_BYTES_PER_PIXEL
    assert 0.8 * estimate < peak <= 1.05 * estimate, (peak, estimate)


@pytest.mark.parametrize("configfile", sorted(glob.glob(os.path.join(REPO, "config", "*.yaml"))))
def test_flow_text_reads_back_to_the_same_settings_without_double_quotes(configfile):
    """What the workflow passes as --params (params_flow_text): one line of
    YAML flow text with no double quote, backslash or line break (which the
    report would show escaped), read back to exactly the configured values;
    JSON still reads the same."""
    import json

    from analysis.params import params_flow_text, parse_params, settings_from_text

    with open(configfile, encoding="utf-8") as fh:
        section = (yaml.safe_load(fh) or {}).get("analysis") or {}
    text = params_flow_text(section)
    assert not set(text) & set('"\\\n'), text
    assert settings_from_text(text) == section
    assert parse_params(text) == parse_params(json.dumps(section))


def test_flow_text_keeps_values_that_yaml_would_read_otherwise():
    """Floats without a dot, infinities, null and strings that look like
    booleans or numbers come back as they were."""
    from analysis.params import params_flow_text, settings_from_text

    tricky = {"a": 1e-06, "b": float("inf"), "c": None, "d": "yes", "e": "1.0", "f": [1, "x y", True],
              "g": {"h": -2.5e300, "i": "null"}}
    text = params_flow_text(tricky)
    assert settings_from_text(text) == tricky, text
    assert settings_from_text('{"a": 1e-06}') == {"a": 1e-06}
    assert settings_from_text(params_flow_text({"a": "1e7"})) == {"a": "1e7"}   # text that reads as a number: quoted


@pytest.mark.parametrize("text, words", [
    ("{rve: [size: 0.08}", ["--params is neither JSON", "nor YAML", "{rve: {size: 0.08}}"]),
    ("[1, 2]", ["--params = '[1, 2]'", "holds a list, not a mapping of settings", "{rve: {size: 0.08}}"]),
    ("0.08", ["--params = '0.08' holds a number, not a mapping of settings"]),
])
def test_params_that_are_not_a_mapping_are_refused_naming_the_option(text, words):
    from analysis.params import parse_params

    with pytest.raises(ParamError) as err:
        parse_params(text)
    assert all(w in str(err.value) for w in words), str(err.value)
