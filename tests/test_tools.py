"""The workflow's tools behind one command line (issue 46, item 1):
``python -m workflow.tools NAME`` runs each module of workflow/tools/, ``--help``
lists them all, the rules and the Makefile call them so, and workflow/scripts/
(once a mix of rule targets and hand-run tools) is gone."""

import re
import subprocess
import sys
from pathlib import Path

from workflow.tools import COMMANDS, TOOLS, module

REPO = Path(__file__).resolve().parents[1]
TOOL = [sys.executable, "-m", "workflow.tools"]


def test_help_lists_every_tool_with_what_it_makes():
    out = subprocess.run([*TOOL, "--help"], capture_output=True, text=True, check=True).stdout
    modules = sorted(p.stem for p in (REPO / "workflow" / "tools").glob("*.py") if not p.stem.startswith("_"))
    assert sorted(module(name) for name in TOOLS) == modules
    assert module("decision") == "decision_pages" and "decision" in TOOLS and "decision_pages" not in TOOLS
    for name in TOOLS:
        assert re.search(rf"^  {name} +\S", out, re.M), name


def test_a_tool_runs_by_name_and_an_unknown_name_is_refused():
    proc = subprocess.run([*TOOL, "settings_table", "--check", str(REPO / "docs" / "parameters.md")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run([*TOOL, "no_such_tool"], capture_output=True, text=True)
    assert proc.returncode == 2 and "unknown tool 'no_such_tool'" in proc.stderr


def test_rules_and_makefile_call_the_tools_by_the_command_line():
    assert not list((REPO / "workflow" / "scripts").glob("*.py"))
    rules = (REPO / "workflow" / "rules" / "reproduction.smk").read_text()
    for tool in re.findall(r'tool="workflow/tools/(\w+)\.py"', rules):
        assert f"-m workflow.tools {COMMANDS.get(tool, tool)} " in rules, tool
    assert "$(PY) -m workflow.tools study_progress" in (REPO / "Makefile").read_text()
