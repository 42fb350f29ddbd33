"""Which pile and stage a file is (issue 47): every reader checks a file's identity
against what the argument naming it means, and the simulator's stages start only
from the stage they are made for.

The analysis half runs on synthetic states (tests/synthetic_states.py) that carry
the identity attributes of docs/formats.md#state-files as the simulator writes
them; the simulator half on a pile of two squares (tests/scenes.py) taken through
relax and the probes for real.
"""

import json

import numpy as np
import pytest
import xarray as xr
from scenes import rectangle, scene
from synthetic_states import displaced, step_pyramid, to_dataset, write_state

from analysis.__main__ import main as analysis
from sim.cli import main as sim
from sim.config import SimConfig
from sim.digest import data_digest
from sim.io import StateFileError, pour_digest, save_state
from sim.probe import probe_file, restore_file, stretch_file, tilt_file
from sim.relax import relax_file

SMALL = json.dumps({"grid": {"x_min": -0.1, "x_max": 0.1, "y_min": 0.03, "y_max": 0.09, "spacing": 0.03}})
LEVEL = 0.1


def stamped(path, state, **attrs):
    """Write ``state`` with the global attributes ``attrs`` and the ``data_digest`` the simulator writes."""
    ds = to_dataset({**state, "attrs": {**state["attrs"], **attrs}})
    ds.attrs["data_digest"] = data_digest(ds)
    ds.to_netcdf(path)
    return str(path)


def pile(folder, protocol, seed, digest="0123456789abcdef"):
    """A relaxed and a reduced state of one synthetic pile, as the simulator names them:
    ``folder/protocol/seedN/{relaxed,reduced}.nc``."""
    d = folder / protocol / f"seed{seed}"
    d.mkdir(parents=True)
    s = step_pyramid(41, 0.006, slope=0.6)
    r = displaced(s, np.column_stack([1e-6 * s["x"], 2e-5 * s["y"]]), 1 - LEVEL, (1 - LEVEL) * 9.81)
    ident = {"protocol": protocol, "seed": seed, "pour_digest": digest}
    relaxed = stamped(d / "relaxed.nc", s, stage="relaxed", **ident)
    with xr.open_dataset(relaxed) as ds:
        parent = ds.attrs["data_digest"]
    reduced = stamped(d / "reduced.nc", r, stage="reduced", gravity_reduction=LEVEL, relaxed_digest=parent, **ident)
    return relaxed, reduced


@pytest.fixture()
def piles(tmp_path):
    return {"wedge": pile(tmp_path, "wedge", 1), "layered": pile(tmp_path, "layered", 1)}


def refused(capsys, argv, *words):
    """Run ``python -m analysis argv``: exit 1, the last line of its output one error holding ``words``."""
    assert analysis([*argv, "--params", SMALL]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    err = lines[-1]
    assert err.startswith("error: ") and not [line for line in lines[:-1] if not line.startswith("[analysis]")], lines
    for w in words:
        assert w in err, err
    return err


def fields(relaxed, reduced, out, checks=None):
    return ["fields", "--relaxed", relaxed, "--reduced", reduced, "--out", str(out)] + (
        ["--checks", str(checks)] if checks else [])


def test_the_fields_of_one_pile_pass(tmp_path, piles):
    relaxed, reduced = piles["wedge"]
    out = tmp_path / "f.nc"
    assert analysis([*fields(relaxed, reduced, out), "--params", SMALL]) == 0
    with xr.open_dataset(out) as ds, xr.open_dataset(relaxed) as r:
        assert (ds.attrs["protocol"], ds.attrs["seed"], ds.attrs["pour_digest"]) == ("wedge", "1", "0123456789abcdef")
        assert ds.attrs["relaxed_digest"] == r.attrs["data_digest"] and ds.attrs["reduced_stage"] == "reduced"


def test_the_reduced_state_of_another_pile_is_refused(tmp_path, piles, capsys):
    """Issue 47: wedge relaxed with layered reduced gave a median strain of -0.48, exit 0."""
    out = tmp_path / "f.nc"
    refused(capsys, fields(piles["wedge"][0], piles["layered"][1], out), "--reduced", piles["layered"][1],
            "pile layered seed 1", "pile wedge seed 1", "(another protocol)", "a gravity reduction")
    assert not out.exists()


def test_swapped_stages_are_refused(tmp_path, piles, capsys):
    """Issue 47: --relaxed and --reduced swapped gave every sign flipped, exit 0."""
    relaxed, reduced = piles["wedge"]
    refused(capsys, fields(reduced, relaxed, tmp_path / "f.nc"), f"--relaxed {reduced}: its stage is 'reduced'",
            "--relaxed takes a relaxed state")


def test_the_same_file_twice_is_refused(tmp_path, piles, capsys):
    """Issue 47: the same file twice gave "passed": true and zero increments; also a
    file without a stage attribute (written before, or by hand), where only the
    file itself tells."""
    relaxed, _ = piles["wedge"]
    refused(capsys, fields(relaxed, relaxed, tmp_path / "f.nc"), "--reduced", "its stage is 'relaxed'")
    bare = write_state(tmp_path / "bare.nc", step_pyramid(41, 0.006, slope=0.6))
    refused(capsys, fields(bare, bare, tmp_path / "f.nc"), f"--reduced {bare}: the same state as --relaxed")
    copy = tmp_path / "copy.nc"
    copy.write_bytes(open(relaxed, "rb").read())
    refused(capsys, fields(relaxed, str(copy), tmp_path / "f.nc"), "its stage is 'relaxed'")


def test_a_balance_check_not_made_is_a_failure(tmp_path, capsys):
    """Issue 47: "support reaction rel. error nan" passed with exit 0.  Two files
    without identity of the same gravity: the increment carries no load and cannot
    be checked, which fails the checks in one line."""
    s = step_pyramid(41, 0.006, slope=0.6)
    a, b = write_state(tmp_path / "a.nc", s), write_state(tmp_path / "b.nc", s)
    checks = tmp_path / "c.json"
    refused(capsys, fields(a, b, tmp_path / "f.nc", checks), "balance-law check(s) failed", "not checked",
            "the increment carries no load")
    report = json.loads(checks.read_text())
    assert report["passed"] is False and report["increment"]["passed"] is False


def test_a_probe_of_another_relaxed_state_is_refused(tmp_path, piles, capsys):
    """Same protocol and seed, but the reduced state descends from another relaxed
    state (relaxed_digest), or from another pour's settings (pour_digest)."""
    relaxed, reduced = piles["wedge"]
    s = step_pyramid(41, 0.006, slope=0.6)
    moved = stamped(tmp_path / "moved.nc", displaced(s, np.full((s["x"].size, 2), 1e-9)), stage="relaxed",
                    protocol="wedge", seed=1, pour_digest="0123456789abcdef")
    refused(capsys, fields(moved, reduced, tmp_path / "f.nc"), "descends from the relaxed state with data_digest",
            f"not from --relaxed {moved}")
    resettled = pile(tmp_path / "resettled", "wedge", 1, digest="fedcba9876543210")[1]
    refused(capsys, fields(relaxed, resettled, tmp_path / "f.nc"), "(another pour_digest)",
            "pour digest fedcba9876543210")


def test_probes_are_checked_against_their_labels(tmp_path, piles, capsys):
    relaxed, reduced = piles["wedge"]
    argv = ["probes", "--relaxed", relaxed, "--probes", f"tiltp05={reduced}", "--out", str(tmp_path / "p.nc")]
    refused(capsys, argv, f"--probes tiltp05={reduced}: its stage is 'reduced'", "the probe of stage 'tiltp05'")
    argv[4] = f"reduced={piles['layered'][1]}"
    refused(capsys, argv, "pile layered seed 1")
    argv[4] = f"reduced={reduced}"
    assert analysis([*argv, "--params", SMALL]) == 0


def test_an_ensemble_counts_each_pile_of_one_protocol_once(tmp_path, piles, capsys):
    """Issue 47: `ensemble --fields seed1.nc seed1.nc` made an ensemble of 2 piles with
    zero standard errors, and wedge + layered was titled "protocol wedge"."""
    made = {}
    for protocol, seed in (("wedge", 1), ("layered", 1), ("wedge", 2)):
        relaxed, reduced = piles[protocol] if seed == 1 else pile(tmp_path, protocol, seed)
        made[protocol, seed] = str(tmp_path / f"{protocol}{seed}.fields.nc")
        assert analysis([*fields(relaxed, reduced, made[protocol, seed]), "--params", SMALL]) == 0
    out = tmp_path / "ens.nc"
    ens = ["ensemble", "--out", str(out), "--fields"]
    refused(capsys, ens + [made["wedge", 1], made["wedge", 1]], "the same pile as", "pile wedge seed 1",
            "counts each pile once")
    refused(capsys, ens + [made["wedge", 1], made["layered", 1]], "pile layered seed 1", "one protocol")
    assert not out.exists()
    assert analysis([*ens, made["wedge", 1], made["wedge", 2], "--params", SMALL]) == 0
    with xr.open_dataset(out) as ds:
        assert ds.attrs["n_seeds"] == 2 and ds.attrs["protocol"] == "wedge"


def test_committed_records_still_make_their_ensemble(tmp_path):
    """Fields files written before the identity attributes (docs/reproduction/)
    are of distinct piles by protocol and seed."""
    from pathlib import Path

    records = sorted(str(p) for p in (Path(__file__).parents[1] / "docs/reproduction/layered").glob("seed*.fields.nc"))
    assert len(records) >= 2
    assert analysis(["ensemble", "--fields", *records[:2], "--out", str(tmp_path / "e.nc")]) == 0


def test_base_pressure_names_the_stage_of_its_input(tmp_path, piles, capsys):
    """Issue 47: `base-pressure --states reduced.nc` wrote stage: relaxed."""
    for k, stage in enumerate(("reduced", "relaxed")):
        out = tmp_path / f"bp{k}.nc"
        assert analysis(["base-pressure", "--states", piles["wedge"][1 - k], "--out", str(out)]) == 0
        with xr.open_dataset(out) as ds:
            assert ds.attrs["stage"] == stage
    argv = ["base-pressure", "--out", str(tmp_path / "bp.nc"), "--states"]
    refused(capsys, argv + [piles["wedge"][0], piles["wedge"][0]], "the same pile as")
    refused(capsys, argv + [piles["wedge"][0], piles["layered"][0]], "one protocol")
    other = pile(tmp_path, "wedge", 2)[1]
    refused(capsys, argv + [piles["wedge"][0], other], f"--states {other}: its stage is 'reduced', but",
            "of stage 'relaxed'", "of one stage")
    checkpoint = stamped(tmp_path / "pour.checkpoint.nc", step_pyramid(41, 0.006), stage="checkpoint",
                         protocol="wedge", seed=3)
    refused(capsys, argv + [checkpoint], "its stage is 'checkpoint'; --states takes the state of a finished stage")


# ---------------------------------------------------------------- the simulator's stages

SETTINGS = {"model": {"integrator": "verlet"}, "relax": {"max_time": 0.5}}


def two_squares(path, **attrs):
    """A state of two squares stacked on the support, written as the simulator writes ``attrs["stage"]``."""
    sim = scene([rectangle(4e-3, 4e-3), rectangle(4e-3, 4e-3)],
                [(0.0, 0.002, 0, 0, 0, 0), (0.0, 0.006, 0, 0, 0, 0)], gravity=(0.0, -9.81), support=True)
    save_state(sim, path, SimConfig.from_dict(SETTINGS).to_dict(), **{"protocol": "wedge", "seed": 1, **attrs})
    return path


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """poured -> relaxed -> reduced -> restored of the two squares, run for real."""
    d = tmp_path_factory.mktemp("chain")
    cfg = SimConfig.from_dict(SETTINGS)
    two_squares(d / "poured.nc", stage="poured")
    relax_file(cfg, d / "poured.nc", d / "relaxed.nc")
    probe_file(cfg, d / "relaxed.nc", LEVEL, d / "reduced.nc")
    restore_file(cfg, d / "reduced.nc", d / "restored.nc")
    return d


def test_every_stage_carries_the_identity_of_its_pour(chain):
    attrs = {}
    for stage in ("poured", "relaxed", "reduced", "restored"):
        with xr.open_dataset(chain / f"{stage}.nc") as ds:
            attrs[stage] = dict(ds.attrs)
    digest = pour_digest(SimConfig.from_dict(SETTINGS).to_dict())
    for stage, a in attrs.items():
        assert (a["stage"], a["protocol"], a["seed"], a["pour_digest"]) == (stage, "wedge", 1, digest)
    assert "relaxed_digest" not in attrs["poured"] and "relaxed_digest" not in attrs["relaxed"]
    assert attrs["reduced"]["relaxed_digest"] == attrs["relaxed"]["data_digest"]
    assert attrs["restored"]["relaxed_digest"] == attrs["relaxed"]["data_digest"]
    assert attrs["reduced"]["gravity_reduction"] == LEVEL
    # another pour's settings make another digest; bookkeeping settings do not
    assert pour_digest(SimConfig.from_dict({**SETTINGS, "pour": {"rate": 7.0}}).to_dict()) != digest
    assert pour_digest(SimConfig.from_dict({**SETTINGS, "relax": {"max_time": 0.7}}).to_dict()) == digest


@pytest.mark.parametrize("stage, extra", [("checkpoint", {"next_release": 1.0}), ("lastgood", {"error": "blow-up"}),
                                          ("relaxed", {}), ("reduced", {"gravity_reduction": LEVEL}),
                                          ("bench", {})])
def test_relax_takes_only_a_poured_state(tmp_path, caplog, stage, extra):
    """Issue 47: a killed pour's checkpoint became a relaxed pile of 139 of 150
    particles, a blow-up's lastgood a relaxed pile of 2, a reduced.nc a relaxed one at g = 8.829."""
    state = two_squares(tmp_path / f"{stage}.nc", stage=stage, **extra)
    out = tmp_path / "out.nc"
    with pytest.raises(StateFileError, match=f"{stage}.nc: its stage is '{stage}'.*; python -m sim relax takes a "
                                             "poured state"):
        relax_file(SimConfig.from_dict(SETTINGS), state, out)
    caplog.clear()
    assert sim(["relax", "--params", json.dumps(SETTINGS), "--input", str(state), "--out", str(out)]) == 2
    assert not out.exists()
    lines = [r.getMessage() for r in caplog.records if r.levelname == "ERROR"]
    assert len(lines) == 1 and "\n" not in lines[0] and f"its stage is '{stage}'" in lines[0]


@pytest.mark.parametrize("probe, stage", [("--level", "reduced"), ("--level", "lastgood"), ("--tilt", "restored"),
                                          ("--stretch", "reduced"), ("--restore", "relaxed"),
                                          ("--restore", "checkpoint")])
def test_a_probe_takes_only_its_own_input_stage(tmp_path, probe, stage):
    state = two_squares(tmp_path / f"{stage}.nc", stage=stage)
    cfg, out = SimConfig.from_dict(SETTINGS), tmp_path / "probe.nc"
    run = {"--level": lambda: probe_file(cfg, state, LEVEL, out), "--tilt": lambda: tilt_file(cfg, state, 0.05, out,
                                                                                             "tiltp05"),
           "--stretch": lambda: stretch_file(cfg, state, 1e-4, out), "--restore": lambda: restore_file(cfg, state, out)}
    takes = "a gravity reduction" if probe == "--restore" else "a relaxed state"
    with pytest.raises(StateFileError, match=f"its stage is '{stage}'.*; python -m sim probe {probe} takes {takes}"):
        run[probe]()
    assert not out.exists()


def test_the_analysis_of_the_real_chain(chain, tmp_path, capsys):
    """The states the simulator wrote pass the checks of their own pile and are
    refused under the wrong argument."""
    relaxed, reduced, restored = (str(chain / f"{s}.nc") for s in ("relaxed", "reduced", "restored"))
    out = tmp_path / "p.nc"
    params = json.dumps({"grid": {"x_min": -0.01, "x_max": 0.01, "y_min": 0.004, "y_max": 0.004, "spacing": 0.01},
                         "rve": {"min_particles": 1, "min_solid_fraction": 0.0}})
    assert analysis(["probes", "--relaxed", relaxed, "--probes", f"reduced={reduced}", f"restored={restored}",
                     "--out", str(out), "--params", params]) == 0
    assert analysis(["fields", "--relaxed", relaxed, "--reduced", restored, "--out", str(out),
                     "--params", params]) == 1
    assert "--reduced takes a gravity reduction" in capsys.readouterr().err


def test_every_reader_of_several_piles_counts_each_once(tmp_path, piles, capsys):
    """moduli --fields, general-fit --probes and base-pressure --piles: the same pile
    twice, or a pile of another protocol than the rest (and the ensemble), refused."""
    made = {}
    for protocol in ("wedge", "layered"):
        relaxed, reduced = piles[protocol]
        made[protocol] = {kind: str(tmp_path / f"{protocol}.{kind}.nc") for kind in ("fields", "probes", "bp")}
        assert analysis([*fields(relaxed, reduced, made[protocol]["fields"]), "--params", SMALL]) == 0
        assert analysis(["probes", "--relaxed", relaxed, "--probes", f"reduced={reduced}", "--out",
                         made[protocol]["probes"], "--params", SMALL]) == 0
        assert analysis(["base-pressure", "--states", reduced, "--out", made[protocol]["bp"],
                         "--params", '{"base_pressure": {"stage": "reduced"}}']) == 0
    ens = str(tmp_path / "ens.nc")
    assert analysis(["ensemble", "--fields", made["wedge"]["fields"], "--out", ens, "--params", SMALL]) == 0
    w, layered = made["wedge"], made["layered"]
    out = ["--out", str(tmp_path / "out.nc")]
    refused(capsys, ["moduli", "--ensemble", ens, "--fields", w["fields"], w["fields"], *out], "the same pile as")
    refused(capsys, ["moduli", "--ensemble", ens, "--fields", layered["fields"], *out], "one protocol")
    refused(capsys, ["general-fit", "--probes", w["probes"], w["probes"], *out], "the same pile as")
    refused(capsys, ["general-fit", "--ensemble", ens, "--probes", layered["probes"], *out], "one protocol")
    refused(capsys, ["base-pressure", "--piles", w["bp"], w["bp"], *out], "the same pile as")
    refused(capsys, ["base-pressure", "--piles", w["bp"], layered["bp"], *out], "one protocol")
