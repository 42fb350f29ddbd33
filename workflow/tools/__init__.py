"""The workflow's tools, each a module here, run by one command line:
``python -m workflow.tools NAME [options]`` (``--help`` lists them; ``python -m
workflow.tools NAME --help`` gives a tool's options).

Some are run by rules of ``workflow/rules/reproduction.smk`` (the tables and
numbers of ``make reproduction``), some by hand (the progress line of ``make
run``, the parameter studies, the calibration of the sources), two both
(calibration, decision). Each module's docstring says what it makes; a tool's
module bears its command's name, but for :data:`COMMANDS`.
"""

import ast
from pathlib import Path

FOLDER = Path(__file__).resolve().parent

#: The modules whose command is another name, ``{module: command}``: ``decision`` writes the
#: decision's pages (decision_pages.py) by the rules of analysis/decision.py.
COMMANDS = {"decision_pages": "decision"}

#: The tools, by command: one a module of this package.
TOOLS = tuple(sorted(COMMANDS.get(p.stem, p.stem) for p in FOLDER.glob("*.py") if not p.stem.startswith("_")))


def module(name):
    """The module (its name in this package) of the tool whose command is `name`."""
    return next((stem for stem, command in COMMANDS.items() if command == name), name)


def summary(name):
    """The first paragraph of the tool's docstring, on one line (read without importing it)."""
    doc = ast.get_docstring(ast.parse((FOLDER / f"{module(name)}.py").read_text(encoding="utf-8"))) or ""
    return " ".join(doc.split("\n\n")[0].split())
