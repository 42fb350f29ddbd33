"""docs/formats.md names everything the workflow writes.

For each kind of file this opens a real one, made by the project's own
writers: the per-pile records committed under docs/reproduction/, a tiny
state from ``sim.io.save_state``, and the ensembles, exports and numerical
checks that the analysis and ``sim.numerics`` commands write from those (or
from tiny hand-made states; the numerical checks with their simulations
replaced by constants). It fails, naming the kind and the name, when one of
its dimensions, coordinates, variables, global attributes, variable
attributes, JSON keys or TSV columns is not mentioned in the section of
docs/formats.md that describes that kind of file. A name counts as mentioned
when it appears in backticks in that section (or in the sections it builds
on, and always in "Conventions"), or matches a pattern such as
```<name>_sem``` written there whose ``<name>`` is mentioned.

It also checks that no file of the repository points to the old, missing
format document any more. About 5 s.
"""

from __future__ import annotations

import ast
import csv
import inspect
import json
import re
import subprocess
import types
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from sim.io import save_state

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "formats.md"
RECORD = REPO / "docs" / "reproduction"
# Layered seeds 6-10 carry every per-pile file, the probes included.
PROBE_SEEDS = (6, 7, 8, 9, 10)


# ---------------------------------------------------------------- the page

def _sections(text: str) -> dict[str, str]:
    """Heading title -> its text, subsections included (down to the next heading of the same or a higher level)."""
    lines = text.splitlines()
    heads = [(k, len(m.group(1)), m.group(2).strip()) for k, line in enumerate(lines)
             if (m := re.match(r"^(#{1,6})\s+(.*)$", line))]
    out = {}
    for n, (start, level, title) in enumerate(heads):
        end = next((k for k, lv, _ in heads[n + 1:] if lv <= level), len(lines))
        assert title not in out, f"docs/formats.md: two sections are called {title!r}"
        out[title] = "\n".join(lines[start + 1:end])
    return out


class Section:
    """The names a section of docs/formats.md mentions, and its ``<name>`` patterns."""

    def __init__(self, titles: tuple[str, ...]):
        sections = _sections(DOC.read_text(encoding="utf-8"))
        missing = [t for t in titles if t not in sections]
        assert not missing, f"docs/formats.md has no section {missing}"
        self.title = titles[0]
        self.names: set[str] = set()
        for t in (*titles, "Conventions"):
            for span in re.findall(r"`([^`]+)`", sections[t]):
                self.names.add(span.strip())
                self.names.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", span))
        self.patterns = [m.groups() for span in re.findall(r"`([^`]+)`", sections[titles[0]])
                         if (m := re.fullmatch(r"(\w*)<name>(\w*)", span.strip())) and any(m.groups())]

    def mentions(self, name: str) -> bool:
        if name in self.names:
            return True
        if (m := re.fullmatch(r"(\w+)@[0-9.]+", name)):  # a statistic per height: strain@4.5
            return f"{m.group(1)}@<h>" in self.names
        for prefix, suffix in self.patterns:
            if (len(name) > len(prefix) + len(suffix) and name.startswith(prefix) and name.endswith(suffix)
                    and self.mentions(name[len(prefix):len(name) - len(suffix)])):
                return True
        return False

    def check(self, kind: str, names: dict[str, set[str]]) -> None:
        """Fail naming every name of ``names`` (what -> names) the section does not mention."""
        missing = [f"{what} {name!r}" for what, group in names.items() for name in sorted(group)
                   if not self.mentions(str(name))]
        assert not missing, (f"{kind}: docs/formats.md, section {self.title!r}, does not mention "
                             + ", ".join(missing))


def _netcdf_names(paths) -> dict[str, set[str]]:
    """Dimensions, coordinates, variables, global and variable attributes of netCDF files (their union)."""
    out = {k: set() for k in ("dimension", "coordinate", "variable", "global attribute", "variable attribute")}
    for path in paths:
        with xr.open_dataset(path, decode_times=False) as ds:
            out["dimension"].update(map(str, ds.sizes))
            out["coordinate"].update(map(str, ds.coords))
            out["variable"].update(map(str, ds.data_vars))
            out["global attribute"].update(ds.attrs)
            for v in ds.variables.values():
                out["variable attribute"].update(v.attrs)
    return out


def _records(kind: str) -> list[Path]:
    paths = sorted(RECORD.glob(f"*/seed*.{kind}"))
    assert paths, f"no committed docs/reproduction/*/seed*.{kind}"
    return paths


def _keys(obj) -> set[str]:
    """Every key of nested JSON objects (not of the lists in them)."""
    if not isinstance(obj, dict):
        return set()
    return {k for k in obj} | {n for k, v in obj.items() for n in _keys(v)}


# ---------------------------------------------------------------- files made here

@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The files this test makes with the project's own writers, by kind: a path or list of paths."""
    tmp = tmp_path_factory.mktemp("formats")
    from scenes import rectangle, scene

    from analysis.base_pressure import combine_base_pressure
    from analysis.elastic import moduli_dataset
    from analysis.ensemble import ensemble_fields
    from analysis.invariants import invariants_dataset
    from analysis.netcdf import read_dataset, write_dataset
    from analysis.params import parse_params
    from analysis.probes import general_fit_dataset
    from sim.frames import FrameRecorder
    from sim.io import save_state

    files: dict = {}
    # A tiny pile of two squares on the support, as the simulator writes it.
    polygons = [rectangle(4e-3, 4e-3), rectangle(4e-3, 3e-3)]
    sim = scene(polygons, [(0.0, 0.002, 0, 0, 0, 0), (0.001, 0.0056, 0.1, 0.01, 0, 0.5)],
                gravity=(0.0, -9.81), support=True)
    files["state"] = tmp / "relaxed.nc"
    save_state(sim, files["state"], {"model": {}}, stage="relaxed", protocol="wedge", seed=1)
    recorder = FrameRecorder(sim.shapes, 2, 0.5)
    recorder(sim)
    files["frames"] = tmp / "frames.nc"
    recorder.save(files["frames"], {"model": {}}, protocol="wedge", seed=1)

    # The ensembles of the layered piles that have every per-pile file.
    params = parse_params("{}")
    fields = [read_dataset(str(RECORD / f"layered/seed{s}.fields.nc")) for s in PROBE_SEEDS]
    names = [f"layered/seed{s}.fields.nc" for s in PROBE_SEEDS]
    ens = ensemble_fields(fields, names, params["ensemble"]["slip_strain_ratio"])
    bp = combine_base_pressure([read_dataset(str(RECORD / f"layered/seed{s}.base_pressure.nc")) for s in PROBE_SEEDS],
                               names, params)
    probes = [read_dataset(str(RECORD / f"layered/seed{s}.probes.nc")) for s in PROBE_SEEDS]
    made_ens = {"ensemble fields": ens, "ensemble moduli": moduli_dataset(ens, fields, params),
                "ensemble invariants": invariants_dataset(ens, params), "ensemble base pressure": bp,
                "ensemble general fit": general_fit_dataset(probes, params, ens)}
    for kind, ds in made_ens.items():
        files[kind] = tmp / f"{kind.replace(' ', '_')}.nc"
        write_dataset(ds, str(files[kind]), title=kind, params=params)
    files["_tmp"] = tmp
    return files


# ---------------------------------------------------------------- netCDF kinds

def test_state_file(made):
    section = Section(("State files",))
    names = _netcdf_names([made["state"]])
    # Attributes the simulator's stages add (save_state(..., stage=..., next_release=...) and the
    # probes' change_gravity(..., gravity_reduction=...)): every keyword of those calls in sim/.
    added = set()
    for path in (REPO / "sim").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) in (
                    "save_state", "change_gravity"):
                added.update(k.arg for k in node.keywords if k.arg)
    added -= set(inspect.signature(save_state).parameters)     # its own arguments (keep=...), not attributes
    assert {"stage", "next_release", "gravity_reduction"} <= added, added
    names["global attribute"] |= added
    section.check("state file (results/piles/.../{stage}.nc)", names)


def test_frames(made):
    Section(("Frames of a pour",)).check("frames.nc", _netcdf_names([made["frames"]]))


@pytest.mark.parametrize("kind, files, titles", [
    ("per-pile fields (seed{seed}.nc, committed as .fields.nc)", "fields.nc", ("Fields",)),
    ("per-pile base pressure (seed{seed}.base_pressure.nc)", "base_pressure.nc", ("Base pressure",)),
    ("RVE-size convergence (seed{seed}.convergence.nc)", "convergence.nc", ("RVE-size convergence", "Fields")),
    ("probe increments (seed{seed}.probes.nc)", "probes.nc", ("Probe increments",)),
])
def test_committed_per_pile_netcdf(kind, files, titles):
    Section(titles).check(kind, _netcdf_names(_records(files)))


@pytest.mark.parametrize("kind, titles", [
    ("ensemble fields", ("Ensemble fields", "Fields")),
    ("ensemble moduli", ("Elastic moduli",)),
    ("ensemble invariants", ("Invariants",)),
    ("ensemble base pressure", ("Base pressure",)),
    ("ensemble general fit", ("General elastic fit",)),
])
def test_ensembles(made, kind, titles):
    Section(titles).check(f"{kind} (results/ensemble/{{protocol}}/)", _netcdf_names([made[kind]]))


# ---------------------------------------------------------------- JSON and TSV

def test_checks_json():
    keys = set()
    for path in _records("checks.json"):
        keys |= _keys(json.loads(path.read_text()))
    keys -= {"relaxed", "reduced"}  # stage names, keys of "stages"
    Section(("Balance checks",)).check("seed{seed}.checks.json", {"key": keys})


def test_summary_json():
    keys = set()
    for path in [*_records("summary.json")]:
        for line in path.read_text().splitlines():
            keys |= set(json.loads(line))
    Section(("Run summary",)).check("seed{seed}.summary.json", {"key": keys})


def test_benchmark_tsv():
    columns = set()
    for path in _records("pour.tsv"):
        with open(path, newline="") as fh:
            columns |= set(next(csv.reader(fh, delimiter="\t")))
    Section(("Benchmark files",)).check("benchmark file (benchmarks/.../*.tsv, seed{seed}.pour.tsv)",
                                        {"column": columns})


def test_committed_sweep_probe_level_and_growth_records():
    section = Section(("Committed records",))
    for path in sorted(p for p in RECORD.glob("*.json") if p.name != "probe_levels.json"):
        record = json.loads(path.read_text())
        per_pile = {k for by_value in record["piles"].values() for piles in by_value.values()
                    for pile in piles for k in pile}
        section.check(f"setting sweep docs/reproduction/{path.name}", {"key": set(record), "pile key": per_pile})
    levels = json.loads((RECORD / "probe_levels.json").read_text())
    piles = [pile for by_protocol in levels.values() for ps in by_protocol.values() for pile in ps]
    section.check("docs/reproduction/probe_levels.json",
                  {"mode": set(levels), "pile key": {k for pile in piles for k in pile},
                   "stage": {st for pile in piles for st in pile["slips"]}})
    keys = set()
    for line in (RECORD / "growing_piles.jsonl").read_text().splitlines():
        keys |= set(json.loads(line))
    section.check("docs/reproduction/growing_piles.jsonl", {"key": keys})


# ---------------------------------------------------------------- VTK

def test_vtk_export(made):
    import meshio
    from synthetic_states import make_state, square_lattice, square_nodes, write_state

    from analysis.vtk import contacts_path, export_state

    x, y, contacts = square_lattice(3, 2, 0.01)
    contacts["fy"] = np.ones(contacts["i"].size)
    state = write_state(made["_tmp"] / "lattice.nc", make_state(x, y, square_nodes(0.01), contacts))
    out = str(made["_tmp"] / "lattice.vtu")
    export_state(state, out)
    section = Section(("VTK export",))
    section.check("VTK particles (.vtu)", {"cell data": set(meshio.read(out).cell_data)})
    section.check("VTK contacts (_contacts.vtu)", {"cell data": set(meshio.read(contacts_path(out)).cell_data)})


def test_vtk_time_series_of_a_pour(made):
    """The frames file made above as a ParaView series: the arrays of its
    frame files, and the elements and attributes of its collection."""
    import xml.etree.ElementTree as ET

    import meshio

    from analysis.vtk import export_frames

    pvd, files = export_frames(str(made["frames"]), str(made["_tmp"] / "pour.pvd"))
    section = Section(("VTK time series of a pour",))
    section.check("VTK frames (OUT/OUT_kkkk.vtu)", {"cell data": set().union(
        *(meshio.read(f).cell_data for f in files))})
    root = ET.parse(pvd).getroot()
    elements = {e.tag for e in root.iter()}
    attributes = {a for e in root.iter() if e.tag != "VTKFile" for a in e.attrib}
    section.check("VTK collection (OUT.pvd)", {"element": elements - {"VTKFile"}, "attribute": attributes})


# ---------------------------------------------------------------- numerical checks

def test_numerics_collisions_and_stability(made, monkeypatch):
    """The two files of ``python -m sim numerics``, with the simulations replaced by constants
    (what is checked is the layout the commands write, not the numbers)."""
    from sim.numerics import collisions, stability
    from sim.numerics.collision_scenes import OBSERVABLES

    ns = types.SimpleNamespace
    tmp = made["_tmp"]
    monkeypatch.setattr(collisions, "reference", lambda case: ns(**{k: 1.0 for k in OBSERVABLES}))
    monkeypatch.setattr(collisions, "scene", lambda case, integrator: ns(bound=ns(dt_limit=1e-6)))
    monkeypatch.setattr(collisions, "measure", lambda case, integrator, dt: (ns(**{k: 1.0 for k in OBSERVABLES}), 10))
    monkeypatch.setattr(collisions, "wall_time", lambda *args: 0.1)
    monkeypatch.setattr(collisions, "_draw", lambda ds, path: None)
    params = {"numerics": {"collisions": {"steps_per_decade": 1, "smallest_fraction": 0.1, "repeats": 1,
                                          "cases": [{"name": "edge_friction", "contact": "edge",
                                                     "friction": 0.5}]}}}
    out = {k: str(tmp / f"collisions.{k}") for k in ("nc", "png", "md")}
    assert collisions.main(["--params", json.dumps(params), "--nc", out["nc"], "--figure", out["png"],
                            "--table", out["md"]]) == 0
    Section(("Collisions",)).check("results/numerics/collisions.nc", _netcdf_names([out["nc"]]))

    sim = ns(bound=ns(dt_limit=1e-6), dt=5e-7)
    monkeypatch.setattr(stability, "run_case", lambda builder, integrator, steps, tolerance: ns(
        status="stable", message="", dt=1e-6, energy_gain=0.0, max_overlap=0.0))
    monkeypatch.setattr(stability, "linear_spring", lambda ym, integrator: ns(simulation=lambda: sim))
    monkeypatch.setattr(stability, "packing", lambda **kw: ns(simulation=lambda: sim))
    monkeypatch.setattr(stability, "linear_spring_limit", lambda ym, integrator: 1e-6)
    monkeypatch.setattr(stability, "largest_stable_dt", lambda *args, **kw: 1e-6)
    monkeypatch.setattr(stability, "_draw", lambda ds, path: None)
    params = {"numerics": {"stability": {"stiffness": [1e7], "cases": ["dt_above_limit"], "integrators": ["verlet"]}}}
    out = {k: str(tmp / f"stability.{k}") for k in ("nc", "png", "md")}
    assert stability.main(["--params", json.dumps(params), "--nc", out["nc"], "--figure", out["png"],
                           "--table", out["md"]]) == 0
    Section(("Stability",)).check("results/numerics/stability.nc", _netcdf_names([out["nc"]]))


def test_numerics_piles_and_ensemble(made):
    """``python -m analysis.numerics.pile_precision data`` on tiny hand-made states of both integrators, and
    ``python -m analysis.numerics.ensemble_cost data`` on the committed piles."""
    import yaml
    from synthetic_states import make_state, square_lattice, square_nodes, write_state

    from analysis.numerics import ensemble_cost, pile_precision

    tmp = made["_tmp"]
    piles = yaml.safe_load((REPO / "config" / "numerics_piles_ci.yaml").read_text())["numerics"]["piles"]
    bench = str(_records("pour.tsv")[0])
    times = tmp / "job.times"
    times.write_text("0m0.010s 0m0.000s\n0m2.000s 0m0.500s\n")
    summary = tmp / "relaxed.summary.json"
    summary.write_text(json.dumps({"flank_left_deg": 28.0, "flank_right_deg": 30.0, "mean_coordination": 1.0}) + "\n")
    # Relaxed piles as the analysis reads them: a row of squares pressing on the support.
    x, y, contacts = square_lattice(3, 1, 0.004, x0=-0.004)
    contacts["fy"] = np.full(contacts["i"].size, 0.04)
    states = []
    for integrator, factor, seed in pile_precision.runs(piles):
        path = tmp / f"{integrator}_{factor:g}_{seed}.nc"
        attrs = {"integrator": integrator, "seed": seed, "dt": 1e-6 * factor, "step": 1000, "time": 1.0,
                 "protocol": "wedge"}
        states.append(write_state(path, make_state(x, y, square_nodes(0.004), contacts, attrs=attrs)))
    n = len(states)
    out = str(tmp / "piles.nc")
    assert pile_precision.main(["data", "--params", json.dumps(piles), "--states", *states,
                                "--summaries", *[str(summary)] * n, "--pour-benchmarks", *[bench] * n,
                                "--relax-benchmarks", *[bench] * n, "--pour-cpu", *[str(times)] * n,
                                "--relax-cpu", *[str(times)] * n, "--out", out]) == 0
    Section(("Accuracy of piles",)).check("results/numerics/piles.nc", _netcdf_names([out]))

    ensemble = {"core": [0.0, 0.09], "points": 5, "fit": "average", "dip_half_width": 0.02,
                "relative_targets": [0.1, 0.05]}
    fields = [str(RECORD / f"layered/seed{s}.fields.nc") for s in PROBE_SEEDS]
    out = str(tmp / "ensemble.nc")
    assert ensemble_cost.main(["data", "--params", json.dumps(ensemble), "--protocol", "layered",
                               "--seeds", *map(str, PROBE_SEEDS), "--fields", *fields,
                               "--pour-benchmarks", *[bench] * 5, "--relax-benchmarks", *[bench] * 5,
                               "--probe-benchmarks", *[bench] * 5,
                               # as the workflow passes it: YAML flow text (the default value)
                               "--analysis-params", "{moduli: {min_points: 3}}",
                               "--base-pressure", str(made["ensemble base pressure"]), "--out", out]) == 0
    Section(("Cost of the ensemble",)).check("results/numerics/ensemble.nc", _netcdf_names([out]))


# ---------------------------------------------------------------- the old document

def _repository_files() -> list[str]:
    try:
        out = subprocess.run(["git", "-C", str(REPO), "ls-files", "--cached", "--others", "--exclude-standard",
                              "-z"], capture_output=True, check=True).stdout
        return sorted({p for p in out.decode().split("\0") if p and (REPO / p).is_file()})
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", ".snakemake", "results", "logs", "benchmarks", ".numba_cache", ".bench"}
        return sorted(str(p.relative_to(REPO)) for p in REPO.rglob("*")
                      if p.is_file() and not skip & set(p.relative_to(REPO).parts))


def test_no_file_points_to_the_old_format_document():
    word = re.compile(rb"\b" + b"CONT" + b"RACT" + rb"\b")  # spelt apart so that this file does not match
    hits = {}
    for name in _repository_files():
        data = (REPO / name).read_bytes()
        if b"\0" in data[:8192]:
            continue  # binary
        lines = [k + 1 for k, line in enumerate(data.splitlines()) if word.search(line)]
        if lines:
            hits[name] = lines
    assert not hits, ("these files still point to the old format document instead of docs/formats.md "
                      f"(file: lines): {hits}")


def test_readme_links_the_page():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "](docs/formats.md)" in readme
