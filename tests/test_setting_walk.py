"""The walk of one setting through the code (docs/parameters.md, "How a
setting reaches the kernel") held against the code: every function a row
names is defined in the row's file, every piece of code it quotes is in
those functions, and the count of hops and files its text gives is the
table's. So an edit that moves a hop makes this test name the row to mend."""

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOC = (REPO / "docs" / "parameters.md").read_text(encoding="utf-8")
SECTION = DOC.split("## How a setting reaches the kernel", 1)[1]


def rows():
    """(number, file, functions cell, code cell) of each row of the walk's table."""
    found = []
    for line in SECTION.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0].isdigit():
            found.append((int(cells[0]), cells[1].strip("`"), cells[2], cells[3]))
    return found


def quoted(cell):
    """The pieces of code quoted in a cell (between backticks)."""
    return re.findall(r"`([^`]+)`", cell)


def python_source(path, name):
    """The source of function or method `name` (``Class.method``) of the Python file `path`."""
    text = path.read_text(encoding="utf-8")
    scope = ast.parse(text).body
    node = None
    for part in name.split("."):
        node = next((n for n in scope if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name == part),
                    None)
        assert node is not None, f"{path.relative_to(REPO)} defines no {name}"
        scope = node.body
    return ast.get_source_segment(text, node)


def rule_source(path, name):
    """The text of rule `name` of the Snakemake file `path`, up to the next rule."""
    text = path.read_text(encoding="utf-8")
    match = re.search(rf"^rule {name}:\n(.*?)(?=^rule |\Z)", text, re.S | re.M)
    assert match, f"{path.relative_to(REPO)} has no rule {name}"
    return match.group(1)


def row_source(path, functions):
    """The code of the functions a row names (the whole file for "(top level)")."""
    if functions.startswith("(top level)"):
        return path.read_text(encoding="utf-8")
    if functions.startswith("rule "):
        return rule_source(path, quoted(functions)[0])
    # a name's remark in brackets ("(its `step`)", "(from `Simulation.run`)") names no function of the row
    names = quoted(re.sub(r"\([^)]*\)", "", functions))
    assert names, functions
    return "\n".join(python_source(path, name) for name in names)


def normal(code):
    """Code with each run of white space one space, as the table writes it."""
    return re.sub(r"\s+", " ", code)


def test_the_walk_is_a_table_of_numbered_rows():
    assert [r[0] for r in rows()] == list(range(1, len(rows()) + 1))
    assert len(rows()) > 10


@pytest.mark.parametrize("row", rows(), ids=lambda r: f"{r[0]}-{r[1]}")
def test_each_row_names_functions_of_its_file_that_hold_its_code(row):
    number, file, functions, code = row
    path = REPO / file
    assert path.is_file(), f"row {number}: no file {file}"
    source = normal(row_source(path, functions))
    pieces = quoted(code)
    assert pieces, f"row {number} quotes no code"
    for piece in pieces:
        assert normal(piece) in source, f"row {number}: {piece!r} is not in {functions} of {file}"


def test_the_walk_ends_in_the_force_law_where_friction_caps_the_tangential_force():
    number, file, functions, code = rows()[-1]
    assert (file, quoted(functions)) == ("sim/contact_law.py", ["tangential_force"])
    assert "friction" in code


def test_the_text_counts_the_table_s_hops_and_files():
    table = rows()
    files = {r[1] for r in table}
    assert f"{len(table)} hops over {len(files)} files" in normal(SECTION)
