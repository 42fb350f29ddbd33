# Settings and helpers of the analysis rules (workflow/rules/analysis.smk).

import json

from analysis.params import params_flow_text

ANALYSIS_CFG = config.get("analysis", {}) or {}
# One line of YAML flow text, keys sorted ({rve: {size: 0.08}, ...}): the
# analysis reads it like JSON, and the report shows it under "Job parameters"
# as it is (Snakemake shows the double quotes of JSON params backslash-escaped).
ANALYSIS_PARAMS = params_flow_text(ANALYSIS_CFG)
ANALYSIS_MEM_MB = 2000
# Each figure and the output (config `outputs`) whose data it draws.
ANALYSIS_FIGURES = {"fig1_convergence": "strain", "fig2_vertical_strain": "strain", "fig3_fabric": "fabric",
                    "fig4_moduli": "fits", "fig5_invariants": "fits", "base_pressure": "fields"}
# The ensemble files of each output.
ANALYSIS_ENSEMBLE = {"fields": ("fields.nc", "base_pressure.nc"), "fits": ("moduli.nc", "invariants.nc")}
# A pile's compact results, by kind: its file under {results}/fields/ and, under
# `committed`, under that folder (docs/reproduction/ as committed).
PILE_RESULTS = {"fields": ("{protocol}/seed{seed}.nc", "{protocol}/seed{seed}.fields.nc"),
                "checks": ("{protocol}/seed{seed}.checks.json", "{protocol}/seed{seed}.checks.json"),
                "base_pressure": ("{protocol}/seed{seed}.base_pressure.nc", "{protocol}/seed{seed}.base_pressure.nc"),
                "convergence": ("{protocol}/seed{seed}.convergence.nc", "{protocol}/seed{seed}.convergence.nc"),
                "summary": ("{protocol}/seed{seed}.summary.json", "{protocol}/seed{seed}.summary.json")}
# With the extra probes (probe.tilts, probe.restore) a pile also has the
# increments of every probe (rule analysis_probes), recorded with the rest.
if extra_probe_stages():
    PILE_RESULTS["probes"] = ("{protocol}/seed{seed}.probes.nc", "{protocol}/seed{seed}.probes.nc")
# Folder of committed per-pile results that the analysis reads instead of
# computing them from state files (config `committed`; None: compute them).
COMMITTED = REPO / config["committed"] if config["committed"] else None


def pile_result(protocol, seed, kind):
    """The file of one pile's compact result of `kind` (a key of PILE_RESULTS)."""
    computed, committed = PILE_RESULTS[kind]
    if COMMITTED is None:
        return results_path(f"fields/{computed.format(protocol=protocol, seed=seed)}")
    return str(COMMITTED / committed.format(protocol=protocol, seed=seed))


def analysis_seeds(protocol, kind="fields"):
    """The seeds whose `kind` result enters the ensembles: all seeds of the
    study, or under `committed` those of them whose file is there."""
    if COMMITTED is None:
        return seeds(protocol)
    found = recorded_seeds(protocol, kind)
    if not found:
        raise ValueError(
            f"committed = {config['committed']!r}: no pile of protocol {protocol} (seeds "
            f"{seeds(protocol)}) has its {kind} file there ({PILE_RESULTS[kind][1]}); commit one "
            "or leave the outputs that need it out"
        )
    return found


def recorded_seeds(protocol, kind):
    """The seeds of the study whose `kind` result is there (computed or committed)."""
    return [s for s in seeds(protocol) if os.path.exists(pile_result(protocol, s, kind))]


def general_fit_protocols():
    """The protocols of the general fit: none without the extra probes; all of
    the study, or under `committed` those with at least one pile's probes file
    there."""
    if not extra_probe_stages():
        return []
    if COMMITTED is None:
        return PROTOCOLS
    return [p for p in PROTOCOLS if recorded_seeds(p, "probes")]


def reported_general_protocols():
    """The protocols whose general fit is built and reported: those of
    general_fit_protocols() when the scene wants the fits, else none."""
    return general_fit_protocols() if wants("fits") else []


def reported_probes():
    """(protocol, probes file) of every pile whose extra probes enter the
    reported general fit."""
    return [(p, pile_result(p, s, "probes")) for p in reported_general_protocols()
            for s in analysis_seeds(p, "probes")]


def _analysis_setting(section, key, default):
    return (ANALYSIS_CFG.get(section) or {}).get(key, default)


def _analysis_protocol(key):
    """Protocol drawn in a single-protocol figure: the configured one, else the first of the study."""
    p = _analysis_setting("figures", key, "wedge")
    return p if p in PROTOCOLS else PROTOCOLS[0]


def _analysis_convergence_seeds(protocol):
    """The piles of Fig. 1: every pile of the protocol (analysis.convergence.seed null), else the one given."""
    s = _analysis_setting("convergence", "seed", None)
    return analysis_seeds(protocol, "convergence") if s is None else [s]


def _analysis_fields(wildcards):
    return [pile_result(wildcards.protocol, s, "fields") for s in analysis_seeds(wildcards.protocol)]


def _analysis_base_pressure_piles(wildcards):
    p = wildcards.protocol
    return [pile_result(p, s, "base_pressure") for s in analysis_seeds(p, "base_pressure")]


def _analysis_convergence_files(wildcards):
    """The convergence files of Fig. 1's piles (_analysis_convergence_seeds)."""
    p = _analysis_protocol("convergence_protocol")
    return [pile_result(p, s, "convergence") for s in _analysis_convergence_seeds(p)]


def analysis_targets():
    """The final outputs of the analysis that the scene asks for (for `rule all`)."""
    names = [name for output, files in ANALYSIS_ENSEMBLE.items() if wants(output) for name in files]
    targets = [results_path(f"ensemble/{p}/{name}") for p in PROTOCOLS for name in names]
    if wants("strain"):
        targets += _analysis_convergence_files(None)
    if wants("figures"):
        targets += [results_path(f"figures/{stem}.{ext}") for stem, output in ANALYSIS_FIGURES.items()
                    if wants(output) for ext in ("png", "pdf")]
    general = reported_general_protocols()
    if general:
        targets += [results_path(f"ensemble/{p}/general_moduli.nc") for p in general]
        if wants("figures"):
            targets += [results_path(f"figures/general_fit.{ext}") for ext in ("png", "pdf")]
    return targets


def _analysis_fields_reduced(wildcards):
    """The reduced state of a pile's fields: with a gravity probe only (the stress increment and strain)."""
    return pile(wildcards.protocol, wildcards.seed, "reduced") if has_probes() else []


def _analysis_reduced_option(wildcards, input):
    """The arguments `--reduced FILE` of `analysis fields` when the pile has a reduced state, else none."""
    return ["--reduced", input.reduced] if input.reduced else []


def _labelled(files, protocols):
    """The `--inputs` of a figure: one PROTOCOL=FILE argument per file."""
    return [f"{p}={f}" for p, f in zip(protocols, files)]
