"""The workflow's tools, each a module here, run by one command line:
``python -m workflow.tools NAME [options]`` (``--help`` lists them; ``python -m
workflow.tools NAME --help`` gives a tool's options).

Some are run by rules of ``workflow/rules/reproduction.smk`` (the tables and
numbers of ``make reproduction``), some by hand (the progress line of ``make
run``, the parameter studies, the calibration of the sources), two both
(calibration, decision). Each module's docstring says what it makes.
"""

import ast
from pathlib import Path

FOLDER = Path(__file__).resolve().parent

#: The tools, by name: the modules of this package.
TOOLS = tuple(sorted(p.stem for p in FOLDER.glob("*.py") if not p.stem.startswith("_")))


def summary(name):
    """The first paragraph of the tool's docstring, on one line (read without importing it)."""
    doc = ast.get_docstring(ast.parse((FOLDER / f"{name}.py").read_text(encoding="utf-8"))) or ""
    return " ".join(doc.split("\n\n")[0].split())
