"""Where a pile's CPU goes: delivery, settling, relaxation and probes, per pile and per arm (issue 57, item 2).

Reads the calibration tool's work folders (``results/calibration/ARM/seedS/``,
:mod:`workflow.tools.calibration`), each pile whose record is in ``--records``
(so its pour, relaxation and probes are done): the simulated time and step of
its states (``poured.nc``, ``relaxed.nc``, the probes'), the release count of
its frames (``frames.nc``) and of its pour's progress lines, the wall clock of
those lines, and the CPU and wall seconds of its jobs (Snakemake's benchmark
files).  The arithmetic is :mod:`analysis.pour_budget`'s: the phases'
particle-steps, the pour's CPU shared between delivery and settling by them,
the CPU the benchmarks' sampling leaves out, the medians per arm.  Writes a
Markdown page (``--out``, docs/performance/pour_budget.md) and prints it.

Usage::

    .venv/bin/python -m workflow.tools pour_budget /work/ensemble/results/calibration \\
        --records /work/ensemble/docs/reproduction/decision_equal_slope [--out docs/performance/pour_budget.md]
"""

from __future__ import annotations

import datetime as _dt
import inspect
import math
import re
import shlex
import subprocess
import sys
from pathlib import Path

import xarray as xr

from analysis.pour_budget import (PHASES, arm_summary, cost_fit, first_long_sample_jobs, pile_budget,
                                  settling_wall_share, tail_estimate)
from analysis.run_times import benchmark_row, stage_cpu_time
from sim.pour import LANDING_WINDOW, pour
from sim.settings_file import read_settings_file
from workflow.stages import probe_input_stage

from ._cli import ToolParser, existing_folder, output_file, read_json, refuse

#: A pour's progress line: released count, simulated time, steps.
PROGRESS = re.compile(r"^(\S+ \S+) INFO .*: released (\d+) of \d+ .*; t = ([0-9.]+) s simulated, .*?, (\d+) steps")
#: The first line of a pour (after its start) and its last.
POURING = re.compile(r"^(\S+ \S+) INFO pouring \d+ particles")
DONE = re.compile(r"^(\S+ \S+) INFO pour \S+ seed \d+ done: wall [0-9.]+ s, (\d+) steps")
STARTED = "started by process"
#: The least simulated time a pour runs after its last release: its settling time (``pour``'s
#: ``settle_time``, which the workflow leaves at its default) and one landing window (``sim.pour._land``).
SETTLE_MIN = inspect.signature(pour).parameters["settle_time"].default + LANDING_WINDOW


def _clock(stamp: str) -> float:
    """Seconds of a log line's time stamp (``2026-12-07 22:40:50,859``)."""
    return _dt.datetime.strptime(stamp, "%Y-%m-%d %H:%M:%S,%f").timestamp()


def pour_log(path: Path) -> dict:
    """The known release counts (times, counts) of a pour's log and its wall clock against its
    steps (``[(steps, s)]``: from its ``pouring`` line, at step 0, to ``done``), and ``runs``, how many
    runs of the pour it holds (more than one: a resumed or retaken pour, whose steps did not all run
    in the job its benchmark file measured; its wall clock is then left empty)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    times, counts, clock = [], [], []
    for line in lines:
        if (m := PROGRESS.match(line)):
            times.append(float(m[3]))
            counts.append(int(m[2]))
            clock.append((int(m[4]), _clock(m[1])))
        elif (m := POURING.match(line)):
            clock.append((0, _clock(m[1])))
        elif (m := DONE.match(line)):
            clock.append((int(m[2]), _clock(m[1])))
    runs = sum(STARTED in line for line in lines)
    return {"times": times, "released": counts, "clock": clock if runs == 1 else [], "runs": runs}


def state_point(path: Path) -> tuple[float, int, float, int]:
    """Simulated time (s), step, time step (s) and particles of a state file."""
    try:
        with xr.open_dataset(path) as ds:
            return float(ds.attrs["time"]), int(ds.attrs["step"]), float(ds.attrs["dt"]), int(ds["x"].size)
    except (OSError, KeyError, ValueError) as exc:
        refuse(f"{path}: not a state file with time, step and dt ({type(exc).__name__}: {exc})")


def benchmark(path: Path) -> dict:
    """CPU and wall seconds of one job (:func:`analysis.run_times.benchmark_row`), refused by file."""
    try:
        return benchmark_row(path)
    except (OSError, ValueError) as exc:
        refuse(f"{path}: not a Snakemake benchmark file ({exc})")


def find_piles(folders: list[Path], records: Path) -> list[tuple[str, int, Path]]:
    """``(arm slug, seed, work folder)`` of every pile under `folders` whose record ``ARM-seedS.json``
    is in `records`."""
    found = {}
    for folder in folders:
        for cfg in sorted(folder.glob("*/seed*/config.yaml")):
            work = cfg.parent
            arm, seed = work.parent.name, work.name.removeprefix("seed")
            if seed.isdigit() and (records / f"{arm}-seed{seed}.json").is_file():
                found.setdefault(work.resolve(), (arm, int(seed), work))
    return list(found.values())


def _counted(log: Path) -> float:
    """A stage's CPU as its log's summary line counts it; NaN without the log or the line."""
    return stage_cpu_time(log) if log.is_file() else math.nan


def gather(arm: str, seed: int, work: Path, records: Path) -> dict:
    """The numbers of one pile that :func:`analysis.pour_budget.pile_budget` takes, and its budget."""
    cfg = read_settings_file(work / "config.yaml")
    (protocol,) = cfg["protocols"]
    res = work / cfg.get("results", "results/study")
    pile, bench = res / "piles" / protocol / f"seed{seed}", res / "benchmarks"
    n = int(cfg["pour"]["n_particles"])
    record = read_json(records / f"{arm}-seed{seed}.json")
    t_pour, s_pour, dt, kept = state_point(pile / "poured.nc")
    t_rel, s_rel, _, _ = state_point(pile / "relaxed.nc")
    probes, cpu, wall, counted = [], {}, {}, {}
    logs = res / "logs"
    for job in ("pour", "relax"):
        row = benchmark(bench / job / protocol / f"seed{seed}.tsv")
        cpu[job], wall[job] = row["cpu_s"], row["wall_s"]
        counted[job] = _counted(logs / job / protocol / f"seed{seed}.log")
    cpu["probe"] = wall["probe"] = counted["probe"] = 0.0
    for tsv in sorted((bench / "probe" / protocol).glob(f"seed{seed}_*.tsv")):
        stage = tsv.stem.removeprefix(f"seed{seed}_")
        t_end, s_end, _, count = state_point(pile / f"{stage}.nc")
        t_in, s_in, _, _ = state_point(pile / f"{probe_input_stage(stage)}.nc")
        probes.append((t_end - t_in, s_end - s_in, count))
        row = benchmark(tsv)
        cpu["probe"] += row["cpu_s"]
        wall["probe"] += row["wall_s"]
        counted["probe"] += _counted(logs / "probe" / protocol / f"{tsv.stem}.log")
    if not probes:
        cpu["probe"] = wall["probe"] = counted["probe"] = math.nan
    frames = pile / "frames.nc"
    try:
        with xr.open_dataset(frames) as ds:
            times, released = ds["time"].values.tolist(), ds["released"].values.tolist()
    except (OSError, KeyError, ValueError) as exc:
        refuse(f"{frames}: not a pour's frames with time and released ({type(exc).__name__}: {exc})")
    log = pour_log(res / "logs" / "pour" / protocol / f"seed{seed}.log")
    if log["runs"] != 1:                            # the benchmark and line measured only the last run
        cpu["pour"] = wall["pour"] = counted["pour"] = math.nan
    release = (times + log["times"], released + log["released"])
    try:
        relax = (t_rel - t_pour, s_rel - s_pour, kept)
        budget = pile_budget(n, dt, (t_pour, s_pour), release, relax, probes, cpu, wall, SETTLE_MIN, counted)
    except ValueError as exc:
        refuse(f"{frames}: {exc}")
    compiled = bench / "compile_kernels.tsv"
    row = benchmark(compiled) if compiled.is_file() else {"cpu_s": math.nan, "wall_s": math.nan}
    budget["cpu_est_compile"] = tail_estimate(row["cpu_s"], row["wall_s"])
    budget["last_release_bracket_s"] = budget["last_release_by"] - budget["last_release_after"]
    budget["settling_wall_share"] = settling_wall_share(log["clock"], budget["delivery_steps"])
    budget["settling_ps_share"] = budget["settling_ps"] / (budget["delivery_ps"] + budget["settling_ps"])
    return {"arm": record.get("arm", arm), "seed": seed, "commit": record.get("commit", "?"), "n": n,
            "dt": dt, "probes": len(probes), "runs": log["runs"], "budget": budget}


#: The phases and jobs as the page names them.
PHASE_NAMES = {"delivery": "delivery (first to last release)", "settling": "settling (last release to the pour's stop)",
               "relax": "relaxation", "probe": "probes"}
JOB_NAMES = {"pour": "pour", "relax": "relaxation", "probe": "probes", "total": "total"}
#: The rows of the per-arm table: heading, budget key, scale, format.
ROWS = (
    [("delivery: last release known within, s", "last_release_bracket_s", 1, ".3f")]
    + [(f"{name}: {what}", f"{phase}{key}", scale, spec) for phase, name in PHASE_NAMES.items()
       for what, key, scale, spec in (("simulated s", "_s", 1, ".3f"), ("steps, thousands", "_steps", 1e-3, ".1f"),
                                      ("particle-steps, millions", "_ps", 1e-6, ".0f"))]
    + [(f"{what}, {name}", f"{key}{job}", 1, ".1f") for what, key in
       (("wall s", "wall_"), ("CPU s recorded (benchmark)", "cpu_"), ("CPU s with the tail (counted, else estimated)", "cpu_est_"))
       for job, name in JOB_NAMES.items() if (key, job) != ("wall_", "total")]
    + [(f"**CPU s by phase, {name}**", f"cpu_est_{phase}", 1, ".1f")
       for phase, name in PHASE_NAMES.items()]
    + [(f"{what}, {name}, %", f"{key}{phase}", 100, ".1f") for what, key in
       (("**share of the pile's CPU**", "share_"), ("share of the recorded CPU", "share_recorded_"))
       for phase, name in PHASE_NAMES.items()]
    + [("not in the total: CPU s with the tail, compiling the kernels (its folder's `compile_kernels`)",
        "cpu_est_compile", 1, ".1f")]
    + [(f"CPU ns per particle-step (with the tail), {JOB_NAMES[job]}", f"ns_ps_{job}", 1, ".0f")
       for job in ("pour", "relax", "probe")]
    + [("settling's share of the pour: its particle-steps, %", "settling_ps_share", 100, ".1f"),
       ("settling's share of the pour: the log's wall clock, %", "settling_wall_share", 100, ".1f")])


def _cell(s: dict, scale: float, spec: str, piles: int) -> str:
    if not s["n"]:
        return "–"
    text = f"{scale * s['median']:{spec}} [{scale * s['min']:{spec}}–{scale * s['max']:{spec}}]"
    return text + (f" ({s['n']} of {piles})" if s["n"] < piles else "")


def arm_table(piles: list[dict]) -> str:
    """Markdown: per row of :data:`ROWS`, each arm's median [smallest–largest] over its piles."""
    arms = list(dict.fromkeys(p["arm"] for p in piles))
    summary = {a: arm_summary([p["budget"] for p in piles if p["arm"] == a]) for a in arms}
    count = {a: sum(p["arm"] == a for p in piles) for a in arms}
    lines = ["| per pile | " + " | ".join(f"{a} ({count[a]} piles)" for a in arms) + " |",
             "|---|" + "---|" * len(arms)]
    for head, key, scale, spec in ROWS:
        lines.append(f"| {head} | " + " | ".join(_cell(summary[a][key], scale, spec, count[a]) for a in arms) + " |")
    return "\n".join(lines) + "\n"


def pile_table(piles: list[dict]) -> str:
    """Markdown: one row per pile."""
    lines = ["| arm | seed | commit | delivery s | settling s | relax s | probes s "
             "| particle-steps M: delivery / settling / relax / probes "
             "| CPU s recorded: pour / relax / probes | wall s: pour / relax / probes "
             "| CPU s with tail: pour / relax / probes | shares %: delivery / settling / relax / probes |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for p in sorted(piles, key=lambda p: (p["arm"], p["seed"])):
        b = p["budget"]
        trio = lambda fmt, *keys: " / ".join(format(b[k], fmt) for k in keys)  # noqa: E731
        lines.append(
            f"| {p['arm']} | {p['seed']} | {p['commit']} | {b['delivery_s']:.3f} | {b['settling_s']:.3f} "
            f"| {b['relax_s']:.3f} | {b['probe_s']:.3f} "
            f"| {' / '.join(format(b[f'{ph}_ps'] / 1e6, '.0f') for ph in PHASES)} "
            f"| {trio('.1f', 'cpu_pour', 'cpu_relax', 'cpu_probe')} "
            f"| {trio('.1f', 'wall_pour', 'wall_relax', 'wall_probe')} "
            f"| {trio('.1f', 'cpu_est_pour', 'cpu_est_relax', 'cpu_est_probe')} "
            f"| {' / '.join(format(100 * b[f'share_{ph}'], '.1f') for ph in PHASES)} |")
    return "\n".join(lines) + "\n"


#: What the equal-slope decision's statistics read (checked in the code at the commit the page names).
STATISTICS = """## Which phases the equal-slope decision's statistics see

Checked in the code (line numbers at commit 8e10770):

- **`stress_column`** (D1 of the registrations; `workflow/tools/calibration.py` l. 199): `analysis/history.py`
  `pile_stress_contrasts` (l. 232-260) and `_stress_column_row` (l. 263-272) read the fields'
  `stress`, `mask_reason` and `surface_height`.  `analysis/fields.py` computes all three from
  the relaxed state alone (`rve_quantities`: `mask_reason` l. 174-177, `stress` l. 179-181;
  `compute_fields`: `surface_height` l. 316-317); the reduced state enters only
  `stress_reduced`, `stress_increment` and the strain (l. 189-203).  The slip filter that `stress_column`
  applies first (`analysis/ensemble.py` `leave_out_slips`, l. 98-126) blanks only the
  probe-response variables (`PROBE_RESPONSE`, `analysis/fields.py` l. 43-44), not `stress`:
  `stress_column` does not change with the probe.
- **`base_pressure_column` (D2), and `centre_column`**: `analysis/history.py`
  `base_pressure_inputs` and `base_pressure_stats` (l. 130-153) read `base_pressure.nc`, made
  from the stage `analysis.base_pressure.stage`, `relaxed` (rule `analysis_base_pressure_pile`,
  `workflow/rules/analysis.smk` l. 94-96), and the fields' `surface_height` (relaxed).
- **`interior_share`**: `workflow/tools/calibration.py` `landing_record` (l. 152-158) reads the
  pour's `frames.nc` and `relaxed.nc`.
- **angle, height, width**: the `relaxed` line of `summary.json`
  (`analysis/pile_quantities.py` `relaxed_line`, l. 67-73, read l. 96-98).
- **`stress_column` in scaled windows and on arm plus angle** (`analysis/decision.py`
  `scaled_stress_column`, `shape_check`): its record inputs and the angle, as above.
- **`solid_fraction@4.5`, `stress_fabric`**: relaxed (`solid_fraction`; the angle between the
  relaxed `stress` and `fabric`, `analysis/fields.py` l. 228).
- **`strain@4.5` and `gravity_gap`**, the first decision's secondaries that
  docs/reproduction/preregistration_equal_slope.md keeps as secondaries (`analysis/decision.py`
  `SECONDARY`, l. 36): **these read the probe**, the strain increment relaxed → reduced
  (`analysis/history.py` l. 209-216) and the stress increment (`gravity_scaling`, l. 156-167).
  So do the core moduli in the record's `quantities` (`analysis/pile_quantities.py` l. 104-107),
  which no test of the decision uses.
- The probe is also a gate: `analysis fields` checks the increment's balance
  (`analysis/balance.py` `increment_report`, l. 134) and, with `analysis.checks.enforce: true`
  (the decision's piles), a failed check fails the pile, which the preregistration counts missing.

So `stress_column`, `base_pressure_column` and the equal-slope decision's own secondaries
(`stress_column` in scaled windows and on arm plus angle, `interior_share`, `centre_column`, the angle) read no output of the probes: for them the
probes carry no physics.  Two registered secondaries inherited from the first decision,
`strain@4.5` and `gravity_gap`, are made from the probe: probing only where a statistic needs it
would drop those two (and the increment's balance check) from a decision ensemble, not `stress_column` or `base_pressure_column`.
"""


def host() -> str:
    """The CPU model of this machine (``/proc/cpuinfo``), or ``unknown``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def checkout_of(folder: Path) -> str:
    """``TOP at COMMIT``: the git checkout `folder` lies in and its short commit, or ``unknown``."""
    done = subprocess.run(["git", "-C", str(folder), "rev-parse", "--show-toplevel", "--short", "HEAD"],
                          capture_output=True, text=True)
    top_commit = done.stdout.split()
    return f"{top_commit[0]} at {top_commit[1]}" if len(top_commit) == 2 else f"{folder} (no git checkout)"


def findings(piles: list[dict]) -> str:
    """The page's summary: per arm, the median share of each phase and the CPU per pile; the fit of a
    job's CPU to its particle-steps over every job."""
    lines = []
    for arm in dict.fromkeys(p["arm"] for p in piles):
        s = arm_summary([p["budget"] for p in piles if p["arm"] == arm])
        shares = ", ".join(f"{name} {100 * s[f'share_{ph}']['median']:.0f} %" for ph, name in
                           zip(PHASES, ("delivery", "settling", "relaxation", "probes")))
        lines.append(f"- **{arm}** ({s['delivery_s']['n']} piles): {s['cpu_est_total']['median']:.0f} CPU s per pile "
                     f"with the tail ({s['cpu_total']['median']:.0f} recorded); {shares}; delivery "
                     f"{s['delivery_s']['median']:.2f} s simulated, {s['delivery_steps']['median'] / 1e3:.0f} "
                     f"thousand steps.")
    ps, cpu = [], []
    for p in piles:
        b = p["budget"]
        for job, steps in (("pour", b["delivery_ps"] + b["settling_ps"]), ("relax", b["relax_ps"]),
                           ("probe", b["probe_ps"])):
            ps.append(steps)
            cpu.append(b[f"cpu_est_{job}"])
    overhead, ns, jobs = cost_fit(ps, cpu)
    capped, largest = first_long_sample_jobs(*zip(*[(p["budget"][f"cpu_{job}"], p["budget"][f"wall_{job}"])
                                                    for p in piles for job in ("pour", "relax", "probe")]))
    if capped:
        lines.append(f"- The sampling's cap: of the {capped} jobs here of 16 to 45 s wall time, the most CPU "
                     f"recorded for one is {largest:.1f} s.")
    lines.append(f"- Over all {jobs} jobs (pours, relaxations, probes), CPU with the tail ≈ {overhead:.1f} s + "
                 f"{ns:.0f} ns × particle-steps (least squares, `analysis.pour_budget.cost_fit`): a job costs "
                 "some seconds before and after its steps (start-up, the kernels' cache, the states), which a "
                 "relaxation or probe pays in full however short; the pour's share of it is split by "
                 "particle-steps with the rest.")
    return "\n".join(lines) + "\n"


def rerun_note(piles: list[dict]) -> str:
    """A paragraph naming the piles whose pour log holds more than one run (their pour's CPU left out)."""
    rerun = [f"{p['arm']} {p['seed']}" for p in piles if p["runs"] != 1]
    return (f"Pours run more than once (resumed or retaken; the benchmark measured the last run only), their "
            f"pour CPU left out: {', '.join(rerun)}.\n\n" if rerun else "")


def counted_text(piles: list[dict]) -> str:
    """How many of the piles' jobs had their CPU counted by their own summary lines."""
    jobs = [p["budget"][f"counted_{job}"] for p in piles for job in ("pour", "relax", "probe")]
    return f"{sum(jobs)} of the {len(jobs)} jobs here"


def page(piles: list[dict], argv: list[str], folders: list[Path]) -> str:
    """The Markdown page: how it was made, the per-arm and per-pile tables, what the statistics read."""
    command = "python -m workflow.tools pour_budget " + " ".join(shlex.quote(a) for a in argv)
    checkouts = ", ".join(dict.fromkeys(checkout_of(f) for f in folders))
    commits = ", ".join(sorted({p["commit"] for p in piles}))
    dt = sorted({f"{p['dt']:.3g}" for p in piles})
    return (
        "# Where a pile's CPU goes: delivery, settling, relaxation, probes\n\n"
        f"Made by `{command}` on {_dt.date.today().isoformat()} on a host "
        f"{host()}; the piles were poured by {checkouts} "
        f"(their records name {commits}).  Piles of {', '.join(sorted({str(p['n']) for p in piles}))} particles, "
        f"dt = {', '.join(dt)} s.  Per arm: median [smallest–largest] over its piles.\n\n"
        "**Phases.** *Delivery*: from the first release (t = 0) to the last; its particle-steps are "
        "the release count integrated over its steps, the count known exactly at each frame of "
        "`frames.nc` and each progress line of the pour's log and linear between them; the last "
        f"release is placed in its bracket (the row *known within*; it ends at most {SETTLE_MIN:g} s, the "
        "pour's settling time and one landing window, before the pour's end) by the release rate before it. "
        "*Settling*: from the last release to the pour's stop criterion (`sim.pour._land`), all "
        "particles present.  *Relaxation* and *probes*: their steps from the states' `step` "
        "(relaxed − poured; each probe's state − its input's).  Steps and times are the states' own "
        "(`time`, `step`, `dt` attributes), not the log's.\n\n"
        "**CPU.** Each job's CPU is its Snakemake benchmark's `cpu_time`.  Snakemake samples it every "
        "0.5 s for about 15 s, then every 30 s, and not at the end (snakemake/benchmark.py), so "
        "the CPU after a job's last sample is missing: a relaxation or probe of 15 to 45 s wall time "
        "is recorded with the CPU of its first 15 s (the records' many 15.0-15.2 s), a pour of "
        "130 s with that of its first 105 s.  *With the unsampled tail* adds it back at the load the "
        "samples saw (`analysis.pour_budget.tail_estimate`; none when the job ended within 1 s of a "
        "sample's time), except where the job's log ends with the stage's own count (its summary line, "
        f"`CPU X s in this process`): that count is taken instead ({counted_text(piles)}).  Wall times grow with whatever else ran beside a job (the calibration tool "
        "runs two piles side by side); CPU times much less.  The pour's CPU is shared between delivery "
        "and settling by their particle-steps (*CPU s by phase*); the last row checks that against the "
        "pour log's wall clock (the wall time after the step of the last release, interpolated between "
        "progress lines).  Shares are of the pile's CPU with the tail, unless *recorded*.\n\n"
        + rerun_note(piles) + findings(piles) + "\n" + arm_table(piles)
        + "\n## Per pile\n\n" + pile_table(piles) + "\n" + STATISTICS)


def main(argv=None) -> None:
    """Command line: the budget of the finished piles in the work folders given."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=existing_folder, metavar="FOLDER",
                    help="a calibration work folder: ARM/seedS/ below it (results/calibration)")
    ap.add_argument("--records", type=existing_folder, required=True,
                    help="the records' folder: a pile counts when its ARM-seedS.json is there (its jobs are done)")
    ap.add_argument("--out", type=output_file, default=None, help="also write the page here "
                    "(docs/performance/pour_budget.md)")
    argv = list(argv) if argv is not None else sys.argv[1:]
    args = ap.parse_args(argv)
    found = find_piles(args.folders, args.records)
    if not found:
        refuse(f"FOLDER {' '.join(map(str, args.folders))}: no pile ARM/seedS/ with a record in --records "
               f"{args.records}; allowed: calibration work folders whose piles are recorded there")
    piles = []
    for arm, seed, work in found:
        try:
            piles.append(gather(arm, seed, work, args.records))
        except (OSError, KeyError, ValueError, TypeError) as exc:
            refuse(f"{work}: not a finished calibration pile ({type(exc).__name__}: {exc}); allowed: a work "
                   "folder with its config.yaml, states, frames, pour log and benchmark files")
    text = page(piles, argv, args.folders)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    print(text)
