"""Does the pour rate change the piles?  (issue 11, item 2)

Runs the medium piles of ``config/pour_rate.yaml`` (merged over the study's
``config/config.yaml``) at each rate, each rate in its own Snakemake working
directory ``results/pour_rate/rate{R}/``, then compares per protocol, with the
seed mean and its standard error:

* the angle of repose: mean of both flank angles of the relaxed pile
  (``python -m sim summary``);
* the solid fraction of the core: mean of the RVE field over ``|x| <= 3 cm``,
  ``y <= 5 cm``;
* the base-pressure dip: ``1 - p(0) / max p``, with ``p(0)`` the mean normal
  force density of the two bins next to ``x = 0``;
* the core moduli: Young's modulus ``E`` and bulk modulus ``K`` of each pile's
  own isotropic fit (average of both fits, m = 5), mean over the core points.

Two rates differ beyond seed scatter in a quantity when their means are more
than twice their combined standard error apart.  Writes the table to
``docs/reproduction/pour_rate.md`` and the numbers to ``pour_rate.json`` there.

With ``--keep-recorded`` the rates not run now are taken from the
``pour_rate.json`` already there (a rate run now replaces its record), so a
rate can be added without pouring the others again; the JSON keeps, per
rate, the commit it was run at (``runs``), and the table names them.

Usage: ``.venv/bin/python workflow/scripts/pour_rate.py [--rates 100 200 400] [--cores 2] [--keep-recorded]``
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

QUANTITIES = {
    "angle_deg": "angle of repose (deg)",
    "solid_fraction": "core solid fraction",
    "dip": "base-pressure dip 1 − p(0)/max p",
    "youngs_modulus": "core E (N/m)",
    "bulk_modulus": "core K (N/m)",
}
CORE_X, CORE_Y = 0.03, 0.05


def run_rate(rate: float, cores: int) -> Path:
    """Pour, relax, probe and analyse the piles at ``rate``; their working directory."""
    work = REPO / "results" / "pour_rate" / f"rate{rate:g}"
    work.mkdir(parents=True, exist_ok=True)
    (work / "rate.yaml").write_text(yaml.safe_dump({"pour": {"rate": float(rate)}}))
    cfg = yaml.safe_load((REPO / "config" / "pour_rate.yaml").read_text())
    summaries = [f"results/fields/{p}/seed{s}.summary.json" for p, v in cfg["protocols"].items()
                 for s in v["seeds"]]
    cmd = [sys.executable, "-m", "snakemake", "all", *summaries, "-s", str(REPO / "Snakefile"),
           "--directory", str(work), "--cores", str(cores),
           "--profile", str(REPO / "workflow" / "profiles" / "default"),
           "--configfile", str(REPO / "config" / "config.yaml"), str(REPO / "config" / "pour_rate.yaml"),
           str(work / "rate.yaml")]
    print(f"rate {rate:g}/s: {' '.join(cmd)}", flush=True)
    subprocess.run(cmd, check=True)
    return work


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


def table(results: dict, rates: list) -> str:
    """Markdown: per protocol and quantity, mean ± SE at each rate, and the largest
    difference between two rates in combined standard errors."""
    rows = ["| protocol | quantity | " + " | ".join(f"{r:g}/s" for r in rates) + " | max |Δ|/SE |",
            "|---|---|" + "---|" * (len(rates) + 1)]
    for protocol, by_rate in results["piles"].items():
        for q, label in QUANTITIES.items():
            stats = [mean_sem([p[q] for p in by_rate[f"{r:g}"]]) for r in rates]
            z = max((abs(a[0] - b[0]) / np.hypot(a[1], b[1])
                     for i, a in enumerate(stats) for b in stats[i + 1:]), default=float("nan"))
            cells = " | ".join(f"{m:.4g} ± {s:.2g}" for m, s, _ in stats)
            rows.append(f"| {protocol} | {label} | {cells} | {z:.1f} |")
    return "\n".join(rows) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", nargs="+", type=float, default=[100.0, 200.0, 400.0])
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--keep-recorded", action="store_true",
                    help="take the rates not run now from the recorded pour_rate.json")
    args = ap.parse_args()
    cfg = yaml.safe_load((REPO / "config" / "pour_rate.yaml").read_text())
    params = parse_params(json.dumps(cfg["analysis"]))
    out = REPO / "docs" / "reproduction"
    results = {"piles": {p: {} for p in cfg["protocols"]}, "runs": {}}
    if args.keep_recorded:
        results = json.loads((out / "pour_rate.json").read_text())
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=True).stdout.strip()
    for rate in args.rates:
        work = run_rate(rate, args.cores)
        for p, v in cfg["protocols"].items():
            results["piles"][p][f"{rate:g}"] = [pile_values(work, p, s, params) for s in v["seeds"]]
        results["runs"][f"{rate:g}"] = commit
    (out / "pour_rate.json").write_text(json.dumps(results, indent=1) + "\n")
    rates = sorted(float(r) for r in results["runs"])
    n = {p: len(v["seeds"]) for p, v in cfg["protocols"].items()}
    runs = ", ".join(f"{r:g}/s at `{results['runs'][f'{r:g}']}`" for r in rates)
    text = (f"# Pour rate: piles of {cfg['pour']['n_particles']} particles, seeds per protocol {n}\n\n"
            "Made by `workflow/scripts/pour_rate.py` (config/pour_rate.yaml); mean ± standard error "
            "over seeds; the last column is the largest difference between two rates over their "
            f"combined standard error (> 2: differs beyond seed scatter). Run: {runs}.\n\n"
            + table(results, rates))
    (out / "pour_rate.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
