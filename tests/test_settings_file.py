"""Configuration files that are not a mapping of settings (issue 28): each refused in
one line naming the file (and the line where the parser knows it), by the
simulator's ``--params @FILE``, by ``python -m workflow.validation`` and, for what
reaches it, by the Snakefile; before this, an empty file poured 3500 particles
with the defaults, a list or ``--params '[1,2]'`` ended in a TypeError, and a
repeated key silently kept its last value."""

import subprocess
import sys
from pathlib import Path

import pytest

from sim.cli import _load_params
from sim.config import ConfigError
from sim.settings_file import SettingsFileError, read_settings_file

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from workflow.validation import ConfigurationError, check_config_files, main  # noqa: E402

BAD = {  # file text: what the message must say
    "empty.yaml": ("", ["empty.yaml is empty", "mapping"]),
    "comment.yaml": ("# nothing but a comment\n", ["comment.yaml is empty"]),
    "list.yaml": ("- 1\n- 2\n", ["list.yaml holds a list", "mapping"]),
    "scalar.yaml": ("42\n", ["scalar.yaml holds a number"]),
    "syntax.yaml": ("pour:\n  rate: [1,\n", ["syntax.yaml:3:1:"]),
    "twice.yaml": ("pour:\n  rate: 1\nmodel: {}\npour:\n  rate: 2\n", ["twice.yaml:4:1:", "'pour' given twice",
                                                                    "first at line 1"]),
    "nested.yaml": ("pour:\n  rate: 1\n  rate: 2\n", ["nested.yaml:3:3:", "'rate' given twice"]),
    "bad.json": ('{"pour": {"rate": 1,}}', ["bad.json:1:", "not valid JSON"]),
}


@pytest.fixture
def bad_file(tmp_path, request):
    name = request.param
    text, words = BAD[name]
    path = tmp_path / name
    path.write_text(text)
    return path, words


@pytest.mark.parametrize("bad_file", sorted(BAD), indirect=True)
def test_each_bad_file_is_one_line_naming_it(bad_file):
    path, words = bad_file
    with pytest.raises(SettingsFileError) as err:
        read_settings_file(path)
    message = str(err.value)
    assert "\n" not in message and str(path.parent) in message
    assert all(w in message for w in words), message


@pytest.mark.parametrize("bad_file", ["empty.yaml", "list.yaml", "twice.yaml"], indirect=True)
def test_the_simulator_refuses_them_as_params_files(bad_file):
    path, words = bad_file
    with pytest.raises(ConfigError) as err:
        _load_params(f"@{path}")
    assert all(w in str(err.value) for w in words)


def test_params_text_must_be_an_object():
    with pytest.raises(ConfigError, match=r"--params = '\[1,2\]' holds a list, not a mapping of settings"):
        _load_params("[1,2]")
    assert _load_params('{"pour": {"rate": 50}, "analysis": {}}') == {"pour": {"rate": 50}}


def test_a_good_file_reads_as_yaml_reads_it(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("pour:\n  rate: 50\n  release_height: 0.1\nprotocols:\n  wedge: {seeds: [1, 2]}\n")
    assert read_settings_file(path) == {"pour": {"rate": 50, "release_height": 0.1},
                                        "protocols": {"wedge": {"seeds": [1, 2]}}}


def test_an_empty_section_over_another_file_is_refused(tmp_path):
    over = tmp_path / "none.yaml"
    over.write_text("protocols: {}\n")
    smoke = REPO / "config" / "smoke.yaml"
    with pytest.raises(ConfigurationError, match=r"none.yaml: protocols: \{\} is an empty mapping.*smoke.yaml"):
        check_config_files([smoke, over])
    # alone, the schema's "at least one protocol" refuses it
    assert main([str(over)]) == 2


def test_the_command_checks_files_then_their_merged_configuration(tmp_path, capsys):
    files = [str(REPO / "config" / "smoke.yaml"), str(REPO / "config" / "scenes" / "stress_only.yaml")]
    assert main(files) == 0 and capsys.readouterr().out.startswith("ok: ")
    no_outputs = tmp_path / "no_outputs.yaml"
    no_outputs.write_text("outputs: []\n")
    assert main(files[:1] + [str(no_outputs)]) == 2
    assert "outputs: [] should be non-empty" in capsys.readouterr().err
    missing = tmp_path / "missing.yaml"
    assert main(files[:1] + [str(missing)]) == 2
    err = capsys.readouterr().err
    assert "missing.yaml: cannot be read (FileNotFoundError" in err and err.count("\n") == 1


def test_the_snakefile_names_a_repeated_key(tmp_path):
    twice = tmp_path / "twice.yaml"
    twice.write_text("pour:\n  rate: 50\npour:\n  rate: 60\n")
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--cores", "1", "-s", str(REPO / "Snakefile"),
                           "--directory", str(tmp_path), "--configfile", str(REPO / "config" / "smoke.yaml"),
                           str(twice)], capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0
    assert f"{twice}:3:1: key 'pour' given twice (first at line 1)" in proc.stdout + proc.stderr
