"""Command line of the analysis: ``python -m analysis <command> ...`` (see ``--help``).

Every command takes ``--params``: the ``analysis`` section of the workflow
configuration as JSON or YAML text (or ``@file``; the workflow passes one
line of YAML flow text, :func:`analysis.params.params_flow_text`); it is validated, with the
defaults of :mod:`analysis.params` filled in, before any input is read. Bad
parameters or inputs end with a one-line ``error: ...`` naming the setting,
file or variable, and exit status 2 (parameters) or 1 (inputs, failed checks).
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import time
from pathlib import Path
from typing import Any

from sim.atomic import OutputError, atomic_path
from sim.digest import code_digest

from . import __version__
from .errors import AnalysisError, InputError, ParamError

#: The commands whose arguments and work live in a module of their own, imported
#: only when the command runs (or asks for its --help): ``command: module``.
MODULE_COMMANDS = {"draw": "draw", "export": "vtk", "film": "film"}


def check_units(ds, path: str | None = None) -> None:
    """:func:`analysis.fields.check_units`, imported when a fields file is read
    (the command line itself starts without xarray and scipy)."""
    from .fields import check_units as check

    check(ds, path)


def _log(msg: str) -> None:
    print(f"[analysis] {msg}", file=sys.stderr, flush=True)


def _read(path: str, check=None):
    """The netCDF file ``path``, loaded and verified (:func:`analysis.netcdf.read_dataset`, with ``check``);
    fields files are read with :func:`analysis.fields.check_units` as ``check``."""
    from .netcdf import read_dataset

    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    try:
        return read_dataset(path, check)
    except AnalysisError:
        raise
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot be read as netCDF ({exc})") from exc


def _require(ds, path: str, names: tuple[str, ...]) -> None:
    missing = [n for n in names if n not in ds.variables]
    if missing:
        raise InputError(f"{path}: missing variable(s) {', '.join(missing)}")


def _labelled(items: list[str]) -> dict[str, str]:
    """``label=path`` pairs (label defaults to the name of the file's folder)."""
    from .command_files import labelled

    out = {}
    for it in items:
        path = labelled(it)
        out[it.partition("=")[0] if path != it else
            os.path.basename(os.path.dirname(os.path.abspath(it))) or it] = path
    return out


def _relaxed_and_probes(relaxed_path: str, probes: dict[str, str], option: str) -> tuple:
    """The states of ``--relaxed`` and of probes of that pile, each checked to be what its argument means
    (:func:`analysis.states.check_identity`) before anything is computed.

    Parameters
    ----------
    relaxed_path : str
        The file of ``--relaxed``: a relaxed state.
    probes : dict
        Label to file.  With ``option`` ``--reduced`` (the label ``reduced``):
        a gravity reduction; with ``--probes``: the probe of the stage the
        label names, or of any probe stage where the label names none.
    option : str
        The argument that names the probes.

    Returns
    -------
    relaxed : analysis.states.State
    probes : dict
        Each label to its :class:`analysis.states.State`.
    """
    from .states import PROBE_STAGES, REDUCTION_STAGES, check_identity, load_state

    relaxed = load_state(relaxed_path)
    check_identity(relaxed.path, relaxed.attrs, "--relaxed", "relaxed",
                   "a relaxed state (stage 'relaxed', written by python -m sim relax)")
    states = {}
    pile = f"of the pile of --relaxed {relaxed_path}"
    for label, path in probes.items():
        state = load_state(path)
        if option == "--reduced":
            argument, stages = option, REDUCTION_STAGES
            takes = f"a gravity reduction (stage 'reduced' or 'reducedNN', python -m sim probe --level) {pile}"
        elif re.fullmatch(PROBE_STAGES, label):
            argument, stages, takes = f"{option} {label}=", re.escape(label), f"the probe of stage {label!r} {pile}"
        else:
            argument, stages = f"{option} {label}=", PROBE_STAGES
            takes = f"a probe (stage reducedNN, tiltpNN, tiltmNN, restored or stretched) {pile}"
        check_identity(state.path, state.attrs, argument, stages, takes, relaxed=(relaxed.path, relaxed.attrs))
        states[label] = state
    return relaxed, states


# ------------------------------------------------------------------ commands
def cmd_run_times(args, params) -> None:
    from .run_times import job_label, run_times_html

    missing = [p for p in args.benchmarks if not os.path.exists(p)]
    if missing:
        raise InputError(f"{missing[0]}: no such benchmark file")
    try:
        page = run_times_html({job_label(p): p for p in args.benchmarks}, args.title)
    except ValueError as exc:  # not a benchmark file: say which, write nothing
        raise InputError(str(exc)) from None
    with atomic_path(args.out) as tmp:
        with open(tmp, "w") as fh:
            fh.write(page)
    _log(f"run-times: {len(args.benchmarks)} jobs -> {args.out}")


def cmd_params(args, params) -> None:
    from .params import params_json

    print(params_json(params))


def cmd_fields(args, params) -> None:
    from .balance import balance_report, enforce, increment_report
    from .fields import check_quantities, compute_fields
    from .netcdf import write_dataset, write_json
    from .states import check_same_particles

    t0 = time.perf_counter()
    quantities = check_quantities(args.quantities, args.reduced is not None)
    relaxed, probes = _relaxed_and_probes(args.relaxed, {"reduced": args.reduced} if args.reduced else {},
                                          "--reduced")
    states = {"relaxed": relaxed, **probes}
    if args.reduced:
        check_same_particles(states["relaxed"], states["reduced"])
    reports = {stage: balance_report(state, params["checks"]) for stage, state in states.items()}
    increment = ({"increment": increment_report(states["relaxed"], states["reduced"], params["checks"])}
                 if "reduced" in states else {})
    passed = all(r["passed"] for r in [*reports.values(), *increment.values()])
    if args.checks:
        write_json({"passed": passed, "tolerances": params["checks"], "stages": reports, **increment,
                    "source": f"analysis {__version__}"}, args.checks)
    for stage, r in {**reports, **increment}.items():
        if "skipped" in r:
            _log(f"checks {stage}: not checked ({r['skipped']})")
            continue
        _log(f"checks {stage}: support reaction rel. error {r.get('support_reaction_rel_error', float('nan')):.3g}, "
             f"Love yy rel. error {r.get('love_rel_error_yy', float('nan')):.3g}"
             + (f", max net force / weight {r['net_force_ratio_max']:.3g}" if "net_force_ratio_max" in r else ""))
    if params["checks"]["enforce"]:
        enforce([*reports.values(), *increment.values()])
    relaxed = states["relaxed"]
    ds = compute_fields(relaxed, states.get("reduced"), params, quantities)
    ds.attrs["balance_checks_passed"] = int(passed)
    for stage, r in {**reports, **increment}.items():
        for k in ("support_reaction_rel_error", "love_rel_error_yy", "net_force_ratio_max"):
            if k in r:
                ds.attrs[f"{k}_{stage}"] = r[k]
    write_dataset(ds, args.out, title=f"RVE fields of pile {os.path.basename(args.relaxed)} "
                  f"({ds.attrs.get('protocol', '')}, seed {ds.attrs.get('seed', '')})", params=params)
    _log(f"fields: {relaxed.n_particles} particles, {ds.sizes['y'] * ds.sizes['x']} RVEs, "
         f"{time.perf_counter() - t0:.2f} s -> {args.out}")


def cmd_probes(args, params) -> None:
    from .netcdf import write_dataset
    from .probes import probe_increments

    t0 = time.perf_counter()
    relaxed, probes = _relaxed_and_probes(args.relaxed, _labelled(args.probes), "--probes")
    ds = probe_increments(relaxed, probes, params)
    write_dataset(ds, args.out, title=f"Probe increments of pile {os.path.basename(args.relaxed)} "
                  f"({ds.attrs.get('protocol', '')}, seed {ds.attrs.get('seed', '')})", params=params)
    _log(f"probes: {', '.join(probes)} of {relaxed.n_particles} particles, {time.perf_counter() - t0:.2f} s "
         f"-> {args.out}")


def cmd_general_fit(args, params) -> None:
    from .netcdf import write_dataset
    from .probes import general_fit_dataset

    from .states import check_distinct_piles

    piles = [_read(p) for p in args.probes]
    for ds, p in zip(piles, args.probes):
        _require(ds, p, ("stress_increment", "strain_increment", "probe"))
    ensemble = _read(args.ensemble, check_units) if args.ensemble else None
    check_distinct_piles(([(args.ensemble, ensemble.attrs)] if ensemble is not None else [])
                         + [(p, ds.attrs) for p, ds in zip(args.probes, piles)], "--probes")
    ds = general_fit_dataset(piles, params, ensemble)
    write_dataset(ds, args.out, title="General 2D elastic fit of the probe increments, and reversibility",
                  params=params)
    ok = int((ds["general_flag"].sel(points=5).values == 0).sum())
    _log(f"general-fit: {len(piles)} piles, probes {ds.attrs['loading_probes']}; m = 5 identified and positive "
         f"definite at {ok} RVEs; {ds.attrs['slip_left_out_total']} pile-probe-RVEs left out as slips -> {args.out}")


def cmd_ensemble(args, params) -> None:
    from .ensemble import ensemble_fields
    from .netcdf import write_dataset
    from .states import check_distinct_piles

    dss = []
    for p in args.fields:
        ds = _read(p, check_units)
        _require(ds, p, ("stress", "n_particles", "solid_fraction"))
        dss.append(ds)
    check_distinct_piles([(p, ds.attrs) for p, ds in zip(args.fields, dss)], "--fields")
    out = ensemble_fields(dss, list(args.fields), params["ensemble"]["slip_strain_ratio"])
    write_dataset(out, args.out, title=f"ensemble fields, protocol {out.attrs.get('protocol', '')}, "
                  f"{len(dss)} piles", params=params)
    _log(f"ensemble of {len(dss)} piles, {out.attrs['slip_left_out_total']} pile-RVEs left out as slipped "
         f"(per pile: {out.attrs['slip_left_out_per_seed']}) -> {args.out}")


def cmd_moduli(args, params) -> None:
    from .elastic import moduli_dataset
    from .netcdf import write_dataset
    from .states import check_distinct_piles

    ens = _read(args.ensemble, check_units)
    _require(ens, args.ensemble, ("stress_increment", "strain_increment"))
    piles = []
    for p in args.fields or []:
        ds = _read(p, check_units)
        _require(ds, p, ("stress_increment", "strain_increment"))
        piles.append(ds)
    check_distinct_piles([(args.ensemble, ens.attrs)] + [(p, ds.attrs) for p, ds in zip(args.fields or [], piles)],
                         "--fields")
    out = moduli_dataset(ens, piles, params)
    write_dataset(out, args.out, title=f"elastic moduli, protocol {out.attrs.get('protocol', '')}", params=params)
    _log(f"moduli -> {args.out}")


def cmd_voigt(args, params) -> None:
    import numpy as np

    from .elastic import moduli_dataset
    from .netcdf import write_json
    from .voigt import compare_with_fit

    out = {}
    for p in args.fields:
        ds = _read(p, check_units)
        _require(ds, p, ("voigt_bulk_modulus", "voigt_shear_modulus", "stress_increment", "strain_increment"))
        out[p] = compare_with_fit(ds, moduli_dataset(ds, [], params), {"x": args.core_x, "y": args.core_y})
        row = out[p]["average/m5"]
        print(f"{p}: Voigt/fit K {row['bulk_ratio']:.3g}, G {row['shear_ratio']:.3g} (median over {row['n']} core "
              f"RVEs; Voigt K {row['voigt_bulk_modulus']:.4g}, G {row['voigt_shear_modulus']:.4g}, fit K "
              f"{row['bulk_modulus']:.4g}, G {row['shear_modulus']:.4g} N/m)")
    for name in ("bulk_ratio", "shear_ratio"):
        v = [r["average/m5"][name] for r in out.values() if np.isfinite(r["average/m5"][name])]
        print(f"median over {len(v)} piles of their {name}: {np.median(v) if v else float('nan'):.3g}")
    if args.out:
        write_json({"core": {"x": args.core_x, "y": args.core_y}, "piles": out}, args.out)
        _log(f"voigt -> {args.out}")


def cmd_base_pressure(args, params) -> None:
    from .base_pressure import base_pressure_dataset, combine_base_pressure
    from .netcdf import write_dataset
    from .states import PROBE_STAGES, check_distinct_piles, check_identity, load_state

    if args.states:
        states = [load_state(p) for p in args.states]
        for state in states:
            check_identity(state.path, state.attrs, "--states", f"poured|relaxed|{PROBE_STAGES}",
                           "the state of a finished stage (poured, relaxed or a probe's)")
        check_distinct_piles([(s.path, s.attrs) for s in states], "--states")
        out = base_pressure_dataset(states, params)
    else:
        piles = [_read(p) for p in args.piles]
        for ds, p in zip(piles, args.piles):
            _require(ds, p, ("seed", "x_bounds", "normal_force_density_per_seed", "shear_force_density_per_seed",
                             "weight"))
        check_distinct_piles([(p, {"protocol": ds.attrs.get("protocol", ""), "seed": seed})
                              for p, ds in zip(args.piles, piles) for seed in ds["seed"].values], "--piles")
        out = combine_base_pressure(piles, list(args.piles), params)
    n = out.attrs["n_seeds"]
    write_dataset(out, args.out, title=f"forces on the support, protocol {out.attrs.get('protocol', '')}, "
                  f"{n} piles", params=params)
    _log(f"base pressure of {n} pile{'s' if n != 1 else ''} -> {args.out}")


def cmd_invariants(args, params) -> None:
    from .invariants import invariants_dataset
    from .netcdf import write_dataset

    ens = _read(args.ensemble, check_units)
    _require(ens, args.ensemble, ("stress_increment", "strain_increment", "depth"))
    out = invariants_dataset(ens, params)
    write_dataset(out, args.out, title=f"stress and strain invariants, protocol {out.attrs.get('protocol', '')}",
                  params=params)
    _log(f"invariants -> {args.out}")


def cmd_convergence(args, params) -> None:
    from .convergence import convergence_dataset
    from .netcdf import write_dataset
    from .states import check_same_particles

    relaxed, probes = _relaxed_and_probes(args.relaxed, {"reduced": args.reduced}, "--reduced")
    reduced = probes["reduced"]
    check_same_particles(relaxed, reduced)
    out = convergence_dataset(relaxed, reduced, params)
    write_dataset(out, args.out, title="RVE-size convergence", params=params)
    _log(f"convergence -> {args.out}")


#: The figures drawn at analysis.figures.heights, and the variable whose values show where each
#: input's pile is (a row of the grid without one draws nothing).
HEIGHT_FIGURES = {"vertical-strain": "strain_increment", "fabric": "fabric_trace",
                  "moduli": "bulk_modulus", "general": "explained_general"}


def check_heights(name: str, data: dict, inputs: dict, heights: list[float]) -> list[str]:
    """Refuse heights that miss the pile in every layer a figure would draw.

    Each height is drawn at the nearest row of the grid (as
    :mod:`analysis.figures` draws it); a row where the figure's variable (:data:`HEIGHT_FIGURES`) holds no finite
    value lies off the pile.

    Parameters
    ----------
    name : str
        The figure (``python -m analysis figure NAME``).
    data, inputs : dict
        The inputs by label: datasets and paths (one panel each; the first
        only for a figure of one protocol).
    heights : list of float
        ``analysis.figures.heights``, m.

    Returns
    -------
    list of str
        A line for each input where some heights miss the pile (left out of
        the figure).

    Raises
    ------
    InputError
        When every height misses the pile of an input (the figure would be
        empty), naming the setting, its value and the heights of the pile.
    """
    import numpy as np

    variable = HEIGHT_FIGURES[name]
    notes = []
    for lab, ds in data.items() if name in ("vertical-strain", "general") else list(data.items())[:1]:
        values = ds[variable]
        finite = np.isfinite(values).any(dim=[d for d in values.dims if d != "y"]).values
        on_pile = ds["y"].values[finite]
        where = (f"its {variable} has values at y = {on_pile.min():.4g}..{on_pile.max():.4g} m"
                 if on_pile.size else f"its {variable} has no value at all")
        missed = [h for h in heights if not finite[int(np.argmin(np.abs(ds["y"].values - h)))]]
        if len(missed) == len(heights):
            raise InputError(f"analysis.figures.heights = {list(heights)} m: every height misses the pile of "
                             f"{lab} ({inputs[lab]}), the figure {name} would be empty; {where}: give "
                             "heights within that range")
        if missed:
            notes.append(f"figure {name}: heights {missed} m miss the pile of {lab} ({where}), left out")
    return notes


def cmd_figure(args, params) -> None:
    from . import figures

    inputs = _labelled(args.inputs)
    data = {lab: _read(p, check_units) for lab, p in inputs.items()}  # fields' variables in convergence too
    first_lab, first = next(iter(data.items()))
    f = params["figures"]
    dpi = f["dpi"]
    name = args.name
    notes = []
    if name == "convergence":
        for lab, ds in data.items():
            _require(ds, inputs[lab], ("stress", "strain_increment", "n_particles"))
        figures.fig_convergence(list(data.values()), args.out, dpi)
    elif name == "vertical-strain":
        for lab, ds in data.items():
            _require(ds, inputs[lab], ("strain_increment",))
        notes = check_heights(name, data, inputs, f["heights"])
        figures.fig_vertical_strain(data, f["heights"], args.out, dpi)
    elif name == "fabric":
        _require(first, inputs[first_lab], ("fabric_trace", "fabric_orientation", "stress_orientation"))
        notes = check_heights(name, data, inputs, f["heights"])
        figures.fig_fabric(first, f["heights"], args.out, dpi, protocol=first_lab)
    elif name == "moduli":
        _require(first, inputs[first_lab], ("bulk_modulus", "E_av", "G_av"))
        notes = check_heights(name, data, inputs, f["heights"])
        figures.fig_moduli(first, f["heights"], args.out, dpi, protocol=first_lab)
    elif name == "invariants":
        _require(first, inputs[first_lab], ("trace_stress_increment", "differential_bulk_modulus"))
        figures.fig_invariants(first, args.out, dpi, protocol=first_lab)
    elif name == "base-pressure":
        for lab, ds in data.items():
            _require(ds, inputs[lab], ("normal_force_density", "shear_force_density"))
        figures.fig_base_pressure(data, args.out, dpi)
    elif name == "general":
        for lab, ds in data.items():
            _require(ds, inputs[lab], ("axis_deg", "reversibility", "explained_general"))
        notes = check_heights(name, data, inputs, f["heights"])
        figures.fig_general(data, f["heights"], args.out, dpi)
    for note in notes:
        _log(note)
    _log(f"figure {name} -> {', '.join(args.out)}")


# ------------------------------------------------------------------ parser
def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of ``python -m analysis``: every command with its help line, and the
    arguments of `command` (all of them when None is given: every module is then imported).

    A command's arguments are read only for the command that runs, so that ``--help``
    and a command start without importing the modules of the others (draw, film and the
    VTK export bring matplotlib, xarray and scipy)."""
    p = argparse.ArgumentParser(
        prog="python -m analysis",
        description="Micro-to-macro analysis of polygon piles (Roul, Schinner & Kassner 2010): RVE fields, "
                    "ensembles, elastic fits, invariants, base pressure, figures. Reads particle states through "
                    "docs/formats.md#state-files only.")
    p.add_argument("--version", action="version",
                   version=f"polypile analysis {__version__}, code digest {code_digest(Path(__file__).parent)} "
                           "(of analysis/*.py)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name, help_, func):
        sp = sub.add_parser(name, help=help_, description=help_)
        if command not in (None, name):          # its arguments are read only when it runs
            return argparse.ArgumentParser(add_help=False)
        sp.add_argument("--params", default="{}", help="the 'analysis' config section as JSON or YAML text, or @file "
                        "(defaults filled in; see analysis/params.py)")
        if name in MODULE_COMMANDS:
            module = importlib.import_module(f"analysis.{MODULE_COMMANDS[name]}")
            module.add_arguments(sp)
            func = getattr(module, func)
        sp.set_defaults(func=func)
        return sp

    add("params", "validate --params and print the effective parameters as JSON", cmd_params)
    sp = add("fields", "per-pile RVE fields (docs/formats.md#fields) and balance-law checks", cmd_fields)
    sp.add_argument("--relaxed", required=True, help="state file at full gravity")
    sp.add_argument("--reduced", help="state file at reduced gravity (without it: no stress increment, no strain)")
    sp.add_argument("--quantities", nargs="*",
                    choices=importlib.import_module("analysis.fields").QUANTITIES if command == "fields" else None,
                    help="optional quantities computed besides the stress (default: fabric, and strain when "
                         "--reduced is given; none listed: the stress only)")
    sp.add_argument("--out", required=True, help="fields netCDF to write")
    sp.add_argument("--checks", help="JSON file for the balance-law checks")
    sp = add("ensemble", "average per-pile fields over seeds (fields.nc with _sem)", cmd_ensemble)
    sp.add_argument("--fields", nargs="+", required=True, help="per-pile fields files")
    sp.add_argument("--out", required=True)
    sp = add("probes", "stress and strain increments of every probe stage of one pile (probe dimension)",
             cmd_probes)
    sp.add_argument("--relaxed", required=True)
    sp.add_argument("--probes", nargs="+", required=True, help="probe states as stage=path")
    sp.add_argument("--out", required=True)
    sp = add("general-fit", "general 2D elastic fit of the probe increments over piles, and reversibility",
             cmd_general_fit)
    sp.add_argument("--probes", nargs="+", required=True, help="per-pile probe increment files")
    sp.add_argument("--ensemble", help="the protocol's ensemble fields.nc (fabric and stress axes copied in)")
    sp.add_argument("--out", required=True)
    sp = add("moduli", "isotropic and cubic elastic fits (moduli.nc)", cmd_moduli)
    sp.add_argument("--ensemble", required=True, help="ensemble fields.nc")
    sp.add_argument("--fields", nargs="*", default=[], help="per-pile fields files (for the uncertainties)")
    sp.add_argument("--out", required=True)
    sp = add("voigt", "the Voigt K, G of each pile's RVEs against its own isotropic fit: ratios, median over the "
             "core RVEs (fit average, m = 5 printed; every fit and m in --out)", cmd_voigt)
    sp.add_argument("--fields", nargs="+", required=True, help="per-pile fields files with voigt_stiffness")
    sp.add_argument("--core-x", type=float, default=0.03, help="half width of the core, m (default 0.03)")
    sp.add_argument("--core-y", type=float, default=0.05, help="top of the core, m (default 0.05)")
    sp.add_argument("--out", help="JSON file of every fit's numbers")
    sp = add("base-pressure", "forces per unit length on the support (base_pressure.nc)", cmd_base_pressure)
    src = sp.add_mutually_exclusive_group(required=True)
    src.add_argument("--states", nargs="+", help="state files (one per seed)")
    src.add_argument("--piles", nargs="+", help="base_pressure.nc files to combine (e.g. one per pile)")
    sp.add_argument("--out", required=True)
    sp = add("invariants", "trace of stress vs trace of strain, bulk modulus vs depth (invariants.nc)",
             cmd_invariants)
    sp.add_argument("--ensemble", required=True)
    sp.add_argument("--out", required=True)
    sp = add("convergence", "stress and strain at fixed points against RVE size (Fig. 1 data)", cmd_convergence)
    sp.add_argument("--relaxed", required=True)
    sp.add_argument("--reduced", required=True)
    sp.add_argument("--out", required=True)
    add("draw", "picture of one particle state: polygons coloured by their Eq. 2 pressure, and the "
        "contact-force network (PNG/PDF/SVG by extension)", "cmd_draw")
    add("export", "one particle state as VTK files for ParaView: OUT.vtu (polygons with velocity, Eq. 2 "
        "pressure, coordination, ...) and OUT_contacts.vtu (the contact network with its forces); or a "
        "pour's frames as a ParaView time series: OUT.pvd and one polygon file per frame in OUT/",
        "cmd_export")
    add("film", "a film of a pour from its frames (python -m sim pour --frames): MP4, and optionally "
        "an HTML page holding it", "cmd_film")
    sp = add("run-times", "table (HTML) of the wall and CPU time and peak memory of simulation jobs, "
             "from their Snakemake benchmark files", cmd_run_times)
    sp.add_argument("--benchmarks", nargs="+", required=True,
                    help="benchmark files benchmarks/<rule>/<protocol>/<name>.tsv")
    sp.add_argument("--title", default="Run times of the simulation jobs")
    sp.add_argument("--out", required=True, help="the table (.html)")
    sp = add("figure", "draw one figure (PNG/PDF by extension)", cmd_figure)
    sp.add_argument("name", choices=["convergence", "vertical-strain", "fabric", "moduli", "invariants",
                                     "base-pressure", "general"])
    sp.add_argument("--inputs", nargs="+", required=True,
                    help="input netCDF files, optionally as label=path (label = protocol; default: folder name)")
    sp.add_argument("--out", nargs="+", required=True, help="output files, e.g. fig.png fig.pdf")
    p.commands = list(sub.choices)
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    commands = _commands()
    command = next((a for a in argv if a in commands), "")   # "": none, only the commands' list
    args = build_parser(command).parse_args(argv)
    from .params import parse_params
    from .command_files import check_paths

    try:
        check_paths(args)
        params = parse_params(args.params)
    except ParamError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        args.func(args, params)
    except (AnalysisError, OutputError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


def _commands() -> list[str]:
    """The names of the commands (a parser of no command's arguments imports nothing)."""
    return build_parser("").commands


if __name__ == "__main__":
    sys.exit(main())
