"""The README's layout names every rule file, script and workflow module by its
file name, and every folder of the two packages, so that a newcomer finds each
one there."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def layout_block():
    text = (REPO / "README.md").read_text()
    return re.search(r"## Layout\n\n```\n(.*?)```", text, re.S).group(1)


def test_the_layout_names_every_rule_file_script_and_package_folder():
    block = layout_block()
    names = [p.name for p in sorted((REPO / "workflow" / "rules").glob("*.smk"))]
    names += [p.name for p in sorted((REPO / "workflow" / "scripts").glob("*.py"))]
    names += [p.name for p in sorted((REPO / "workflow").glob("*.py"))]
    folders = [f"{p.parent.relative_to(REPO).as_posix()}/" for package in ("sim", "analysis")
               for p in sorted((REPO / package).rglob("__init__.py"))]
    missing = [n for n in names if not re.search(rf"\b{re.escape(n)}\b", block)]
    missing += [f for f in folders if not re.search(rf"^{re.escape(f)} ", block, re.M)]
    assert missing == []
