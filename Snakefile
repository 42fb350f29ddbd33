# Sand piles of soft convex polygons: Roul, Schinner & Kassner,
# Granular Matter (2010). Thin entry point: configuration, its validation and
# the rule files; see README.md for the stages and docs/formats.md for the files.

import sys

from snakemake.utils import min_version

sys.path.insert(0, workflow.basedir)  # for workflow/validation.py
from workflow.validation import check_config_files, validate_config

min_version("9.0")


# config/config.yaml is the default; a --configfile replaces it instead of being
# merged into it. --replace-workflow-config does that only in the main process:
# cluster jobs (the SLURM executor) get --configfiles but not that flag, and
# would merge the study's settings back in.
if not workflow.overwrite_configfiles:

    configfile: "config/config.yaml"


# The --configfile files read again strictly: a repeated key, which YAML
# reads as its last value, and an empty section laid over another file, which
# the merge ignores, are refused naming the file and line.
check_config_files(workflow.overwrite_configfiles)


# The one validator (schemas, finite numbers, integers, the simulator's and the
# analysis' own checks); it fills in every default of the schemas, so the
# rules see a complete config.
validate_config(config)


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/scene.smk"
include: "workflow/rules/pour.smk"
include: "workflow/rules/relax.smk"
include: "workflow/rules/probe.smk"
include: "workflow/rules/figures_piles.smk"
include: "workflow/rules/analysis_common.smk"
include: "workflow/rules/analysis.smk"
include: "workflow/rules/numerics.smk"
include: "workflow/rules/numerics_piles.smk"
include: "workflow/rules/reproduction.smk"


# The first paragraph of the report (workflow/report/workflow.rst) names the
# configuration files, the results folder and the piles there; a --report
# under results/ but outside that folder is refused.
_check_report_path()
config["_report"] = report_description()


rule all:
    # What the scene asks for (config `outputs`; by default everything: every
    # pile stage, the picture of every relaxed pile, and the analysis).
    input:
        scene_targets(),
    default_target: True
    localrule: True


rule piles:
    # The simulation part only: poured, relaxed and every gravity probe.
    input:
        pile_targets(),
    localrule: True


rule made:
    # What of `all` exists now (made_targets()): `make report` reports it, so
    # that the report of a study in progress shows its finished piles.
    input:
        made_targets(),
    localrule: True
