"""Validated workflow configurations for the tests of the workflow's modules
(workflow/piles.py, outputs.py, analysis_inputs.py, ...): a configuration file of
config/ with overrides laid over it as Snakemake merges a further
--configfile, validated with its defaults filled in as the Snakefile does."""

from pathlib import Path

import yaml

from workflow.validation import merge_configs, validate_config

REPO = Path(__file__).resolve().parents[1]


def configuration(*layers, base="config/smoke.yaml"):
    """The validated configuration of `base` with `layers` (dicts, or paths
    relative to the repository) merged over it in order."""
    return _validated(layers, base)[0]


def simulator(*layers, base="config/smoke.yaml"):
    """The simulator's sections (sim.config.SimConfig) of :func:`configuration`,
    as the workflow keeps them (workflow.study.Study.sim)."""
    return _validated(layers, base)[1]


def _validated(layers, base):
    """The configuration of :func:`configuration` and its SimConfig."""
    config = yaml.safe_load((REPO / base).read_text())
    for layer in layers:
        if not isinstance(layer, dict):
            layer = yaml.safe_load((REPO / layer).read_text())
        config = merge_configs(config, layer)
    return config, validate_config(config)
