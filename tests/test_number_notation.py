"""Settings read as physicists write them, one rule for JSON and YAML (issues 43
and 47), through every entry point: a settings file, the simulator's
``--params`` (inline or ``@FILE``, given twice), the workflow's validator on a
configuration file and on the configuration Snakemake itself read, the
analysis' ``--params``; and the results folder kept out of the sources.

Before this, PyYAML (YAML 1.1) read ``1e7``, ``1E-3``, ``-.5`` as text, so
``youngs_modulus: 1e7`` was refused as "'1e7' is not of type 'number'"; a JSON
file that gave ``"model"`` twice kept the last one silently; a second
``--params`` replaced the first; ``results: docs`` wrote the piles among the
sources.  The expected values below are written by hand.
"""

import math
import subprocess
import sys
from pathlib import Path

import pytest

from analysis.errors import ParamError
from analysis.params import parse_params
from sim.cli import _params, _parser
from sim.config import ConfigError
from sim.settings_file import SettingsFileError, number_from_text, read_settings, read_settings_file, yaml_value

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from workflow.validation import ConfigurationError, check_results_folder, load_config, main, validate_config  # noqa: E402

SMOKE = str(REPO / "config" / "smoke.yaml")

#: As written in a file, and the number it means.
NUMBERS = [
    ("1e7", 1.0e7),
    ("1E-3", 0.001),
    ("2.5e+6", 2500000.0),
    ("2.5E6", 2500000.0),
    ("1.0e6", 1000000.0),
    ("1.0e+7", 10000000.0),
    (".5", 0.5),
    ("-.5", -0.5),
    ("5.", 5.0),
    ("-3e-2", -0.03),
    ("+1e2", 100.0),
    ("1.0e300", 1.0e300),
    ("0.08", 0.08),
    ("800", 800),
    ("1_000", 1000),          # YAML 1.1's digit groups, as Snakemake reads them too
]
#: Text that is no number: a numeric setting refuses it.
TEXT = ["e7", "1e", "1e7x", "fast", "inf", "nan", "1.0 m", "--1", "1e7.5"]
#: As the numbers are written in a JSON file, those that JSON allows.
JSON_NUMBERS = [(text, value) for text, value in NUMBERS
                if text not in (".5", "-.5", "5.", "+1e2", "1_000")]


@pytest.mark.parametrize("text, value", NUMBERS)
def test_each_notation_reads_as_its_number(text, value):
    read = yaml_value(text)
    assert read == value and type(read) is type(value), (text, read)
    assert number_from_text(text) == value


@pytest.mark.parametrize("text", TEXT)
def test_text_that_is_no_number_stays_text(text):
    assert yaml_value(text) == text
    assert number_from_text(text) is None


def test_infinity_and_nan_only_in_yaml_s_own_spelling():
    assert yaml_value(".inf") == math.inf and yaml_value("-.inf") == -math.inf
    assert math.isnan(yaml_value(".nan"))
    assert yaml_value("1e400") == math.inf    # too large for a float: refused as not finite below


# --- a settings file ------------------------------------------------------------------

@pytest.mark.parametrize("text, value", NUMBERS)
def test_a_yaml_settings_file_reads_each_notation(tmp_path, text, value):
    path = tmp_path / "s.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\nprobe:\n  levels: [{text}, 0.1]\n")
    assert read_settings_file(path) == {"model": {"youngs_modulus": value}, "probe": {"levels": [value, 0.1]}}


@pytest.mark.parametrize("text, value", JSON_NUMBERS)
def test_a_json_settings_file_reads_each_notation(tmp_path, text, value):
    path = tmp_path / "s.json"
    path.write_text(f'{{"model": {{"youngs_modulus": {text}}}}}')
    assert read_settings_file(path) == {"model": {"youngs_modulus": value}}


# --- the simulator's --params ------------------------------------------------------------

POSITIVE = [(text, value) for text, value in NUMBERS if value > 0]


@pytest.mark.parametrize("text, value", POSITIVE)
def test_the_simulator_takes_each_notation_inline_and_from_a_file(tmp_path, text, value):
    assert _params(f"{{model: {{youngs_modulus: {text}}}}}").model.youngs_modulus == value
    path = tmp_path / "p.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    assert _params(f"@{path}").model.youngs_modulus == value


@pytest.mark.parametrize("text, value", [t for t in JSON_NUMBERS if t[1] > 0])
def test_the_simulator_takes_each_json_notation(text, value):
    assert _params(f'{{"model": {{"youngs_modulus": {text}}}}}').model.youngs_modulus == value


def test_a_negative_notation_reaches_a_setting_that_allows_it():
    assert _params("{physics: {walls: [-5e-2, +5E-2]}}").physics.walls == (-0.05, 0.05)


@pytest.mark.parametrize("text", TEXT)
def test_the_simulator_refuses_text_naming_the_file_setting_and_value(tmp_path, text):
    path = tmp_path / "p.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    with pytest.raises(ConfigError) as err:
        _params(f"@{path}")
    assert str(err.value) == f"--params @{path}: model.youngs_modulus = {text!r}: must be a number"


@pytest.mark.parametrize("text, words", [(".inf", "= inf: must be finite"), ("1e400", "= inf: must be finite"),
                                         ("-1e-3", "= -0.001: must be > 0")])
def test_the_simulator_refuses_numbers_out_of_range(text, words):
    with pytest.raises(ConfigError, match=words):
        _params(f"{{model: {{youngs_modulus: {text}}}}}")


def test_the_command_line_refuses_text_in_one_line(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("model:\n  youngs_modulus: 1e7x\n")
    proc = subprocess.run([sys.executable, "-m", "sim", "pour", "--params", f"@{path}", "--protocol", "wedge",
                           "--seed", "1", "--out", str(tmp_path / "pile.nc")],
                          capture_output=True, text=True, timeout=300, cwd=REPO)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(
        f"ERROR --params @{path}: model.youngs_modulus = '1e7x': must be a number"), proc.stderr


def test_the_numerical_checks_read_their_params_alike(tmp_path):
    from sim.numerics.command import load_section

    path = tmp_path / "n.yaml"
    path.write_text("numerics:\n  collisions:\n    overlap: 1E-3\n")
    assert load_section(f"@{path}", "collisions") == {"overlap": 0.001}
    assert load_section("{numerics: {collisions: {overlap: 2e-3}}}", "collisions") == {"overlap": 0.002}
    with pytest.raises(ConfigError, match=r"^--params:1:18: key 'numerics' given twice \(first at line 1\)$"):
        load_section('{"numerics": {}, "numerics": {}}', "collisions")


# --- a second --params (issue 43, item 8) ------------------------------------------------

@pytest.fixture
def study(tmp_path):
    path = tmp_path / "study.json"
    path.write_text('{"pour": {"n_particles": 300, "rate": 40.0}, "model": {"youngs_modulus": 2e7}}')
    return path


def test_a_second_params_changes_one_setting_of_the_first(study):
    args = _parser().parse_args(["pour", "--params", f"@{study}", "--params", '{"pour": {"n_particles": 200}}',
                                 "--protocol", "wedge", "--seed", "1", "--out", "x.nc"])
    cfg = _params(args.params)
    assert (cfg.pour.n_particles, cfg.pour.rate, cfg.model.youngs_modulus) == (200, 40.0, 2.0e7)


def test_the_later_params_wins(study):
    cfg = _params(['{pour: {n_particles: 200, rate: 2e1}}', f"@{study}"])
    assert (cfg.pour.n_particles, cfg.pour.rate) == (300, 40.0)


# --- one rule for a repeated key, JSON as YAML (issue 47, item 3) -------------------------

DUP_JSON = '{\n  "model": {"youngs_modulus": 1e7},\n  "model": {"damping": 0.5}\n}\n'
DUP_YAML = "model: {youngs_modulus: 1e7}\nmodel: {damping: 0.5}\n"


@pytest.mark.parametrize("name, text, where", [("dup.json", DUP_JSON, "3:3"), ("dup.yaml", DUP_YAML, "2:1")])
def test_a_repeated_key_is_refused_in_json_as_in_yaml(tmp_path, name, text, where):
    path = tmp_path / name
    path.write_text(text)
    first = {"dup.json": 2, "dup.yaml": 1}[name]
    message = f"{path}:{where}: key 'model' given twice (first at line {first})"
    with pytest.raises(SettingsFileError) as err:
        read_settings_file(path)
    assert str(err.value) == message
    with pytest.raises(ConfigError) as err:
        _params(f"@{path}")
    assert str(err.value) == message
    with pytest.raises(ParamError) as err:
        parse_params(f"@{path}")
    assert str(err.value) == message


def test_a_repeated_key_in_nested_json_names_its_place():
    with pytest.raises(SettingsFileError) as err:
        read_settings('{"pour": {"rate": 40, "n_particles": 3, "rate": 50}}')
    assert str(err.value) == "--params:1:41: key 'rate' given twice (first at line 1)"
    # the same key in two mappings is no repetition
    assert read_settings('{"a": {"x": 1}, "b": {"x": 2}}') == {"a": {"x": 1}, "b": {"x": 2}}


def test_inline_params_refuse_a_repeated_key_in_json_and_yaml():
    with pytest.raises(ConfigError, match=r"^--params:1:15: key 'model' given twice \(first at line 1\)$"):
        _params('{"model": {}, "model": {"damping": 0.5}}')
    with pytest.raises(ParamError, match=r"^--params:1:11: key 'rve' given twice \(first at line 1\)$"):
        parse_params("{rve: {}, rve: {size: 0.1}}")


def test_the_workflow_validator_refuses_a_repeated_key_in_json(tmp_path, capsys):
    path = tmp_path / "dup.json"
    path.write_text(DUP_JSON)
    assert main([SMOKE, str(path)]) == 2
    assert capsys.readouterr().err == f"{path}:3:3: key 'model' given twice (first at line 2)\n"


# --- the workflow's validator ------------------------------------------------------------

@pytest.mark.parametrize("text, value", POSITIVE)
def test_the_validator_reads_each_notation_in_a_config_file(tmp_path, text, value):
    path = tmp_path / "c.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    assert load_config([SMOKE, str(path)])["model"]["youngs_modulus"] == value


@pytest.mark.parametrize("text, value", POSITIVE)
def test_the_validator_reads_each_notation_as_snakemake_loaded_it(tmp_path, text, value):
    """Snakemake reads --configfile with its own loader (YAML 1.1: 1e7 is text);
    the validator the Snakefile runs turns the text into the number."""
    from snakemake.common.configfile import load_configfile

    path = tmp_path / "c.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    config = load_configfile(SMOKE)
    config["model"] = {**config.get("model", {}), **load_configfile(str(path))["model"]}
    validate_config(config)
    assert config["model"]["youngs_modulus"] == value


@pytest.mark.parametrize("text", TEXT)
def test_the_validator_refuses_text_naming_the_file_setting_and_value(tmp_path, capsys, text):
    path = tmp_path / "c.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    assert main([SMOKE, str(path)]) == 2
    assert capsys.readouterr().err == (
        f"{path}: model.youngs_modulus = {text!r}: must be a number > 0, not text (numbers are written "
        "unquoted: 800, 0.5, 2.5e-3, 1e7)\n")


def test_the_validator_refuses_a_quoted_number_in_a_file(tmp_path, capsys):
    path = tmp_path / "c.yaml"
    path.write_text("model:\n  youngs_modulus: '1e7'\n")
    assert main([SMOKE, str(path)]) == 2
    assert "model.youngs_modulus = '1e7': must be a number > 0, not text" in capsys.readouterr().err


@pytest.mark.parametrize("text", [".inf", "1e400"])
def test_the_validator_refuses_infinity(tmp_path, capsys, text):
    path = tmp_path / "c.yaml"
    path.write_text(f"model:\n  youngs_modulus: {text}\n")
    assert main([SMOKE, str(path)]) == 2
    assert capsys.readouterr().err == f"{path}: model.youngs_modulus = inf: must be finite, a number > 0\n"


def test_the_snakefile_passes_1e7_to_the_jobs_and_refuses_1e7x(tmp_path):
    good, bad = tmp_path / "good.yaml", tmp_path / "bad.yaml"
    good.write_text("model:\n  youngs_modulus: 1e7\n")
    bad.write_text("model:\n  youngs_modulus: 1e7x\n")
    run = [sys.executable, "-m", "snakemake", "-n", "-p", "--cores", "1", "-s", str(REPO / "Snakefile"),
           "--directory", str(tmp_path), "--configfile", SMOKE]
    proc = subprocess.run(run + [str(good)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert '"youngs_modulus": 10000000.0' in proc.stdout
    proc = subprocess.run(run + ["--config", "model={youngs_modulus: 2e7, damping: 0.5}"],
                          capture_output=True, text=True, timeout=300)   # --config gives a mapping as text
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert '"youngs_modulus": 20000000.0' in proc.stdout and '"damping": 0.5' in proc.stdout
    proc = subprocess.run(run + [str(bad)], capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0
    assert proc.stdout + proc.stderr == (f"{bad}: model.youngs_modulus = '1e7x': must be a number > 0, not text "
                                         "(numbers are written unquoted: 800, 0.5, 2.5e-3, 1e7)\n")


# --- the analysis' --params --------------------------------------------------------------

@pytest.mark.parametrize("text, value", [("8e-2", 0.08), ("8E-2", 0.08), (".08", 0.08), ("0.8e-1", 0.08)])
def test_the_analysis_reads_each_notation_inline_and_from_a_file(tmp_path, text, value):
    assert parse_params(f"{{rve: {{size: {text}}}}}")["rve"]["size"] == value
    path = tmp_path / "a.yaml"
    path.write_text(f"rve:\n  size: {text}\n")
    assert parse_params(f"@{path}")["rve"]["size"] == value


@pytest.mark.parametrize("text", TEXT)
def test_the_analysis_refuses_text_naming_the_setting_and_value(text):
    with pytest.raises(ParamError) as err:
        parse_params(f"{{rve: {{size: {text}}}}}")
    assert str(err.value) == f"analysis.rve.size = {text!r} is not a finite number"


# --- the results folder outside the sources ----------------------------------------------

SOURCES = ["docs", "sim", "analysis", "workflow", "config", "tests", "docs/x", "sim/deep/er", "config/results"]


@pytest.mark.parametrize("results", SOURCES)
def test_a_results_folder_in_the_sources_is_refused(monkeypatch, results):
    monkeypatch.chdir(REPO)
    folder = REPO / results
    source = REPO / results.split("/")[0]
    where = f"the source folder {folder}" if folder == source else f"{folder}, in the source folder {source}"
    with pytest.raises(ConfigurationError) as err:
        check_results_folder(results)
    assert str(err.value) == (
        f"invalid configuration: results = {results!r} is {where}, where the workflow would write its piles "
        f"and logs among the sources; give a folder under results/ (e.g. results/my_study) or outside {REPO}")


def test_the_repository_itself_and_a_link_into_the_sources_are_refused(monkeypatch, tmp_path):
    monkeypatch.chdir(REPO)
    with pytest.raises(ConfigurationError, match="is the repository itself"):
        check_results_folder(".")
    (tmp_path / "link").symlink_to(REPO / "docs")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigurationError, match=r"in the source folder .*docs"):
        check_results_folder("link/out")


@pytest.mark.parametrize("results", ["results/study", "results/docs", "results/sim/x", "elsewhere"])
def test_folders_under_results_or_outside_the_sources_are_allowed(monkeypatch, tmp_path, results):
    monkeypatch.chdir(REPO)
    check_results_folder(results)
    monkeypatch.chdir(tmp_path)
    check_results_folder("docs")   # another folder's docs/: not the project's


def test_the_validator_refuses_results_in_the_sources(monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(REPO)
    path = tmp_path / "c.yaml"
    path.write_text("results: docs\n")
    assert main([SMOKE, str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "results = 'docs' is the source folder" in err


def test_the_snakefile_refuses_results_in_the_sources_in_one_line(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("results: sim/piles\n")
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--cores", "1", "-s", str(REPO / "Snakefile"),
                           "--configfile", SMOKE, str(path)], capture_output=True, text=True, timeout=300, cwd=REPO)
    assert proc.returncode != 0
    line = (f"invalid configuration: results = 'sim/piles' is {REPO}/sim/piles, in the source folder {REPO}/sim, "
            "where the workflow would write its piles and logs among the sources; give a folder under results/ "
            f"(e.g. results/my_study) or outside {REPO}\n")
    assert proc.stdout + proc.stderr == line
    assert not (REPO / "sim" / "piles").exists()
