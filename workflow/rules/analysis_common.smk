# Settings and helpers of the analysis rules (workflow/rules/analysis.smk).

import json

ANALYSIS_CFG = config.get("analysis", {}) or {}
ANALYSIS_PARAMS = json.dumps(ANALYSIS_CFG, sort_keys=True)
ANALYSIS_MEM_MB = 2000
ANALYSIS_FIGURES = ("fig1_convergence", "fig2_vertical_strain", "fig3_fabric", "fig4_moduli",
                    "fig5_invariants", "base_pressure")


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
    """Every final output of the analysis (for `rule all`)."""
    targets = []
    for p in PROTOCOLS:
        targets += [f"results/ensemble/{p}/{name}" for name in
                    ("fields.nc", "moduli.nc", "base_pressure.nc", "invariants.nc", "convergence.nc")]
    targets += [f"results/figures/{stem}.{ext}" for stem in ANALYSIS_FIGURES for ext in ("png", "pdf")]
    return targets


def _labelled(files, protocols):
    return " ".join(f"{p}={f}" for p, f in zip(protocols, files))
