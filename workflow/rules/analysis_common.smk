# Settings and helpers of the analysis rules (workflow/rules/analysis.smk).

import json

ANALYSIS_CFG = config.get("analysis", {}) or {}
ANALYSIS_PARAMS = json.dumps(ANALYSIS_CFG, sort_keys=True)
ANALYSIS_MEM_MB = 2000
# Each figure and the output (config `outputs`) whose data it draws.
ANALYSIS_FIGURES = {"fig1_convergence": "strain", "fig2_vertical_strain": "strain", "fig3_fabric": "fabric",
                    "fig4_moduli": "fits", "fig5_invariants": "fits", "base_pressure": "fields"}
# The ensemble files of each output.
ANALYSIS_ENSEMBLE = {"fields": ("fields.nc", "base_pressure.nc"), "strain": ("convergence.nc",),
                     "fits": ("moduli.nc", "invariants.nc")}


def _analysis_setting(section, key, default):
    return (ANALYSIS_CFG.get(section) or {}).get(key, default)


def _analysis_protocol(key):
    """Protocol drawn in a single-protocol figure: the configured one, else the first of the study."""
    p = _analysis_setting("figures", key, "wedge")
    return p if p in PROTOCOLS else PROTOCOLS[0]


def _analysis_convergence_seed(protocol):
    s = _analysis_setting("convergence", "seed", None)
    return seeds(protocol)[0] if s is None else s


def _analysis_fields(wildcards):
    return expand("results/fields/{protocol}/seed{seed}.nc", protocol=wildcards.protocol,
                  seed=seeds(wildcards.protocol))


def analysis_targets():
    """The final outputs of the analysis that the scene asks for (for `rule all`)."""
    names = [name for output, files in ANALYSIS_ENSEMBLE.items() if wants(output) for name in files]
    targets = [f"results/ensemble/{p}/{name}" for p in PROTOCOLS for name in names]
    if wants("figures"):
        targets += [f"results/figures/{stem}.{ext}" for stem, output in ANALYSIS_FIGURES.items()
                    if wants(output) for ext in ("png", "pdf")]
    return targets


def _analysis_fields_reduced(wildcards):
    """The reduced state of a pile's fields: with a gravity probe only (the stress increment and strain)."""
    return f"results/piles/{wildcards.protocol}/seed{wildcards.seed}/reduced.nc" if has_probes() else []


def _analysis_reduced_option(wildcards, input):
    """The arguments `--reduced FILE` of `analysis fields` when the pile has a reduced state, else none."""
    return ["--reduced", input.reduced] if input.reduced else []


def _labelled(files, protocols):
    """The `--inputs` of a figure: one PROTOCOL=FILE argument per file."""
    return [f"{p}={f}" for p, f in zip(protocols, files)]
