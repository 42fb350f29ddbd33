"""Does one setting change the piles?  (issue 11: the pour rate, the pile shape)

Runs the piles of ``--piles`` (``config/medium_piles.yaml``, 800 particles, by
default; ``config/sweep_piles.yaml``, 1600, for the unknown parameters of
issue 25), merged over the study's ``config/config.yaml``, at each value of
one setting, each value in its own
Snakemake working directory ``results/sweeps/{name}/{value}/``, then compares
per protocol, with the seed mean and its standard error:

* the angle of repose: mean of both flank angles of the relaxed pile
  (``python -m sim summary``), and the pile's height and base width from the
  same summary (a steeper flank fit need not mean a higher pile: long feet
  widen the base);
* the solid fraction of the core: mean of the RVE field over ``|x| <= 3 cm``,
  ``y <= 5 cm``;
* the base-pressure dip: ``1 - p(0) / max p``, with ``p(0)`` the mean normal
  force density of the two bins next to ``x = 0``;
* the core moduli: Young's modulus ``E`` and bulk modulus ``K`` of each pile's
  own isotropic fit (average of both fits, m = 5), mean over the core points.

Two values differ beyond seed scatter in a quantity when their means are more
than twice their combined standard error apart.  Writes the table to
``docs/reproduction/{name}.md`` and the numbers to ``{name}.json`` there; the
JSON keeps, per value, the commit it was run at (``runs``), and a ``note``
written there by hand goes into the table's heading.  With
``--keep-recorded`` the values not run now are taken from that JSON (a value
run now replaces its record), so a value can be added without pouring the
others again, and without ``--values`` only the table is written again.
Every value is checked by the workflow's own validation before anything
runs.

Usage::

    .venv/bin/python workflow/scripts/setting_sweep.py --setting pour.rate \\
        --values 100 200 400 --name pour_rate [--cores 2] [--keep-recorded] \\
        [--piles config/sweep_piles.yaml]
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from analysis.elastic import moduli_dataset  # noqa: E402
from analysis.params import parse_params  # noqa: E402

MEDIUM = REPO / "config" / "medium_piles.yaml"
QUANTITIES = {
    "angle_deg": "angle of repose (deg)",
    "height": "height (m)",
    "width": "base width (m)",
    "solid_fraction": "core solid fraction",
    "dip": "base-pressure dip 1 − p(0)/max p",
    "youngs_modulus": "core E (N/m)",
    "bulk_modulus": "core K (N/m)",
}
CORE_X, CORE_Y = 0.03, 0.05


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
    (work / "setting.yaml").write_text(yaml.safe_dump(overlay(setting, value)))
    cfg = yaml.safe_load(piles.read_text())
    summaries = [f"results/fields/{p}/seed{s}.summary.json" for p, v in cfg["protocols"].items()
                 for s in v["seeds"]]
    cmd = [sys.executable, "-m", "snakemake", "all", *summaries, "-s", str(REPO / "Snakefile"),
           "--directory", str(work), "--cores", str(cores),
           "--profile", str(REPO / "workflow" / "profiles" / "default"),
           "--configfile", str(REPO / "config" / "config.yaml"), str(piles), str(work / "setting.yaml")]
    print(f"{setting} = {label(value)}: {' '.join(cmd)}", flush=True)
    subprocess.run(cmd, check=True)
    return work


def merged(base: dict, layer: dict) -> dict:
    """``base`` updated by ``layer`` key by key, into nested sections (as Snakemake merges configfiles)."""
    out = dict(base)
    for key, value in layer.items():
        out[key] = merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def check_values(setting: str, values: list, piles: Path = MEDIUM) -> None:
    """Refuse a setting or value that the workflow would refuse, before any pile is poured."""
    from workflow.validation import ConfigurationError, validate_config

    study = merged(yaml.safe_load((REPO / "config" / "config.yaml").read_text()), yaml.safe_load(piles.read_text()))
    for value in values:
        try:
            validate_config(merged(study, overlay(setting, value)))
        except ConfigurationError as exc:  # it names the setting, the value and what is allowed
            raise SystemExit(f"setting_sweep.py --setting {setting} --values ... {label(value)}: {exc}") from None


def pile_values(work: Path, protocol: str, seed: int, params: dict) -> dict:
    """The compared quantities of one pile."""
    stem = work / "results" / "fields" / protocol / f"seed{seed}"
    lines = [json.loads(s) for s in Path(f"{stem}.summary.json").read_text().splitlines() if s.strip()]
    rel = next(line for line in lines if line["stage"] == "relaxed")
    out = {"angle_deg": 0.5 * (rel["flank_left_deg"] + rel["flank_right_deg"]),
           "height": rel["height"], "width": rel["width"]}
    with xr.open_dataset(f"{stem}.nc") as f:
        core = (np.abs(f["x"]) <= CORE_X) & (f["y"] <= CORE_Y)
        out["solid_fraction"] = float(f["solid_fraction"].where(core).mean())
        mod = moduli_dataset(f.load(), [], params)
    core = (np.abs(mod["x"]) <= CORE_X) & (mod["y"] <= CORE_Y)
    for k in ("youngs_modulus", "bulk_modulus"):
        out[k] = float(mod[k].sel(fit="average", points=5).where(core).mean())
    with xr.open_dataset(f"{stem}.base_pressure.nc") as bp:
        p = bp["normal_force_density_per_seed"].values[0]
        x = bp["x"].values
        centre = np.argsort(np.abs(x))[:2]
        out["dip"] = float(1.0 - np.mean(p[centre]) / np.max(p))
    return out


def mean_sem(values: list) -> tuple:
    a = np.asarray(values, float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return float("nan"), float("nan"), 0
    sem = float(a.std(ddof=1) / np.sqrt(a.size)) if a.size > 1 else float("nan")
    return float(a.mean()), sem, int(a.size)


def table(results: dict, keys: list) -> str:
    """Markdown: per protocol and quantity, mean ± SE at each value, and the largest
    difference between two values in combined standard errors."""
    rows = ["| protocol | quantity | " + " | ".join(keys) + " | max |Δ|/SE |",
            "|---|---|" + "---|" * (len(keys) + 1)]
    for protocol, by_value in results["piles"].items():
        for q, text in QUANTITIES.items():
            stats = [mean_sem([p[q] for p in by_value[k]]) for k in keys]
            z = max((abs(a[0] - b[0]) / np.hypot(a[1], b[1])
                     for i, a in enumerate(stats) for b in stats[i + 1:]), default=float("nan"))
            cells = " | ".join(f"{m:.4g} ± {s:.2g}" for m, s, _ in stats)
            rows.append(f"| {protocol} | {text} | {cells} | {z:.1f} |")
    return "\n".join(rows) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", required=True, help="dotted name of the setting, e.g. pour.rate")
    ap.add_argument("--values", nargs="*", default=[], type=yaml.safe_load,
                    help="its values, each read as YAML (100, 0.5, false); none with --keep-recorded: "
                         "only write the table of the recorded ones again")
    ap.add_argument("--name", required=True, help="the study's name: results/sweeps/NAME, docs/reproduction/NAME.md")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--piles", type=Path, default=MEDIUM,
                    help="the piles' settings, merged over config/config.yaml (default: config/medium_piles.yaml)")
    ap.add_argument("--keep-recorded", action="store_true",
                    help="take the values not run now from the recorded docs/reproduction/NAME.json")
    args = ap.parse_args()
    if not args.values and not args.keep_recorded:
        ap.error("--values: give at least one value (or --keep-recorded to rewrite the table)")
    piles = args.piles.resolve()
    check_values(args.setting, args.values, piles)
    cfg = yaml.safe_load(piles.read_text())
    params = parse_params(json.dumps(cfg["analysis"]))
    out = REPO / "docs" / "reproduction"
    record = out / f"{args.name}.json"
    results = {"setting": args.setting, "piles": {p: {} for p in cfg["protocols"]}, "runs": {}}
    if args.keep_recorded:
        results = json.loads(record.read_text())
        if results.get("setting", args.setting) != args.setting:
            raise SystemExit(f"--keep-recorded: {record} is a sweep of {results['setting']}, not {args.setting}")
        results["setting"] = args.setting
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=True).stdout.strip()
    for value in args.values:
        work = run_value(args.name, args.setting, value, args.cores, piles)
        for p, v in cfg["protocols"].items():
            results["piles"][p][label(value)] = [pile_values(work, p, s, params) for s in v["seeds"]]
        results["runs"][label(value)] = commit
    record.write_text(json.dumps(results, indent=1) + "\n")
    keys = list(results["runs"])
    n = {p: len(v["seeds"]) for p, v in cfg["protocols"].items()}
    runs = ", ".join(f"{k} at `{results['runs'][k]}`" for k in keys)
    text = (f"# {args.setting}: piles of {cfg['pour']['n_particles']} particles, seeds per protocol {n}\n\n"
            f"Made by `workflow/scripts/setting_sweep.py --setting {args.setting} --name {args.name}` "
            f"(--piles {piles.relative_to(REPO)}); mean ± standard error over seeds; the last column is the largest "
            "difference between two values over their combined standard error (> 2: differs beyond seed "
            f"scatter). Run: {runs}." + (f" Note: {results['note']}." if results.get("note") else "")
            + "\n\n" + table(results, keys))
    (out / f"{args.name}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
