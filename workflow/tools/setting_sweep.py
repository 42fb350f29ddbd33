"""Does one setting change the piles? For the pile shape and the parameters the paper does not give.

Runs the piles of ``--piles`` (``config/medium_piles.yaml``, 800 particles, by
default; ``config/sweep_piles.yaml``, 1600, for the unknown parameters of
issue 25), merged over the study's ``config/config.yaml``, at each value of
one setting, each value in its own
Snakemake working directory ``results/sweeps/{name}/{value}/`` (its piles in
the configuration's results folder there, ``results/study/``), then compares
per protocol, with the seed mean and its standard error:

* the angle of repose: mean of both flank angles of the relaxed pile
  (``python -m sim summary``), and the pile's height and base width from the
  same summary (a steeper flank fit need not mean a higher pile: long feet
  widen the base);
* the solid fraction of the core: mean of the RVE field over ``|x| <= 3 cm``,
  ``y <= 5 cm``;
* the primary construction-history statistics of ``analysis/history.py``
  (the strain and solid fraction of the centre against fixed shoulders, the
  base pressure against a uniform-density pile, the gravity scaling of the
  stresses, the stress-fabric angle), and at each value wedge against
  layered with the standard error of the difference;
* the core moduli: Young's modulus ``E`` and bulk modulus ``K`` of each pile's
  own isotropic fit (average of both fits, m = 5), mean over the core points;
* the CPU seconds of each pile's pour, relaxation and probe.

Two values differ beyond seed scatter in a quantity when their means are more
than twice their combined standard error apart.  Writes the table to
``docs/reproduction/{name}.md`` and the numbers to ``{name}.json`` there; the
JSON keeps, per value, the commit it was run at (``runs``), and a ``note``
written there by hand goes into the table's heading.  With
``--keep-recorded`` the values not run now are taken from that JSON (a value
run now replaces its record), so a value can be added without pouring the
others again, and without ``--values`` only the table is written again.
Every value is checked by the workflow's own validation before anything
runs.  With ``--from DIR`` the piles are read from ``DIR/{name}/{value}/``
(a clone that ran them at a fixed commit) instead of being poured here, and
``--same VALUE=NAME/OTHER`` takes a value's piles from another run of the
same configuration (e.g. the study's value, poured once for all sweeps);
each value records the commit of the checkout its piles came from.

Usage::

    .venv/bin/python -m workflow.tools setting_sweep --setting pour.rate \\
        --values 100 200 400 --name pour_rate [--cores 2] [--keep-recorded] \\
        [--piles config/sweep_piles.yaml]
    .venv/bin/python -m workflow.tools setting_sweep --piles config/sweep_piles.yaml \\
        --setting pour.release_height --values 0.3 --same 0.02=friction/0.5 \\
        --name release_height --from /work/sweep/results/sweeps
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from analysis.ensemble_statistics import compare, mean_sem
from analysis.params import parse_params
from analysis.pile_quantities import MODULI, SHAPE, pile_quantities
from analysis.pile_quantities import quantities as pile_quantity_names
from sim.settings_file import SettingsDumper, read_settings_file, yaml_value
from workflow.layout import folders
from workflow.validation import ConfigurationError, validate_config
from workflow.validation import merge_configs as merged

from ._cli import ToolParser, existing_file, existing_folder, plain_name, positive_int, read_json, refuse, shown

REPO = Path(__file__).resolve().parents[2]

MEDIUM = REPO / "config" / "medium_piles.yaml"
COST = {"cpu_s": "CPU s per pile (pour, relax, probe)"}


def quantities(params: dict) -> dict:
    """The compared quantities, ``{key: heading}``: those of
    :func:`analysis.pile_quantities.quantities` and the CPU time."""
    return {**pile_quantity_names(params), **COST}


def label(value) -> str:
    """The value as a table heading and a JSON key: ``100.0`` → ``100``."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def overlay(setting: str, value) -> dict:
    """``{"pour": {"rate": 400.0}}`` for ``pour.rate`` and 400.0."""
    out: dict = {}
    node = out
    *sections, key = setting.split(".")
    for s in sections:
        node = node.setdefault(s, {})
    node[key] = value
    return out


def run_value(name: str, setting: str, value, cores: int, piles: Path) -> Path:
    """Pour, relax, probe and analyse the piles of ``piles`` at one value; their working directory."""
    work = REPO / "results" / "sweeps" / name / label(value)
    work.mkdir(parents=True, exist_ok=True)
    (work / "setting.yaml").write_text(yaml.dump(overlay(setting, value), Dumper=SettingsDumper))
    cfg = read_settings_file(piles)
    tree = results_setting(piles, overlay(setting, value))
    summaries = [f"{tree}/fields/{p}/seed{s}.summary.json" for p, v in cfg["protocols"].items()
                 for s in v["seeds"]]
    cmd = [sys.executable, "-m", "snakemake", "all", *summaries, "-s", str(REPO / "Snakefile"),
           "--directory", str(work), "--cores", str(cores),
           "--profile", str(REPO / "workflow" / "profiles" / "default"),
           "--configfile", str(REPO / "config" / "config.yaml"), str(piles), str(work / "setting.yaml")]
    print(f"{setting} = {label(value)}: {' '.join(cmd)}", flush=True)
    subprocess.run(cmd, check=True)
    return work


def check_values(setting: str, values: list, piles: Path = MEDIUM) -> None:
    """Refuse a setting or value that the workflow would refuse, before any pile is poured."""
    study = merged(read_settings_file(REPO / "config" / "config.yaml"), read_settings_file(piles))
    for value in values:
        try:
            validate_config(merged(study, overlay(setting, value)))
        except ConfigurationError as exc:  # it names the setting, the value and what is allowed
            refuse(f"--setting {setting} --values ... {label(value)}: {' '.join(str(exc).split())}")


def results_setting(piles: Path, layer: dict) -> str:
    """The ``results`` folder of the sweep's configuration (the study's, ``results/study``)."""
    return _configuration(piles, layer).get("results", "results/study")


def cpu_seconds(work: Path, protocol: str, seed: int, results: str = "results/study") -> float:
    """CPU seconds of the pile's simulation jobs (pour, relax, probes) from Snakemake's benchmark
    files, in the working directory `work` whose configuration writes to `results`."""
    benchmarks = folders(work, results)[1]
    files = [benchmarks / rule / protocol / f"seed{seed}.tsv" for rule in ("pour", "relax")]
    files += sorted((benchmarks / "probe" / protocol).glob(f"seed{seed}_*.tsv"))
    total = 0.0
    for f in files:
        if not f.exists():
            return float("nan")
        header, row = f.read_text().splitlines()[:2]
        total += float(dict(zip(header.split("\t"), row.split("\t")))["cpu_time"])
    return total


def pile_values(work: Path, protocol: str, seed: int, params: dict, results: str = "results/study") -> dict:
    """The compared quantities of one pile (:func:`analysis.pile_quantities.pile_quantities`) and its CPU time,
    in the working directory `work` whose configuration writes to `results`
    (or in the layout before the results folders, :func:`workflow.layout.folders`)."""
    stem = folders(work, results)[0] / "fields" / protocol / f"seed{seed}"
    out = pile_quantities(Path(f"{stem}.summary.json"), Path(f"{stem}.nc"), Path(f"{stem}.base_pressure.nc"), params)
    out["cpu_s"] = cpu_seconds(work, protocol, seed, results)
    return out


def table(results: dict, keys: list, quantities: dict) -> str:
    """Markdown: per protocol and quantity, mean ± SE at each value, and the largest
    difference between two values in combined standard errors (rows no pile has are left out)."""
    rows = ["| protocol | quantity | " + " | ".join(keys) + " | max |Δ|/SE |",
            "|---|---|" + "---|" * (len(keys) + 1)]
    for protocol, by_value in results["piles"].items():
        for q, text in quantities.items():
            stats = [mean_sem([p.get(q, np.nan) for p in by_value[k]]) for k in keys]
            if not any(n for *_, n in stats):
                continue
            z = max((abs(a[0] - b[0]) / np.hypot(a[1], b[1])
                     for i, a in enumerate(stats) for b in stats[i + 1:]), default=float("nan"))
            cells = " | ".join(f"{m:.4g} ± {s:.2g}" for m, s, *_ in stats)
            rows.append(f"| {protocol} | {text} | {cells} | {z:.1f} |")
    return "\n".join(rows) + "\n"


def history_table(results: dict, keys: list, quantities: dict, a: str = "wedge", b: str = "layered") -> str:
    """Markdown: at each value, ``a − b`` in each history statistic, ± its standard error (z)."""
    if not {a, b} <= set(results["piles"]):
        return ""
    names = [q for q in quantities if q not in SHAPE and q not in MODULI and q not in COST]
    rows = [f"| {a} − {b} | " + " | ".join(keys) + " |", "|---|" + "---|" * len(keys)]
    for q in names:
        cells = []
        for k in keys:
            c = compare(*([p.get(q, np.nan) for p in results["piles"][x][k]] for x in (a, b)))
            cells.append(f"{c['diff']:+.3g} ± {c['se']:.2g} ({c['z']:+.1f})" if c["se"] > 0 else "n/a")
        if any(c != "n/a" and "nan" not in c for c in cells):
            rows.append(f"| {quantities[q]} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n" if len(rows) > 2 else ""


def _order(key: str) -> tuple:
    """Numbers in increasing order, then the rest as given (``sorted`` is stable)."""
    value = yaml_value(key)
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    return (0, value) if number else (1, 0)


def same_run(spec: str, root: Path) -> tuple:
    """``VALUE=NAME/OTHER`` → (value, ``root/NAME/OTHER``), or ``VALUE=/absolute/dir`` →
    (value, that folder): the value's piles are those of another run, refused in
    :func:`main` unless both give the same configuration."""
    value_text, _, run = spec.partition("=")
    name, _, other = run.partition("/")
    if not (value_text and run and (Path(run).is_absolute() or (name and other))):
        refuse(f"--same {spec!r}: expected VALUE=NAME/VALUE (under the runs' folder) or "
               "VALUE=/path/to/run, e.g. 0.02=friction/0.5")
    return yaml_value(value_text), Path(run) if Path(run).is_absolute() else root / name / other


def commit_of(folder: Path) -> str:
    """The short commit of the checkout that holds ``folder`` (where its piles were made)."""
    return subprocess.run(["git", "-C", str(folder), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()


def _configuration(piles: Path, layer: dict) -> dict:
    study = merged(read_settings_file(REPO / "config" / "config.yaml"), read_settings_file(piles))
    return merged(study, layer)


def main(argv=None) -> None:
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", required=True, help="dotted name of the setting, e.g. pour.rate")
    ap.add_argument("--values", nargs="*", default=[], type=yaml_value,
                    help="its values, each read as YAML (100, 0.5, 1e7, false); none with --keep-recorded: "
                         "only write the table of the recorded ones again")
    ap.add_argument("--name", required=True, type=plain_name, help="the study's name: results/sweeps/NAME, docs/reproduction/NAME.md")
    ap.add_argument("--cores", type=positive_int, default=2)
    ap.add_argument("--piles", type=existing_file, default=MEDIUM,
                    help="the piles' settings, merged over config/config.yaml (default: config/medium_piles.yaml)")
    ap.add_argument("--keep-recorded", action="store_true",
                    help="take the values not run now from the recorded docs/reproduction/NAME.json")
    ap.add_argument("--from", dest="runs", type=existing_folder, default=None, metavar="DIR",
                    help="read the values' piles from DIR/NAME/VALUE/ (results/sweeps of a clone that ran "
                         "them at a fixed commit, which is recorded) instead of pouring them here")
    ap.add_argument("--same", nargs="*", default=[], metavar="VALUE=NAME/VALUE",
                    help="a value whose piles are another run of the same configuration: NAME/VALUE under "
                         "the runs' folder, or an absolute folder (e.g. the study's value, poured once for "
                         "every sweep); its commit is that folder's")
    args = ap.parse_args(argv)
    if not args.values and not args.same and not args.keep_recorded:
        ap.error("--values: give at least one value (or --keep-recorded to rewrite the table)")
    piles = args.piles.resolve()
    check_values(args.setting, args.values, piles)
    cfg = read_settings_file(piles)
    params = parse_params(json.dumps(cfg["analysis"]))
    out = REPO / "docs" / "reproduction"
    record = out / f"{args.name}.json"
    results = {"setting": args.setting, "piles": {p: {} for p in cfg["protocols"]}, "runs": {}}
    if args.keep_recorded:
        results = read_json(record, "--keep-recorded: the sweep's record")
        if not isinstance(results, dict) or not isinstance(results.get("piles"), dict):
            refuse(f"--keep-recorded: {record} holds no sweep (a mapping with piles); allowed is a sweep's record")
        if results.get("setting", args.setting) != args.setting:
            refuse(f"--keep-recorded: {record} is a sweep of {results['setting']}, not {args.setting}")
        results["setting"] = args.setting
    root = args.runs or REPO / "results" / "sweeps"
    values = list(args.values)
    works = {label(v): root / args.name / label(v) for v in values} if args.runs else {}
    for spec in args.same:
        value, run = same_run(spec, root)
        if _configuration(piles, overlay(args.setting, value)) != \
                _configuration(piles, read_settings_file(run / "setting.yaml")):
            refuse(f"--same {spec}: {run} was run with another configuration than "
                   f"{args.setting} = {label(value)}")
        check_values(args.setting, [value], piles)
        works[label(value)] = run
        values.append(value)
    for value in values:
        work = works.get(label(value)) or run_value(args.name, args.setting, value, args.cores, piles)
        for p, v in cfg["protocols"].items():
            tree = results_setting(piles, overlay(args.setting, value))
            results["piles"][p][label(value)] = [pile_values(work, p, s, params, tree) for s in v["seeds"]]
        results["runs"][label(value)] = commit_of(work)
    record.write_text(json.dumps(results, indent=1) + "\n")
    keys = sorted(results["runs"], key=_order)
    n = {p: len(v["seeds"]) for p, v in cfg["protocols"].items()}
    runs = ", ".join(f"{k} at `{results['runs'][k]}`" for k in keys)
    text = (f"# {args.setting}: piles of {cfg['pour']['n_particles']} particles, seeds per protocol {n}\n\n"
            f"Made by `python -m workflow.tools setting_sweep --setting {args.setting} --name {args.name}` "
            f"(--piles {shown(piles)}); mean ± standard error over seeds; the last column is the largest "
            "difference between two values over their combined standard error (> 2: differs beyond seed "
            f"scatter). Run: {runs}." + (f" Note: {results['note']}." if results.get("note") else "")
            + "\n\n" + table(results, keys, quantities(params)))
    versus = history_table(results, keys, quantities(params))
    if versus:
        text += ("\nWedge against layered at each value, in the history statistics (docs/reproduction/numbers.md "
                 "defines them): the difference of the means ± its standard error (in standard errors).\n\n" + versus)
    (out / f"{args.name}.md").write_text(text)
    print(text)
