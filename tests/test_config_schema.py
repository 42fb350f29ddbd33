"""workflow/schemas/config.schema.yaml: the study's configs validate, defaults
are filled in, and bad configs fail with a message that names the key, the
value and what is allowed."""

import copy
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from sim.config import SECTIONS, STAGE_SECTIONS, SimConfig

REPO = Path(__file__).resolve().parents[1]
SCHEMA = str(REPO / "workflow" / "schemas" / "config.schema.yaml")
# the numerics section's schema and the simulator's, which SCHEMA refers to
NUMERICS_SCHEMA = str(REPO / "workflow" / "schemas" / "numerics.schema.yaml")
SIM_SCHEMA = str(REPO / "sim" / "config.schema.yaml")


def load(name):
    return yaml.safe_load((REPO / "config" / name).read_text())


def schema(path=SCHEMA):
    return yaml.safe_load(Path(path).read_text())


@pytest.mark.parametrize("name", ["config.yaml", "smoke.yaml", "numerics_piles.yaml", "numerics_piles_ci.yaml"])
def test_shipped_configs_validate(name):
    config = load(name)
    validate(config, SCHEMA)
    assert config["model"]["integrator"] in ("gear", "verlet")


def test_paper_study():
    config = load("config.yaml")
    validate(config, SCHEMA)
    assert config["protocols"]["wedge"]["seeds"] == list(range(1, 10))
    assert config["protocols"]["layered"]["seeds"] == list(range(1, 11))
    assert config["pour"]["n_particles"] == 3500
    assert config["probe"]["levels"] == [0.10]
    assert config["model"]["youngs_modulus"] == 1.0e7


def test_the_smoke_runs_the_study_model():
    """config/smoke.yaml pours smaller piles, with the study's contact law,
    integrator, particles and physics (the schema fills in what it leaves out)."""
    study, smoke = load("config.yaml"), load("smoke.yaml")
    validate(study, SCHEMA)
    validate(smoke, SCHEMA)
    for section in ("model", "particles", "physics"):
        assert smoke[section] == study[section], section
    assert smoke["pour"]["n_particles"] < study["pour"]["n_particles"]


def test_defaults_are_filled_in():
    config = {"protocols": {"wedge": {"seeds": [3]}}}
    validate(config, SCHEMA)
    assert config["threads"] == 2
    # every simulator and analysis default is filled in, equal to the package's own
    # (the schema refers to the schemas that the packages ship)
    from analysis.params import DEFAULTS
    from sim.config import SimConfig
    for section, values in SimConfig().to_dict().items():
        assert config[section] == values, section
    assert config["analysis"] == DEFAULTS
    assert "layered" not in config["protocols"]  # a protocol not asked for is not run


def _set(path, value):
    def change(config):
        node = config
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return change


def _drop(key):
    return lambda config: config.pop(key)


# (change, substrings the error message must contain: key, value, what is allowed)
BAD = {
    "wrong type": (_set(["pour", "n_particles"], "many"),
                   ["'n_particles'", "'many'", "is not of type 'integer'"]),
    "missing protocols": (_drop("protocols"), ["'protocols' is a required property"]),
    "out of range": (_set(["model", "damping"], -1),
                     ["'damping'", "-1", "less than the minimum of 0"]),
    "level out of range": (_set(["probe", "levels"], [0.1, 1.5]),
                           ["'levels'", "1.5", "maximum of 1"]),
    "unknown key": (_set(["model", "fricton"], 0.3),
                    ["'fricton'", "'model'", "is not one of", "'friction'"]),
    "unknown top-level key": (_set(["thread"], 4),
                              ["'thread'", "is not one of", "'threads'"]),
    "unknown protocol": (_set(["protocols", "conical"], {"seeds": [1]}),
                         ["'conical'", "is not one of ['wedge', 'layered']"]),
    "no protocol": (_set(["protocols"], {}), ["'protocols'", "should be non-empty"]),
    "repeated seed": (_set(["protocols", "wedge", "seeds"], [1, 2, 1]),
                      ["'seeds'", "[1, 2, 1]", "non-unique"]),
    "negative seed": (_set(["protocols", "wedge", "seeds"], [-3]),
                      ["'seeds'", "-3", "minimum of 0"]),
    "bad enum": (_set(["model", "integrator"], "rk4"),
                 ["'integrator'", "'rk4'", "is not one of ['gear', 'verlet']"]),
    "dt not positive": (_set(["model", "dt"], 0.0),
                        ["'dt'", "0.0", "less than or equal to the minimum of 0"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_config_is_rejected_with_a_clear_message(case):
    change, expected = BAD[case]
    config = load("config.yaml")
    change(config)
    with pytest.raises(WorkflowError) as err:
        validate(config, SCHEMA)
    message = str(err.value)
    for text in expected:
        assert text in message, f"{text!r} not in:\n{message}"


def _objects(node, path=()):
    """Every object schema with `properties`, with its path."""
    if isinstance(node, dict):
        if "properties" in node:
            yield path, node
        for key, value in node.items():
            yield from _objects(value, path + (key,))


@pytest.mark.parametrize("file", [SCHEMA, NUMERICS_SCHEMA, SIM_SCHEMA], ids=["config", "numerics", "sim"])
def test_every_object_is_closed_and_lists_its_keys(file):
    for path, obj in _objects(schema(file)):
        assert obj.get("additionalProperties") is False, path
        assert obj["propertyNames"]["enum"] == list(obj["properties"]), path


@pytest.mark.parametrize("file", [SCHEMA, NUMERICS_SCHEMA, SIM_SCHEMA], ids=["config", "numerics", "sim"])
def test_every_key_is_documented_and_optional_keys_have_defaults(file):
    for path, obj in _objects(schema(file)):
        required = set(obj.get("required", []))
        for key, sub in obj["properties"].items():
            where = "/".join(path + (key,))
            if "$ref" in sub:  # protocols.wedge / .layered: absent = not run
                continue
            assert sub.get("description"), f"{where} has no description"
            if key not in required:
                assert "default" in sub, f"{where} is optional but has no default"


def test_defaults_satisfy_the_schema_and_the_simulators_own_checks():
    """The defaults alone (plus one protocol) form a valid config: the schema
    fills them in, and the simulator's own checks (ranges across settings, the
    particle recipe) accept the result; a default the checks refuse fails here."""
    from sim.config import SimConfig
    config = {"protocols": {"layered": {"seeds": [0]}}}
    validate(copy.deepcopy(config), SCHEMA, set_default=False)
    validate(config, SCHEMA)
    assert {"model", "particles", "pour", "relax", "probe", "physics"} <= set(config)
    cfg = SimConfig.from_dict(config)
    assert cfg.model.friction == config["model"]["friction"]
    assert cfg.particles.corners_min <= cfg.particles.corners_max
    broken = copy.deepcopy(config)
    broken["particles"]["corners_min"] = broken["particles"]["corners_max"] + 1
    validate(broken, SCHEMA)  # each value alone is in range
    with pytest.raises(Exception, match="corners"):
        SimConfig.from_dict(broken)


def test_the_settings_tables_of_the_docs_are_the_schemas():
    """docs/parameters.md lists every setting as the schemas define it
    (python -m workflow.tools settings_table made it; rerun it after a schema change)."""
    proc = subprocess.run([sys.executable, "-m", "workflow.tools", "settings_table", "--check",
                           str(REPO / "docs" / "parameters.md")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    page = (REPO / "docs" / "parameters.md").read_text()
    for section in ("model", "particles", "pour", "relax", "probe", "physics"):
        for key, spec in schema(SIM_SCHEMA)["$defs"][section]["properties"].items():
            assert f"| `{section}.{key}` |" in page, (section, key)


def test_the_section_map_is_the_simulators_configuration():
    """sim.config.SECTIONS are the sections SimConfig holds, and each stage's sections
    (STAGE_SECTIONS, the one map the workflow reads) are among them; the pour alone
    reads particles and physics (relax and probe take them from their state)."""
    assert SECTIONS == tuple(f.name for f in dataclasses.fields(SimConfig))
    assert all(set(s) <= set(SECTIONS) for s in STAGE_SECTIONS.values())
    assert {"particles", "physics"} <= set(STAGE_SECTIONS["pour"])
    assert not {"particles", "physics"} & (set(STAGE_SECTIONS["relax"]) | set(STAGE_SECTIONS["probe"]))
