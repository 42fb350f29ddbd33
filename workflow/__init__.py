"""The workflow's Python: the configuration's checks, the piles' paths and targets, the
commands, resources and reporting that the rules of ``workflow/rules/`` read by name.

An installed package (``pyproject.toml``), imported as ``workflow`` by the
Snakefile, the rule files and the tools of ``workflow/tools/`` (``python -m workflow.tools``).
"""
