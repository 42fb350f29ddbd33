# Sand piles of soft convex polygons: Roul, Schinner & Kassner,
# Granular Matter (2010). Thin entry point: configuration, the rule files (common.smk
# builds `study`, workflow/study.py, which validates it) and the report; see README.md
# for the stages and docs/formats.md for the files.

from snakemake.utils import min_version

import os
import sys

from snakemake.logging import logger

# workflow/ is the installed package of the rules' Python (pyproject.toml), read by name.
from workflow.reporting import (Freshness, check_report_path, configuration_files, piles_made, report_path,
                                report_words)

min_version("9.0")


# config/config.yaml is the default; a --configfile replaces it instead of being
# merged into it. --replace-workflow-config does that only in the main process:
# cluster jobs (the SLURM executor) get --configfiles but not that flag, and
# would merge the study's settings back in.
if not workflow.overwrite_configfiles:

    configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/pour.smk"
include: "workflow/rules/relax.smk"
include: "workflow/rules/probe.smk"
include: "workflow/rules/figures_piles.smk"
include: "workflow/rules/analysis.smk"
include: "workflow/rules/numerics.smk"
include: "workflow/rules/numerics_piles.smk"
include: "workflow/rules/reproduction.smk"


# The first paragraph of the report (workflow/report/workflow.rst) names the
# configuration files, the results folder and the piles there, the captions the
# piles of each protocol; a --report under results/ but outside that folder is refused.
CONFIGURATION = configuration_files(workflow.overwrite_configfiles, workflow.config_settings.config, study.repo)
check_report_path(report_path(sys.argv), study.paths.folder, CONFIGURATION)
config["_report"] = report_words(
    CONFIGURATION, study.paths.folder, piles_made(study.piles, study.analysis.analysis_seeds),
    Freshness(lambda: workflow.dag, logger.warning, logger.info, lambda: any(map(os.path.exists, SCENE_TARGETS)))
    if report_path(sys.argv) else "", config["protocols"])

# What the scene asks for (config `outputs`; by default everything: every pile
# stage, the picture of every relaxed pile, and the analysis), with the
# numerical checks' files when it asks for numerics.
SCENE_TARGETS = study.outputs.targets(study.analysis.targets(), list(rules.numerics.input) + study.numerics.targets())


rule all:
    input:
        SCENE_TARGETS,
    default_target: True
    localrule: True


rule piles:
    # The simulation part only: poured, relaxed and every gravity probe.
    input:
        study.piles.targets(),
    localrule: True


rule made:
    # What of `all` exists now: `make report` reports it, so that the report of
    # a study in progress shows its finished piles (or none, instead of failing
    # on a figure not yet drawn).
    input:
        [path for path in SCENE_TARGETS if os.path.exists(path)],
    localrule: True
