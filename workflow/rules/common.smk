# The one name the rule files read: `study` (workflow/study.py), the validated
# configuration and its piles, stages, paths, job settings, resources, outputs,
# analysis, numerics, command lines and code digests; every rule file calls
# study.<part>.<method>(...). Building it runs every check of the
# configuration before any job; a refusal is the user's: its lines, not a traceback.
# No rules and no functions in this file (snakemake --lint wants them apart).

import sys

from snakemake.logging import logger

from workflow.study import Study

try:
    study = Study.of_workflow(workflow, config, logger.warning)
except ValueError as exc:
    sys.exit(str(exc))


wildcard_constraints:
    protocol="wedge|layered",
    seed=r"\d+",
