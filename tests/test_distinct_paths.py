"""No output of a command line is one of its inputs or another of its outputs
(sim.distinct_paths, issue 47 item 5): ``pour --out a.nc --checkpoint a.nc`` said
"done" and left no a.nc, ``--frames b.nc --out b.nc`` lost the frames,
``analysis fields --relaxed R.nc --out R.nc`` replaced its input. Every such
command line is refused in one line naming both options and the file, before
anything runs; every option of every subcommand of both command lines is
walked through the check. Seeds out of the generator's range and bench
thread counts beyond the machine's are refused the same way (items 7, 10)."""

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

import analysis.__main__ as analysis_main
from analysis.numerics import ensemble_cost, pile_precision, piles_report
from analysis.command_files import NUMERICS_PATHS, PATHS as ANALYSIS_PATHS, labelled
from sim import cli
from sim.numerics import command, kernel_profile
from sim.distinct_paths import PathCollision, PathRoles, at_file, check_distinct_paths

REPO = Path(__file__).resolve().parents[1]
TINY = '{"pour": {"n_particles": 20}}'   # should a refused pour run after all: seconds, not hours


def _run(tmp_path, *args):
    """``python *args`` in `tmp_path`: (exit status, stderr lines)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    done = subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=tmp_path,
                          env=env, timeout=600)
    return done.returncode, done.stderr.strip().splitlines()


def _refused(tmp_path, *args, says=()):
    """Run the command line; it must end with status 2 and one line holding each of `says`."""
    status, lines = _run(tmp_path, *args)
    assert status == 2 and len(lines) == 1, (status, lines)
    for words in says:
        assert words in lines[0], (words, lines[0])
    return lines[0]


def test_a_pour_whose_output_is_its_checkpoint_is_refused_before_it_runs(tmp_path):
    _refused(tmp_path, "-m", "sim", "pour", "--params", TINY, "--protocol", "wedge", "--seed", "1",
             "--out", "a.nc", "--checkpoint", "a.nc",
             says=("--checkpoint a.nc", "--out a.nc", str(tmp_path / "a.nc")))
    assert list(tmp_path.iterdir()) == []


def test_a_pour_whose_frames_are_its_output_is_refused(tmp_path):
    _refused(tmp_path, "-m", "sim", "pour", "--params", TINY, "--protocol", "wedge", "--seed", "1",
             "--frames", "b.nc", "--out", "b.nc", says=("--frames b.nc", "--out b.nc"))
    assert list(tmp_path.iterdir()) == []


def test_fields_written_over_the_state_they_read_are_refused_and_the_state_kept(tmp_path):
    state = tmp_path / "R.nc"
    state.write_bytes(b"the relaxed state")
    _refused(tmp_path, "-m", "analysis", "fields", "--relaxed", "R.nc", "--out", "R.nc",
             says=("--out R.nc", "--relaxed R.nc", str(state)))
    assert state.read_bytes() == b"the relaxed state"


def test_an_output_reached_through_a_symbolic_link_or_a_hard_link_is_the_same_file(tmp_path,
                                                                                  monkeypatch):
    (tmp_path / "link.nc").symlink_to(tmp_path / "x.nc")
    _refused(tmp_path, "-m", "sim", "pour", "--params", TINY, "--protocol", "wedge", "--seed", "1",
             "--out", "x.nc", "--frames", "link.nc",
             says=("--frames link.nc", "--out x.nc", str(tmp_path / "x.nc")))
    monkeypatch.chdir(tmp_path)
    Path("settings.yaml").write_text("pour: {n_particles: 20}\n")
    os.link("settings.yaml", "hard.yaml")
    args = cli._parser().parse_args(["relax", "--params", "@settings.yaml", "--input", "s.nc",
                                     "--out", "hard.yaml"])
    with pytest.raises(PathCollision, match="--out hard.yaml and --params @settings.yaml"):
        check_distinct_paths(args, cli.PATHS["relax"])


@pytest.mark.parametrize("argv,says", [
    (["--out", "c.nc.lock", "--checkpoint", "c.nc"], "the lock c.nc.lock of --checkpoint c.nc"),
    (["--out", "s.nc", "--checkpoint", "c.nc", "--frames", "c.frames.nc"],
     "the frames so far c.frames.nc of --checkpoint c.nc"),
    (["--out", "s.nc", "--log", "s.lastgood.nc"], "the last good state s.lastgood.nc of --out s.nc"),
    (["--out", "s.nc", "--params", "@s.nc"], "--out s.nc and --params @s.nc"),
])
def test_the_files_a_pour_derives_from_its_paths_take_part(argv, says):
    args = cli._parser().parse_args(["pour", "--protocol", "wedge", "--seed", "1", *argv])
    with pytest.raises(PathCollision, match=says.replace(".", r"\.")):
        check_distinct_paths(args, cli.PATHS["pour"])


def test_export_s_contact_network_over_its_input_is_refused(tmp_path):
    args = analysis_main.build_parser().parse_args(
        ["export", "--input", "s_contacts.vtu", "--vtk", "s.vtu"])
    with pytest.raises(PathCollision, match="the contact network s_contacts.vtu of --vtk s.vtu"):
        check_distinct_paths(args, ANALYSIS_PATHS["export"])


# ------------------------------------------------------------ the walk over every option
def _subparsers(parser):
    """The subcommands of `parser` by name."""
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


#: Every command line: (name, parser, roles), the subcommands of both CLIs and the numerics checks.
COMMAND_LINES = (
    [(f"sim {name}", p, cli.PATHS[name]) for name, p in _subparsers(cli._parser()).items()
     if name != "numerics"]
    + [(f"sim numerics {name}", command.parser(name, ""), command.PATHS)
       for name in ("collisions", "stability")]
    + [("sim numerics kernel-profile", kernel_profile._parser(), kernel_profile.PATHS)]
    + [(f"analysis {name}", p, ANALYSIS_PATHS[name])
       for name, p in _subparsers(analysis_main.build_parser()).items()]
    + [(f"{top.prog} {name}", p, NUMERICS_PATHS[top.prog, name])
       for top in (pile_precision._parser(), ensemble_cost._parser())
       for name, p in _subparsers(top).items()]
    + [(piles_report._parser().prog, piles_report._parser(), NUMERICS_PATHS[piles_report._parser().prog, None])])

#: Options that name no file, and a value for each that a command line needs.
NOT_PATHS = {"--protocol": "wedge", "--seed": "1", "--bookkeeping": None, "--level": "0.1",
             "--tilt": None, "--restore": None, "--stretch": None, "--stage": None,
             "--sizes": None, "--steps": None, "--repeats": None, "--integrators": None,
             "--threads": None, "--peer": None, "--kernel": None, "--quantities": None,
             "--core-x": None, "--core-y": None, "--color-by": None, "--forces": None,
             "--dpi": None, "--fps": None, "--title": None, "name": "fabric",
             "--model": None, "--seeds": "1"}

#: Options that are settings as JSON text, not a file, in the command lines of analysis.numerics.
JSON_TEXT = {"--params": "{}"}


def _option(action):
    """An option's name as written (its first option string, or a positional's dest)."""
    return action.option_strings[0] if action.option_strings else action.dest


def _options(parser):
    return {_option(a): a for a in parser._actions if not isinstance(a, argparse._HelpAction)}


@pytest.mark.parametrize("name,parser,roles", COMMAND_LINES, ids=[c[0] for c in COMMAND_LINES])
def test_every_option_is_a_path_in_or_out_or_named_as_no_path(name, parser, roles):
    text = set(JSON_TEXT) if "analysis.numerics" in name else set()
    unknown = set(_options(parser)) - roles.options - set(NOT_PATHS) - text
    assert unknown == set(), f"{name}: say in its PathRoles whether these are read or written"
    assert roles.options <= set(_options(parser)), name


def test_the_pile_numerics_refuse_their_output_over_an_input(tmp_path):
    """The command lines of analysis.numerics call the check too (one line, status 2)."""
    line = _refused(tmp_path, "-m", "analysis.numerics.pile_precision", "figure", "--data", "d.nc",
                    "--out", "d.nc", says=("--out d.nc", "--data d.nc"))
    assert line.endswith("give it a path of its own")
    _refused(tmp_path, "-m", "analysis.numerics.piles_report", "--piles", "p.nc", "--ensemble", "e.nc",
             "--out", "e.nc", says=("error: --out e.nc and --ensemble e.nc",))


def _value(roles, option, path):
    """`path` as `option` takes it (``@path`` for settings, ``x=path`` for labelled inputs)."""
    read = roles.read.get(option)
    return f"@{path}" if read is at_file else f"x={path}" if read is labelled else path


def _argv(parser, roles, given):
    """A command line of `parser` with the options of `given` (option -> path) and every other
    required one, each path of its own."""
    options = _options(parser)
    chosen = dict(given)
    for group in parser._mutually_exclusive_groups:
        if group.required and not any(_option(a) in chosen for a in group._group_actions):
            chosen[_option(group._group_actions[0])] = None
    for option, action in options.items():
        if (action.required or not action.option_strings) and option not in chosen:
            chosen[option] = None
    argv, positional = [], []
    for option, path in chosen.items():
        action = options[option]
        value = (_value(roles, option, path) if path is not None else
                 _value(roles, option, f"{action.dest}.own") if option in roles.options else
                 {**NOT_PATHS, **JSON_TEXT}[option])
        if not action.option_strings:
            positional.append(value)
        elif action.nargs == 0:
            argv.append(option)
        else:
            argv += [option, value]
    return positional + argv   # before any option of several values


def _pairs():
    """(command line, output, other option) for every output and every path option besides it,
    and the output with itself where it takes several paths."""
    for name, parser, roles in COMMAND_LINES:
        options = _options(parser)
        for out in roles.outputs:
            for other in sorted(roles.options - {out}):
                yield name, parser, roles, out, other
            if options[out].nargs in ("+", "*") or isinstance(options[out], argparse._AppendAction):
                yield name, parser, roles, out, out


@pytest.mark.parametrize("name,parser,roles,out,other", list(_pairs()),
                         ids=[f"{p[0]}:{p[3]}={p[4]}" for p in _pairs()])
def test_every_output_equal_to_any_other_path_is_refused(tmp_path, monkeypatch, name, parser, roles,
                                                         out, other):
    monkeypatch.chdir(tmp_path)
    if out == other:
        argv = _argv(parser, roles, {})
        argv += [out, "same.nc", "same.nc"] if "--" in out else []
    else:
        exclusive = [g for g in parser._mutually_exclusive_groups
                     if {out, other} <= {_option(a) for a in g._group_actions}]
        if exclusive:
            pytest.skip(f"{out} and {other} cannot be given together")
        argv = _argv(parser, roles, {out: "same.nc", other: "same.nc"})
    args = parser.parse_args(argv)
    with pytest.raises(PathCollision) as refused:
        check_distinct_paths(args, roles)
    message = str(refused.value)
    assert "\n" not in message
    assert f"{out} " in message and f"{other} " in message and str(tmp_path / "same.nc") in message


@pytest.mark.parametrize("name,parser,roles", COMMAND_LINES, ids=[c[0] for c in COMMAND_LINES])
def test_a_command_line_with_a_path_of_its_own_for_each_file_passes(tmp_path, monkeypatch, name,
                                                                    parser, roles):
    monkeypatch.chdir(tmp_path)
    every = {option: f"{option.strip('-')}.own" for option in roles.options}
    for group in parser._mutually_exclusive_groups:   # one of each group of alternatives
        for action in group._group_actions[1:]:
            every.pop(_option(action), None)
    check_distinct_paths(parser.parse_args(_argv(parser, roles, every)), roles)


# ------------------------------------------------------------ seeds and threads
@pytest.mark.parametrize("seed", [str(2**64), "-1", str(2**32)])
def test_a_seed_beyond_the_generator_s_range_is_refused_before_the_pour(tmp_path, seed):
    """2**64 went through the whole pour and then crashed in data_digest
    (OverflowError), writing nothing."""
    _refused(tmp_path, "-m", "sim", "pour", "--params", TINY, "--protocol", "wedge", "--seed", seed,
             "--out", "a.nc", says=(f"--seed {seed}", "from 0 to 4294967295"))
    assert list(tmp_path.iterdir()) == []


def _seed_lists(schema):
    """Every property ``seeds`` of a JSON schema (nested mappings and lists walked)."""
    if isinstance(schema, dict):
        if "seeds" in schema.get("properties", {}):
            yield schema["properties"]["seeds"]
        for value in schema.values():
            yield from _seed_lists(value)
    elif isinstance(schema, list):
        for value in schema:
            yield from _seed_lists(value)


def test_the_workflow_s_seeds_are_the_simulator_s():
    """The protocols' seeds and the pile numerics' seeds go to pour --seed: the
    schemas refuse what the pour would."""
    import yaml

    from sim.pour import SEED_MAX

    found = []
    for name in ("config.schema.yaml", "numerics.schema.yaml"):
        schema = yaml.safe_load((REPO / "workflow/schemas" / name).read_text())
        found += [(name, s["items"].get("minimum"), s["items"].get("maximum")) for s in _seed_lists(schema)]
    assert {f[0] for f in found} == {"config.schema.yaml", "numerics.schema.yaml"}
    assert all(low == 0 and high == SEED_MAX for _, low, high in found), found


def test_bench_threads_beyond_the_machine_are_refused(tmp_path):
    """--threads 100000 exited 0 having timed nothing."""
    import numba

    most = numba.config.NUMBA_NUM_THREADS
    _refused(tmp_path, "-m", "sim", "bench", "--sizes", "10", "--steps", "1", "--repeats", "1",
             "--integrators", "verlet", "--threads", f"1,{most + 1}", "--cache", "cache",
             says=(f"--threads '1,{most + 1}'", f"at most {most}"))
    assert list(tmp_path.iterdir()) == []
