"""workflow/validation.py, the one validator the Snakefile runs before any
job: every numeric setting must be finite and of its type, and what the
simulator or the analysis would refuse when a job starts is refused here,
each time naming the setting."""

import copy
import math
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from workflow.validation import CONFIG_SCHEMA, ConfigurationError, validate_config  # noqa: E402

def valid_config():
    """The smoke study with every default filled in, side walls and a tilted probe
    (so that every list of numbers has an item to spoil)."""
    config = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
    config["physics"] = {"walls": [-0.05, 0.05]}
    config["probe"] = {"tilts": [0.05]}
    validate_config(config)
    return config


BASE = valid_config()


def numeric_keys(schema, root, path=()):
    """(path, schema) of every number in the configuration; a list item's path
    holds the index 0. A ``$ref`` to another schema file (numerics.schema.yaml,
    the packages' sim/config.schema.yaml and analysis/params.schema.yaml) is
    followed into that file."""
    while "$ref" in schema:
        file, _, pointer = schema["$ref"].partition("#")
        if file:
            root = _schema(Path(CONFIG_SCHEMA).parent / file)
        node = root
        for part in filter(None, pointer.split("/")):
            node = node[part]
        schema = node
    kinds = schema.get("type", [])
    kinds = [kinds] if isinstance(kinds, str) else kinds
    if "number" in kinds or "integer" in kinds:
        yield path, schema
    for name, sub in schema.get("properties", {}).items():
        yield from numeric_keys(sub, root, path + (name,))
    if isinstance(schema.get("items"), dict):
        yield from numeric_keys(schema["items"], root, path + (0,))


def _schema(path):
    return yaml.safe_load(Path(path).read_text())


KEYS = [(path, sub) for path, sub in numeric_keys(_schema(CONFIG_SCHEMA), _schema(CONFIG_SCHEMA))]


def with_value(path, value):
    config = copy.deepcopy(BASE)
    node = config
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value
    return config


def bad_values(schema):
    """Values a numeric setting must refuse: not finite, of the wrong type (text
    that is no number: text that is one, as Snakemake's readers leave 1e7, is
    read as the number), below a non-negative minimum, a float for an integer."""
    values = [st.sampled_from([math.nan, math.inf, -math.inf, "1.0 m", "many", "1e7x", [1.0], True,
                               {"value": 1}])]
    low = schema.get("minimum", schema.get("exclusiveMinimum"))
    if low is not None and low >= 0:
        values.append(st.floats(max_value=-1e-9, allow_nan=False, allow_infinity=False))
        values.append(st.integers(max_value=-1))
    if schema.get("type") == "integer":
        values.append(st.integers(-10**6, 10**6).map(float))
    return st.one_of(values)


@st.composite
def bad_settings(draw):
    path, schema = draw(st.sampled_from(KEYS))
    return path, draw(bad_values(schema))


def test_every_numeric_key_is_covered():
    names = {".".join(map(str, path)) for path, _ in KEYS}
    for key in ("model.youngs_modulus", "pour.n_particles", "relax.max_time",
                "probe.levels.0", "probe.tilts.0", "physics.walls.0", "protocols.wedge.seeds.0",
                "analysis.strain.min_contacts", "analysis.convergence.points.0.0",
                "numerics.collisions.cases.0.damping"):
        assert key in names, key
    assert len(KEYS) > 80


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bad_settings())
def test_a_bad_number_anywhere_is_refused_naming_its_key(case):
    path, value = case
    with pytest.raises(ConfigurationError) as err:
        validate_config(with_value(path, value))
    key = ".".join(str(part) for part in path)
    named = str(err.value).replace("[", ".").replace("]", "")
    assert key in named, (path, value, str(err.value))


@pytest.mark.parametrize("path, value, message", [
    # issue 12, 3: refused in the dry run, never by a job or a resource function
    (("model", "youngs_modulus"), math.nan, "model.youngs_modulus = nan: must be finite"),
    (("model", "damping"), math.nan, "model.damping = nan: must be finite, a number >= 0 and <= 10"),
    (("relax", "max_time"), math.nan, "relax.max_time = nan: must be finite"),
    (("pour", "rate"), math.inf, "pour.rate = inf: must be finite, a number > 0"),
    (("probe", "levels"), [0.1, math.nan], "probe.levels[1] = nan"),
    (("probe", "tilts"), [0.05, 0.6], "probe.tilts"),
    # integer-valued floats: what the simulator and the analysis refuse, the validator refuses
    (("pour", "n_particles"), 3500.0, "pour.n_particles = 3500.0: must be an integer (write 3500)"),
    (("analysis", "strain", "min_contacts"), 20.0, "analysis.strain.min_contacts = 20.0"),
    # analysis settings and cross-checks: refused before the simulations, not after
    (("analysis", "grid", "x_min"), 0.5, "analysis.grid.x_min = 0.5 must be <= analysis.grid.x_max"),
    (("analysis", "grid", "spacing"), 1e-7, "grid points (more than 10^6)"),
    (("relax", "hold_time"), 5.0, "relax.hold_time = 5.0: must be <= relax.max_time = 3.0"),
    (("physics", "walls"), [-0.002, 0.002], "the walls must be farther apart"),
])
def test_named_bad_settings_are_refused_with_setting_value_and_what_is_allowed(path, value,
                                                                               message):
    with pytest.raises(ConfigurationError, match="invalid configuration") as err:
        validate_config(with_value(path, value))
    assert message in str(err.value)


def test_the_simulator_agrees_with_the_validator_on_integers():
    """Both refuse 3500.0 (JSON schema alone took it for an integer)."""
    from sim.config import ConfigError, SimConfig

    with pytest.raises(ConfigError, match="pour.n_particles = 3500.0: must be an integer"):
        SimConfig.from_dict({"pour": {"n_particles": 3500.0}})


def test_valid_configs_pass_and_get_their_defaults():
    for name in ("config.yaml", "smoke.yaml", "numerics_piles_ci.yaml"):
        config = yaml.safe_load((REPO / "config" / name).read_text())
        validate_config(config)
        assert config["analysis"]["grid"]["spacing"] > 0
        assert config["pour"]["checkpoint_interval"] > 0


def test_a_crafted_stage_is_refused_even_when_no_fields_are_asked_for():
    """analysis.base_pressure.stage reaches a file name in a shell command."""
    config = with_value(("outputs",), ["states"])
    config["analysis"]["base_pressure"]["stage"] = "relaxed.nc; touch pwned; echo "
    with pytest.raises(ConfigurationError, match="analysis.base_pressure.stage"):
        validate_config(config)


def test_a_pattern_is_refused_with_its_rule_in_words():
    """No regular expression reaches a user: every ``pattern`` of the schemas has
    its rule in words beside it (``patternWords``), and a refused value is
    named with those words."""
    import yaml as _yaml

    from workflow.validation import ConfigurationError, validate_config
    from workflow_config import configuration

    def patterns(node):
        if isinstance(node, dict):
            if "pattern" in node and isinstance(node["pattern"], str):
                yield node
            for value in node.values():
                yield from patterns(value)
        elif isinstance(node, list):
            for value in node:
                yield from patterns(value)

    files = [REPO / "workflow" / "schemas" / "config.schema.yaml", REPO / "workflow" / "schemas" /
             "numerics.schema.yaml", REPO / "sim" / "config.schema.yaml", REPO / "analysis" / "params.schema.yaml"]
    found = [node for f in files for node in patterns(_yaml.safe_load(f.read_text()))]
    assert len(found) >= 3 and all(node.get("patternWords") for node in found)
    config = configuration()
    config["results"] = "my results/ü"
    with pytest.raises(ConfigurationError) as refused:
        validate_config(config)
    message = str(refused.value)
    assert "results = 'my results/ü': allowed: a relative folder" in message and "^[" not in message
