"""Is the probe response linear in the gravity reduction, and does a ramp remove the slips?

Reads the ``probes.nc`` of piles probed by ``config/scenes/probe_levels.yaml``
(reductions of 5, 10 and 15 % and the restoration after the 10 % one, gravity
changed at once) and by ``config/scenes/probe_levels_ramp.yaml`` (the same
over ``probe.ramp_time``), each in its own Snakemake working directory, and
per pile computes (:func:`analysis.probes.pile_levels`):

* the compliance at each level: the median over the core RVEs
  (``analysis.history``: ``|x| <= shoulder_outer``, ``y <= core_height``) of
  ``u_yy / Delta``; its *linearity* ``c(Delta) / c(10 %) - 1`` (0 for a pile
  that answers in proportion; above 0 at 15 %: softer under the larger load);
* the slips: RVEs whose ``|u|`` exceeds ``analysis.ensemble.slip_strain_ratio``
  times that probe's median over the pile (:func:`analysis.ensemble.slipped`);
* the reversibility ``1 - |u(restored)| / |u(reduced)|``, median over RVEs;
* with both modes, the ramp's compliance at 10 % over the step's, minus 1.

Then the mean and standard error over each protocol's piles.  Prints Markdown
and writes it (``--out``) with the numbers as JSON beside it.

Usage::

    .venv/bin/python -m workflow.tools probe_levels --piles config/sweep_piles.yaml \\
        --step DIR --ramp DIR --out docs/reproduction/probe_levels.md
"""

import json
from pathlib import Path

import numpy as np
import xarray as xr


from analysis.ensemble_statistics import mean_sem
from analysis.params import parse_params
from analysis.probes import pile_levels
from sim.settings_file import read_settings_file
from workflow.layout import folders

from ._cli import ToolParser, existing_file, existing_folder, output_file, refuse

def _pm(values, scale=1.0, spec=".1f") -> str:
    m, se, _, n = mean_sem(values)
    if n == 0:
        return "n/a"
    return f"{format(scale * m, spec)} ± " + ("n/a" if not np.isfinite(se) else format(scale * se, spec))


def report(results: dict, ramp_time: float) -> str:
    """Markdown tables of ``results[mode][protocol] = [pile numbers]``."""
    modes = list(results)
    rows = ["| protocol | mode | linearity at 5 % | linearity at 15 % | compliance at 10 % (1) | "
            "slips at 5 / 10 / 15 % / restored (per pile) | reversibility |",
            "|---|---|---|---|---|---|---|"]
    for protocol in results[modes[0]]:
        for mode in modes:
            piles = results[mode].get(protocol, [])
            slips = " / ".join(",".join(str(p["slips"].get(s, 0)) for p in piles)
                               for s in ("reduced05", "reduced", "reduced15", "restored"))
            rows.append(f"| {protocol} | {mode} | {_pm([p['linearity'].get('reduced05') for p in piles], 100)} % | "
                        f"{_pm([p['linearity'].get('reduced15') for p in piles], 100)} % | "
                        f"{_pm([p['compliance'].get('reduced') for p in piles], 1, '.4g')} | {slips} | "
                        f"{_pm([p['reversibility'] for p in piles], 1, '.3f')} |")
    text = "\n".join(rows) + "\n"
    if {"step", "ramp"} <= set(modes):
        text += ("\nRamp against step, per pile: the ramp's compliance at 10 % over the step's − 1 (mean ± SE, %): "
                 + "; ".join(f"{p} {_pm([r['compliance']['reduced'] / s['compliance']['reduced'] - 1 for r, s in zip(results['ramp'][p], results['step'][p])], 100)} %"
                             for p in results["step"] if p in results["ramp"])
                 + f" (ramp over {ramp_time:g} s).\n")
    return text


def main(argv=None):
    """Command line: print the report (and write it to ``--out``)."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--piles", type=existing_file, required=True,
                    help="the piles' settings (their protocols, seeds, analysis)")
    ap.add_argument("--step", type=existing_folder, help="working directory of the step probes")
    ap.add_argument("--ramp", type=existing_folder, help="working directory of the ramp probes")
    ap.add_argument("--out", type=output_file, help="Markdown file to write (and its .json beside it)")
    args = ap.parse_args(argv)
    if not (args.step or args.ramp):
        ap.error("give --step DIR, --ramp DIR or both")
    cfg = read_settings_file(args.piles)
    if not (isinstance(cfg.get("protocols"), dict) and "n_particles" in cfg.get("pour", {})):
        refuse(f"--piles {args.piles}: no protocols or pour.n_particles; allowed is a piles' settings file "
               "(config/sweep_piles.yaml)")
    try:
        params = parse_params(json.dumps(cfg.get("analysis", {})))
    except ValueError as exc:   # its one message names the setting
        refuse(f"--piles {args.piles}: analysis: {' '.join(str(exc).split())}")
    study = read_settings_file(Path(__file__).resolve().parents[2] / "config" / "config.yaml")
    ramp_time = study["probe"]["ramp_time"]
    tree = cfg.get("results", study["results"])  # the piles' results folder in each working directory
    results = {}
    for mode, work in (("step", args.step), ("ramp", args.ramp)):
        if work is None:
            continue
        results[mode] = {}
        for protocol, v in cfg["protocols"].items():
            for seed in v["seeds"]:
                path = folders(work, tree)[0] / "fields" / protocol / f"seed{seed}.probes.nc"
                if not path.exists():
                    refuse(f"--{mode} {work}: {path} is missing; run the probes first")
                with xr.open_dataset(path) as pr:
                    results[mode].setdefault(protocol, []).append(pile_levels(pr.load(), params))
    n = {p: len(v["seeds"]) for p, v in cfg["protocols"].items()}
    text = (f"# Probe levels and ramp: piles of {cfg['pour']['n_particles']} particles, seeds per protocol {n}\n\n"
            "Made by `workflow/tools/probe_levels.py` from the probes of `config/scenes/probe_levels.yaml` "
            "(step) and `config/scenes/probe_levels_ramp.yaml` (ramp); mean ± standard error over piles. "
            "Linearity: the core's median u_yy/Δ at 5 and 15 % over that at 10 %, − 1 (0: linear); compliance: "
            "the core's median u_yy/Δ at 10 %; slips: RVEs above the slip rule per probe, pile by pile; "
            "reversibility: median over RVEs of 1 − |u(restored)|/|u(reduced)|.\n\n" + report(results, ramp_time))
    print(text)
    if args.out:
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps(results, indent=1) + "\n")
