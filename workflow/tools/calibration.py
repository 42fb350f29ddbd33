"""Calibrate the sources before the stresses (issue 44, step 4): one record per pile.

Reads ``config/calibration.yaml``: the piles (``config/sweep_piles.yaml``,
1600 particles), fresh seeds, and the *arms*, each a protocol and the settings
that make its source.  Every (arm, seed) is poured, relaxed, probed and
analysed by the workflow in its own working directory
``results/calibration/ARM/seedS/`` (so that two piles run side by side, one
per core, without sharing a Snakemake lock), with a film's frames every
``frame_interval`` simulated seconds, and as soon as it lands its record is
written to ``docs/reproduction/calibration/ARM-seedS.json``:

* ``growth``: how the pile grew, read from the frames of the growth (from
  ``START`` of the particles released to the last release) by
  :func:`analysis.growth.growth_statistics`: the fraction of those frames in
  which *the flanks flow* (at least ``FLOW_MIN`` particles of the pile,
  released more than ``OLD`` s before and with their centre below the tip,
  faster than the settling speed: an avalanche, not a particle landing), the
  median and largest number of such particles, the flank angle (median, 90th
  percentile, largest) and the measured flux; and how the pile was laid
  down (:func:`analysis.growth.landing_displacement`): the share of its
  particles resting within one mean diameter of where they landed
  (``interior_share``), within two, and quantiles of that distance;
* ``quantities`` and ``inputs``: :func:`analysis.pile_quantities.pile_record`:
  the sweeps' per-pile numbers (shape, core solid fraction, the five primary
  history statistics, core moduli), the σ_yy column contrast of the lowest
  RVE row (``stress_column``, the low-variance statistic of
  docs/reproduction.md) and the flank fabric; and the numbers it and
  ``base_pressure_column`` are computed from, so that a reader recomputes
  both from the record alone;
* ``cpu_s``: CPU seconds of the pour, the relaxation and the probes, each,
  from the summary lines of their logs (``definitions.cpu_from``; records
  made before that took them from Snakemake's benchmark files);
* ``commit``: the checkout the pile was made in;
* ``definitions.probe_levels``: the gravity probes the pile was given
  (``probe.levels``; records made before it was written were probed at 0.10).

A pile without the probe: ``probe: {levels: []}`` with ``outputs`` without
``strain`` and ``fits`` (in the plan's ``piles`` file, or in every arm's
``settings``) pours, relaxes and analyses the pile without the gravity probe
after its relaxation.  Its record holds NaN for the quantities read from the
probe (``strain@h``, ``gravity_xx``, ``gravity_yy``, ``gravity_gap``, the core
moduli) and 0 for the probes' CPU; every other number is the one the pile
gives with the probe (tests/test_calibration_probe_cut.py).  Settings whose pile
cannot make its record are refused before any pile (:func:`record_problems`).

``FLOW_MIN``, ``OLD`` and ``START`` (:mod:`analysis.growth`) were fixed, and
committed, before the first calibration pile was poured.  ``--table`` prints the table of the
records (mean ± standard error over seeds, per arm), each checked against the
configuration that registered its pile (:mod:`workflow.tools._records`: a copy
of another record, another arm or seed is refused, not tabled);
``--out`` writes it (``docs/reproduction/calibration.md``).

Usage::

    .venv/bin/python -m workflow.tools calibration --jobs 2 [--arms "wedge funnel"] [--records DIR]
    .venv/bin/python -m workflow.tools calibration --table [--out docs/reproduction/calibration.md]
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import xarray as xr
import yaml

from analysis.ensemble_statistics import compare, mean_sem, paired_difference, welch
from analysis.growth import FLOW_MIN, OLD, START, growth, growth_statistics, landing_displacement
from analysis.params import parse_params
from analysis.pile_quantities import pile_record, quantities
from analysis.run_times import stage_cpu_time
from sim.config import SimConfig
from sim.pour import pile_shapes
from sim.release import SETTLED_SPEED, mean_diameter
from sim.settings_file import SettingsDumper, read_settings_file
from workflow.outputs import Outputs
from workflow.piles import Piles
from workflow.validation import check_problems, merge_configs, validate_config

from ._cli import ToolParser, existing_file, output_file, positive_int, refuse, seed, shown
from ._records import check_registered, check_unique, read_records, read_registration

REPO = Path(__file__).resolve().parents[2]

CONFIG = REPO / "config" / "calibration.yaml"
RECORDS = REPO / "docs" / "reproduction" / "calibration"
#: Stages whose logs' CPU lines make the CPU time of a pile.
JOBS = ("pour", "relax", "probe")
#: The outputs whose fields a pile's record reads: the stress and the fabric (the flank fabric).
RECORD_OUTPUTS = ("fields", "fabric")


def arm_config(cal: dict, arm: str, seed: int) -> dict:
    """The workflow configuration of one calibration pile: the study's, the piles', the arm's protocol
    alone with this seed, a film's frames (not the film), and the arm's settings.

    Raises
    ------
    ValueError
        Naming the settings, their values and what is allowed, for a configuration the
        workflow refuses (its checks of the settings and of the scene) or whose pile
        cannot make its record (:func:`record_problems`).
    """
    spec = cal["arms"][arm]
    cfg = merge_configs(read_settings_file(REPO / "config" / "config.yaml"), read_settings_file(REPO / cal["piles"]))
    cfg = merge_configs(cfg, {"pour": {"frame_interval": cal["frame_interval"]}})
    cfg = merge_configs(cfg, spec["settings"])
    cfg["protocols"] = {spec["protocol"]: {"seeds": [seed]}}
    cfg["outputs"] = sorted(set(cfg["outputs"]) | {"film"})
    validate_config(cfg)
    outputs = Outputs(Piles(cfg))
    check_problems(outputs.problems(REPO) + record_problems(outputs), "arm")
    return cfg


def record_problems(outputs: Outputs) -> list[str]:
    """What keeps a pile of these outputs from its record, beyond the workflow's own checks.

    Parameters
    ----------
    outputs : workflow.outputs.Outputs
        The outputs of the pile's configuration.

    Returns
    -------
    list of str
        One message per problem, naming the setting, its value and what is allowed: an
        output of :data:`RECORD_OUTPUTS` left out, or a gravity probe whose strain would
        not be computed (the probe read by half).  Strain without a probe the
        workflow refuses itself (:meth:`workflow.outputs.Outputs.problems`).
    """
    asked, levels = outputs.config["outputs"], outputs.config["probe"]["levels"]
    problems = [f"outputs {asked}: a pile's record reads the {name}; add {name!r}"
                for name in RECORD_OUTPUTS if not outputs.wants(name)]
    if outputs.has_probes() and not outputs.wants("strain"):
        problems.append(f"probe.levels {levels} with outputs {asked}: the record would read the probe without its "
                        "strain; add 'strain', or give probe.levels [] for a pile without the probe")
    return problems


def slug(arm: str) -> str:
    """``wedge funnel`` → ``wedge_funnel`` (folder and file names)."""
    return arm.replace(" ", "_")


def targets(cfg: dict, protocol: str, seed: int) -> dict:
    """The files of one pile the record is read from, relative to its working directory."""
    res = cfg.get("results", "results/study")
    stem = f"{res}/fields/{protocol}/seed{seed}"
    pile = f"{res}/piles/{protocol}/seed{seed}"
    return {"fields": f"{stem}.nc", "summary": f"{stem}.summary.json", "base_pressure": f"{stem}.base_pressure.nc",
            "frames": f"{pile}/frames.nc", "relaxed": f"{pile}/relaxed.nc", "logs": f"{res}/logs"}


def cpu_seconds(logs: Path, protocol: str, seed: int, probed: bool) -> dict:
    """CPU seconds of each simulation stage of the pile (the probes summed), from the
    summary lines of their logs (:func:`analysis.run_times.stage_cpu_time`); NaN for a
    stage whose log has none, 0 for the probes of a pile not `probed`."""
    out = {}
    for job in JOBS:
        files = sorted((logs / job / protocol).glob(f"seed{seed}.log")) + \
            sorted((logs / job / protocol).glob(f"seed{seed}_*.log"))
        if files:
            out[job] = float(sum(stage_cpu_time(f) for f in files))
        else:                                         # no log: unknown, unless no such stage ran
            out[job] = 0.0 if job == "probe" and not probed else math.nan
    out["total"] = float(sum(out.values()))
    return out


def growth_record(frames: Path, cfg: dict, protocol: str, seed: int) -> dict:
    """The growth statistics of one pile from its frames (:func:`analysis.growth.growth_statistics`),
    its particles drawn again from its settings and seed."""
    sim_cfg = SimConfig.from_dict({k: cfg[k] for k in ("model", "particles", "pour") if k in cfg})
    shapes = pile_shapes(sim_cfg, seed)
    n = cfg["pour"]["n_particles"]
    return growth_statistics(growth(frames, shapes.radius[:n], mean_diameter(shapes), START, SETTLED_SPEED), FLOW_MIN)


def landing_record(frames: Path, relaxed: Path, cfg: dict, seed: int) -> dict:
    """Where the particles came to rest against where they landed
    (:func:`analysis.growth.landing_displacement`, distances in mean diameters)."""
    sim_cfg = SimConfig.from_dict({k: cfg[k] for k in ("model", "particles", "pour") if k in cfg})
    with xr.open_dataset(relaxed) as ds:
        x, y = ds["x"].values, ds["y"].values
    return landing_displacement(frames, x, y, mean_diameter(pile_shapes(sim_cfg, seed)))


def commit_of(folder: Path) -> str:
    """The short commit of the checkout the pile was made in."""
    return subprocess.run(["git", "-C", str(folder), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()


#: Held while a pile's files are read: the piles run side by side in threads, and the
#: netCDF/HDF5 library is not thread-safe (two reads at once failed with "NetCDF: Can't open
#: HDF5 attribute" and stopped the run).
READING = threading.Lock()


def run_pile(cal: dict, arm: str, seed: int, records: Path) -> Path:
    """Pour, relax, probe and analyse one pile in its own working directory; write its record."""
    cfg = arm_config(cal, arm, seed)
    protocol = cal["arms"][arm]["protocol"]
    work = REPO / "results" / "calibration" / slug(arm) / f"seed{seed}"
    work.mkdir(parents=True, exist_ok=True)
    (work / "config.yaml").write_text(yaml.dump(cfg, Dumper=SettingsDumper))
    files = targets(cfg, protocol, seed)
    cmd = [sys.executable, "-m", "snakemake",
           *(files[k] for k in ("fields", "summary", "base_pressure", "frames", "relaxed")),
           "-s", str(REPO / "Snakefile"), "--directory", str(work), "--cores", "1",
           "--profile", str(REPO / "workflow" / "profiles" / "default"),
           "--configfile", str(work / "config.yaml"), "--replace-workflow-config"]
    log = work / "calibration.log"
    print(f"{arm} seed {seed}: {work.relative_to(REPO)} (log {log.name})", flush=True)
    with open(log, "a") as out:
        subprocess.run(cmd, check=True, stdout=out, stderr=subprocess.STDOUT, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    with READING:                                     # HDF5 is not thread-safe: one pile's files at a time
        record = calibration_record(cal, arm, seed, cfg, protocol, work, files)
    records.mkdir(parents=True, exist_ok=True)
    dest = records / f"{slug(arm)}-seed{seed}.json"
    tmp = dest.with_suffix(".part")
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    tmp.replace(dest)
    print(f"{arm} seed {seed}: recorded {dest} ({record['cpu_s']['total']:.0f} CPU s, "
          f"flanks flow {100 * record['growth']['flow_fraction']:.0f} % of the growth)", flush=True)
    return dest


def calibration_record(cal: dict, arm: str, seed: int, cfg: dict, protocol: str, work: Path, files: dict) -> dict:
    """The record of one poured, relaxed, probed (unless ``probe.levels`` is empty) and analysed
    pile, read from its working directory (the module's docstring says what it holds)."""
    params = parse_params(json.dumps(cfg["analysis"]))
    path = {k: work / v for k, v in files.items()}
    q, inputs = pile_record(path["summary"], path["fields"], path["base_pressure"], params)
    record = {"arm": arm, "protocol": protocol, "seed": seed, "n_particles": cfg["pour"]["n_particles"],
              "settings": cal["arms"][arm]["settings"], "commit": commit_of(REPO),
              "growth": {**growth_record(path["frames"], cfg, protocol, seed),
                         **landing_record(path["frames"], path["relaxed"], cfg, seed)},
              "quantities": q, "inputs": inputs,
              "cpu_s": cpu_seconds(path["logs"], protocol, seed, Outputs(Piles(cfg)).has_probes()),
              "definitions": {"flow_min": FLOW_MIN, "old_s": OLD, "start": START,
                              "frame_interval": cal["frame_interval"], "cpu_from": CPU_FROM,
                              "probe_levels": cfg["probe"]["levels"]}}
    return record


GROWTH = {"flow_fraction": "fraction of the growth the flanks flow",
          "old_moving_median": "pile particles moving, median per frame",
          "old_moving_max": "pile particles moving, largest",
          "flank_median_deg": "flank angle while growing, median (deg)",
          "flank_p90_deg": "flank angle while growing, 90th percentile (deg)",
          "flux_per_s": "flux (particles per s)"}
EXTRA = {"stress_column": "σ_yy lowest row centre/shoulders against a uniform pile − 1",
         "fabric_deviator": "flank fabric deviatoric fraction",
         "fabric_axis_deg": "flank fabric axis, mirrored (deg)"}
#: Where a record's ``cpu_s`` come from (``definitions.cpu_from``); records without it
#: took them from Snakemake's benchmark files, which miss a job's last seconds.
CPU_FROM = "stage logs"
CPU = {"pour": "CPU s, pour", "relax": "CPU s, relaxation", "probe": "CPU s, probes", "total": "CPU s per pile"}


def table(records: list, params: dict, arms: list) -> str:
    """Markdown: per quantity, mean ± standard error over seeds (and the number of piles) of each arm.

    A value that is not a number (NaN: not measured in that pile) is left out
    of its cell, which then says how many piles it holds: ``(5 of 6 piles)``.
    """
    by_arm = {a: [r for r in records if r["arm"] == a] for a in arms}
    by_arm = {a: rs for a, rs in by_arm.items() if rs}
    rows = ["| quantity | " + " | ".join(f"{a} ({len(rs)})" for a, rs in by_arm.items()) + " |",
            "|---|" + "---|" * len(by_arm)]
    sections = [("growth", GROWTH), ("quantities", {**quantities(params), **EXTRA}), ("cpu_s", CPU)]
    for part, names in sections:
        for key, text in names.items():
            cells = []
            for rs in by_arm.values():
                m, s, _, n = mean_sem([r[part].get(key, math.nan) for r in rs])
                cells.append(f"{m:.4g} ± {s:.2g}" + (f" ({n} of {len(rs)} piles)" if n < len(rs) else ""))
            rows.append(f"| {text} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


#: The statistics of the history comparison set side by side for each lever (exploratory).
CONTRASTS = ("stress_column", "base_pressure_column", "solid_fraction@4.5", "strain@4.5")


def baseline_arm(arm: str, baseline: list) -> str | None:
    """The baseline arm a lever's arm changes one setting of: the longest baseline name it starts with."""
    found = [b for b in baseline if arm.startswith(b + " ")]
    return max(found, key=len) if found else None


def lever_contrasts(records: list, baseline: list, arms: list) -> str:
    """Markdown: per lever value (the baseline's, then each lever's), the point source − layered
    difference of :data:`CONTRASTS` by Welch's test, and each arm's change with the lever, paired by seed.

    Exploratory numbers (no test here was registered): they say which lever a registered
    ensemble should vary, they decide nothing.
    """
    values = lambda arm, key: {r["seed"]: r["quantities"].get(key, math.nan)  # noqa: E731
                               for r in records if r["arm"] == arm}
    levers = {}
    for arm in arms:
        base = baseline_arm(arm, baseline)
        if base is not None:
            levers.setdefault(arm[len(base) + 1:], {})[base] = arm
    out = ["| lever | arms | " + " | ".join(CONTRASTS) + " |", "|---|---|" + "---|" * len(CONTRASTS)]
    rows = [("default", dict(zip(baseline, baseline)))] + list(levers.items())
    for name, by_base in rows:
        point = [a for b, a in by_base.items() if b.startswith("wedge")]
        layered = [a for b, a in by_base.items() if b.startswith("layered")]
        if not (point and layered and values(point[0], CONTRASTS[0]) and values(layered[0], CONTRASTS[0])):
            continue
        cells = []
        for key in CONTRASTS:
            a, b = list(values(point[0], key).values()), list(values(layered[0], key).values())
            w = welch(a, b)
            cells.append(f"{100 * compare(a, b)['diff']:+.1f} % (t {w['t']:.2f}, {w['df']:.0f} df)")
        out.append(f"| {name} | {point[0]} − {layered[0]} | " + " | ".join(cells) + " |")
    out += ["", "Each arm's change with its lever, paired by seed (lever − default, mean ± SE over the seeds "
            "of both):", "", "| arm | " + " | ".join(CONTRASTS) + " |", "|---|" + "---|" * len(CONTRASTS)]
    for name, by_base in levers.items():
        for base, arm in by_base.items():
            if not set(values(arm, CONTRASTS[0])) & set(values(base, CONTRASTS[0])):
                continue
            cells = []
            for key in CONTRASTS:
                m, se, _, n = paired_difference(values(arm, key), values(base, key))
                cells.append(f"{100 * m:+.1f} ± {100 * se:.1f} % ({n})")
            out.append(f"| {arm} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def main(argv=None) -> None:
    """Command line: run the piles not recorded yet, or (``--table``) print the table of the records."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=existing_file, default=CONFIG)
    ap.add_argument("--arms", nargs="*", default=None, help="the arms to run (default: all of the config)")
    ap.add_argument("--seeds", nargs="*", type=seed, default=None,
                    help="the seeds to run (default: the config's)")
    ap.add_argument("--jobs", type=positive_int, default=2, help="piles run side by side, one core each")
    ap.add_argument("--records", type=Path, default=RECORDS, help="where each pile's record is written")
    ap.add_argument("--table", action="store_true", help="only print the table of the records")
    ap.add_argument("--out", type=output_file, default=None,
                    help="with --table: also write the table to this file (docs/reproduction/calibration.md)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="with --table: the records of the arms the config's arms change one setting of "
                         "(docs/reproduction/calibration for config/levers.yaml), tabled beside them with "
                         "the point − layered contrasts at each lever value")
    args = ap.parse_args(argv)
    cal = read_registration(args.config)
    arms = args.arms or list(cal["arms"])
    unknown = sorted(set(arms) - set(cal["arms"]))
    if unknown:
        refuse(f"--arms: {unknown} not among the arms of {args.config}: {list(cal['arms'])}")
    if args.table:
        params = parse_params(json.dumps(read_settings_file(REPO / cal["piles"])["analysis"]))
        found = read_records(args.records)
        check_registered(found, args.config)
        records = list(found.values())
        base_found = read_records(args.baseline, "--baseline") if args.baseline else {}
        check_unique(base_found)
        base_records = list(base_found.values())
        baseline = list(dict.fromkeys(r["arm"] for r in base_records
                                      if any(baseline_arm(a, [r["arm"]]) for a in arms)))
        page = (f"# {'Levers of the sources' if baseline else 'The calibration of the sources'}: piles of "
                f"{records[0]['n_particles']} particles, per arm\n\n"
                "Made by `python -m workflow.tools calibration --table` from the per-pile records in "
                f"{shown(args.records)}/ (settings: {shown(args.config)}; what each number is: the script's "
                "docstring); mean ± standard error over seeds, the number of piles after each arm. CPU seconds "
                "are each job's own, with two piles side by side on a 2-core host: from the stages' own CPU "
                "lines where a record's definitions say `cpu_from: stage logs`, else from Snakemake's "
                "benchmark files, which miss a job's last seconds.\n\n"
                + table(records + [r for r in base_records if r["arm"] in baseline], params, baseline + arms))
        if baseline:
            page += (f"\n## The levers, exploratory\n\nThe default arms' records are those of "
                     f"{shown(args.baseline)}/ (same seeds). Point source − layered, at each lever value, "
                     "in per cent of the statistic (Welch's t; not registered, no threshold):\n\n"
                     + lever_contrasts(records + base_records, baseline, arms))
        if args.out:
            args.out.write_text(page)
        print(page)
        return
    seeds = args.seeds or cal["seeds"]
    for arm in arms:                                  # refuse a bad arm before any pile
        try:
            arm_config(cal, arm, seeds[0])
        except ValueError as exc:                     # the settings' own one-line message
            refuse(f"--config {args.config}: arm {arm!r}: {' '.join(str(exc).split())}")
    # seed-major: the first seeds of every arm land first, so a stopped run leaves every arm measured
    todo = [(a, s) for s in seeds for a in arms if not (args.records / f"{slug(a)}-seed{s}.json").exists()]
    print(f"{len(todo)} piles to run, {args.jobs} at a time", flush=True)
    failed = []

    def one(job):
        try:
            run_pile(cal, *job, args.records)
        except subprocess.CalledProcessError:       # its log says why; the other piles go on
            failed.append(job)
            print(f"{job[0]} seed {job[1]}: failed, see results/calibration/{slug(job[0])}/seed{job[1]}/"
                  "calibration.log", flush=True)

    with ThreadPoolExecutor(args.jobs) as pool:
        list(pool.map(one, todo))
    if failed:
        refuse(f"{len(failed)} of {len(todo)} piles failed: {failed}")
