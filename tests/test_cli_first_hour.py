"""The command lines as a new user meets them (issue 43, item 8): ``--version``,
plain-text ``--help`` everywhere, and relax and probe going on with the
integrator and time step of the pile they read."""

import hashlib
import logging
import re
import subprocess
import sys
from pathlib import Path

import pytest
import xarray as xr

import analysis
import sim
from analysis.__main__ import build_parser
from sim.cli import NUMERICS, _parser, main
from sim.config import SimConfig
from sim.io import save_state

from scenes import rectangle, scene

REPO = Path(__file__).resolve().parents[1]
# reST a docstring may hold and plain text never does: any backquote
# (``code``, `name`, :role:`target`, `link`_) and a role without one.
MARKUP = re.compile(r"`|:(?:func|mod|class|meth|data|attr|ref|doc|math):")


def _run(*args):
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=REPO,
                          check=True)


def test_sim_version_names_the_code_its_state_files_record(tmp_path):
    """One line: the package version and the digest that a state file written
    now records as code_version, so that a user can tell which code made a pile."""
    out = _run("-m", "sim", "--version").stdout
    assert out.count("\n") == 1
    one = scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)])
    save_state(one, tmp_path / "s.nc", {"model": {}}, stage="relaxed")
    with xr.open_dataset(tmp_path / "s.nc") as ds:
        recorded = ds.attrs["code_version"]
    assert re.fullmatch(r"[0-9a-f]{16}", recorded)
    assert out.startswith(f"polypile sim {sim.__version__}, code_version {recorded} ")


def test_analysis_version_names_its_sources():
    """One line: the package version and the SHA-256 of analysis/*.py (name,
    NUL, contents, in name order: the digest the workflow records for the
    analysis' rules), computed here from the files themselves."""
    out = _run("-m", "analysis", "--version").stdout
    package = REPO / "analysis"
    h = hashlib.sha256()
    for path in sorted(package.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    assert out.count("\n") == 1
    assert out.startswith(f"polypile analysis {analysis.__version__}, code digest {h.hexdigest()[:16]} ")


def _subcommands(parser):
    """The subcommand names of an argparse parser."""
    return list(parser._subparsers._group_actions[0].choices)


def _help(call, argv, capsys):
    """What ``--help`` prints for `argv` through the entry point `call`."""
    with pytest.raises(SystemExit) as exit_:
        call([*argv, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "usage:" in out
    return out


def test_every_help_is_plain_text(capsys):
    """python -m sim and python -m analysis, each subcommand and each numerical
    check of sim: --help holds no reST markup."""
    sim_commands = [[c] for c in _subcommands(_parser()) if c != "numerics"]
    sim_commands += [["numerics", what] for what in NUMERICS]
    analysis_commands = [[c] for c in _subcommands(build_parser())]
    assert len(sim_commands) >= 9 and len(analysis_commands) >= 15
    from analysis.__main__ import main as analysis_main
    helps = {("sim", *a): _help(main, a, capsys) for a in [[], *sim_commands]}
    helps.update({("analysis", *a): _help(analysis_main, a, capsys) for a in [[], *analysis_commands]})
    marked = {" ".join(k): [line for line in text.splitlines() if MARKUP.search(line)]
              for k, text in helps.items()}
    assert {k: v for k, v in marked.items() if v} == {}


def test_the_markup_of_a_docstring_becomes_its_words():
    from sim.cli import plain

    assert plain("``--params`` (see :mod:`sim.config`, :func:`~sim.io.read_state`)") == (
        "--params (see sim.config, sim.io.read_state)")


def _verlet_state(path, stage, **model):
    """A square at rest on the support, written by the Verlet integrator at
    its automatic step (what a Verlet pour leaves), with the ``model`` settings given."""
    cfg = SimConfig.from_dict({"model": {"integrator": "verlet", **model}})
    one = scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)], gravity=(0.0, -9.81),
                support=True, integrator="verlet", **model)
    save_state(one, path, cfg.to_dict(), stage=stage, protocol="wedge", seed=1)
    return one.dt


def _model(path):
    with xr.open_dataset(path) as ds:
        return ds.attrs["integrator"], float(ds.attrs["dt"])


def test_relax_and_probe_go_on_with_the_integrator_and_step_of_their_input(tmp_path, caplog):
    """A Verlet pile relaxed and probed with no --params: both run with Verlet
    at the pour's step (the Gear default refused that step before, naming a dt
    the user never set), and one log line says what was taken from the input."""
    dt = _verlet_state(tmp_path / "poured.nc", "poured")
    caplog.set_level(logging.INFO, logger="sim")
    # What the default integrator makes of this step: refused.
    assert SimConfig().model.integrator == "gear"
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(tmp_path / "gear.nc"),
                 "--params", '{"model": {"integrator": "gear"}}']) == 2
    assert "stability limit" in caplog.records[-1].getMessage()
    caplog.clear()
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(tmp_path / "relaxed.nc")]) == 0
    assert _model(tmp_path / "relaxed.nc") == ("verlet", dt)
    taken = [r.getMessage() for r in caplog.records if "taken from the input" in r.getMessage()]
    assert taken == [f"model.integrator = verlet, model.dt = {dt:.4g} s, {PHYSICS} taken from the input "
                     f"{tmp_path / 'poured.nc'} (not set by --params)"]
    caplog.clear()
    assert main(["probe", "--input", str(tmp_path / "relaxed.nc"), "--level", "0.1",
                 "--out", str(tmp_path / "reduced.nc")]) == 0
    assert _model(tmp_path / "reduced.nc") == ("verlet", dt)
    assert sum("taken from the input" in r.getMessage() for r in caplog.records) == 1


#: The physics of the pile as taken from the input (sim.cli.PHYSICS, the defaults poured with).
PHYSICS = ("model.youngs_modulus = 1e+07, model.damping = 0.1, model.friction = 0.5, "
           "model.support_friction = 0.5, model.density = 2500")


def test_params_say_otherwise(tmp_path, caplog):
    """What --params sets of the numerics is not taken from the input: a dt given
    is used with the input's integrator; both given, only the physics is taken."""
    dt = _verlet_state(tmp_path / "poured.nc", "poured")
    caplog.set_level(logging.INFO, logger="sim")
    out = tmp_path / "again.nc"
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(out),
                 "--params", '{"model": {"dt": 5e-6}}']) == 0
    assert _model(out) == ("verlet", 5e-6)
    assert [r.getMessage().split(" taken")[0] for r in caplog.records
            if "taken from the input" in r.getMessage()] == [f"model.integrator = verlet, {PHYSICS}"]
    caplog.clear()
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(out),
                 "--params", f'{{"model": {{"integrator": "verlet", "dt": {dt / 2}}}}}']) == 0
    assert _model(out) == ("verlet", dt / 2)
    assert [r.getMessage().split(" taken")[0] for r in caplog.records
            if "taken from the input" in r.getMessage()] == [PHYSICS]


@pytest.mark.parametrize("setting, value", [("youngs_modulus", 2e7), ("friction", 0.3), ("density", 2000.0)])
def test_another_physics_than_the_pour_s_is_refused(tmp_path, caplog, setting, value):
    """Issue 47: relaxing with another modulus or friction exited 0 and wrote a
    'relaxed' pile of physics no pour made; now one line names the setting, both
    values and what to do, and nothing is written. The pour's own value passes."""
    _verlet_state(tmp_path / "poured.nc", "poured")
    out = tmp_path / "relaxed.nc"
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(out),
                 "--params", f'{{"model": {{"{setting}": {value}}}}}']) == 2
    errors = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert len(errors) == 1 and f"model.{setting} = {value:.4g} in --params" in errors[0], errors
    assert "leave model." in errors[0] and not out.exists()


def test_the_pour_s_physics_is_kept_when_params_leave_it_out(tmp_path):
    """A pile poured stiffer than the default and relaxed with --params '{}' goes on at its own modulus."""
    _verlet_state(tmp_path / "poured.nc", "poured", youngs_modulus=2e7)
    out = tmp_path / "relaxed.nc"
    assert main(["relax", "--input", str(tmp_path / "poured.nc"), "--out", str(out), "--params", "{}"]) == 0
    with xr.open_dataset(out) as ds:
        assert float(ds.attrs["youngs_modulus"]) == 2e7


def test_a_missing_input_is_one_line_before_anything_runs(tmp_path, caplog):
    assert main(["relax", "--input", str(tmp_path / "none.nc"), "--out", str(tmp_path / "r.nc")]) == 2
    errors = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert errors == [f"state file {tmp_path / 'none.nc'} does not exist"]


def test_a_first_run_says_it_compiles_the_kernels(tmp_path, monkeypatch, caplog):
    """Without a compiled copy of the kernels in the cache the first run compiles
    them for about a minute without a progress line: the log says so first,
    and says nothing of it once the cache holds them."""
    import logging

    import numba

    from sim.cli import _announce_compile

    log = logging.getLogger("sim")
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    with caplog.at_level(logging.INFO, logger="sim"):
        _announce_compile(log)
    assert [r.getMessage() for r in caplog.records if "compiling the simulator's kernels" in r.getMessage()]
    (tmp_path / "cache" / "step").mkdir(parents=True)
    (tmp_path / "cache" / "step" / "step.kernel-1.py311.nbi").write_bytes(b"")
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="sim"):
        _announce_compile(log)
    assert not caplog.records


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_numerics_help_lists_the_checks_and_exits_0(flag, capsys):
    """``python -m sim numerics --help`` is a request, not a mistake: it
    prints the usage and one line per check on stdout and exits 0, as every
    other --help does; a missing or unknown check is still a usage error (2)."""
    assert main(["numerics", flag]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: python -m sim numerics")
    for what in NUMERICS:
        assert re.search(rf"^  {re.escape(what)}\s+\S", out, re.M), what
    assert not MARKUP.search(out)
    assert main(["numerics"]) == 2 and main(["numerics", "nothing"]) == 2
