"""Validated workflow configurations for the tests of the workflow's modules
(workflow/piles.py, scene.py, analysis_inputs.py, ...): a configuration file of
config/ with overrides laid over it as Snakemake merges a further
--configfile, validated with its defaults filled in as the Snakefile does."""

from pathlib import Path

import yaml

from workflow.validation import merge_configs, validate_config

REPO = Path(__file__).resolve().parents[1]


def configuration(*layers, base="config/smoke.yaml"):
    """The validated configuration of `base` with `layers` (dicts, or paths
    relative to the repository) merged over it in order."""
    config = yaml.safe_load((REPO / base).read_text())
    for layer in layers:
        if not isinstance(layer, dict):
            layer = yaml.safe_load((REPO / layer).read_text())
        config = merge_configs(config, layer)
    validate_config(config)
    return config
