"""docs/model.md's module table and command line against the code (issue 46 item 4).

The table under "Where it lives" names one row per module of ``sim/``; a
module added without a row, a row left after its module went, or a command
of ``python -m sim`` missing from the ``sim/cli.py`` row fails here, as the
parameter tables fail test_settings_single_source when they drift from the
schema.
"""

import argparse
import re
from pathlib import Path

from sim import cli

REPO = Path(__file__).resolve().parents[1]
MODEL = (REPO / "docs" / "model.md").read_text()


def table_modules() -> list[str]:
    """The ``sim/NAME.py`` of every row of the module table, in order."""
    return re.findall(r"^\| `(sim/[a-z_]+\.py)` \|", MODEL, flags=re.M)


def test_every_module_of_sim_has_one_row_and_every_row_a_module():
    rows = table_modules()
    modules = sorted(f"sim/{p.name}" for p in (REPO / "sim").glob("*.py") if not p.name.startswith("__"))
    assert len(rows) == len(set(rows)), [r for r in rows if rows.count(r) > 1]
    assert sorted(rows) == modules, {"without a row": sorted(set(modules) - set(rows)),
                                     "row without a module": sorted(set(rows) - set(modules))}
    assert "| `sim/numerics/` |" in MODEL


def test_the_command_row_lists_the_commands_of_python_m_sim():
    row = re.search(r"^\| `sim/cli.py` \| `python -m sim \{([a-z,-]+)\}` \|", MODEL, flags=re.M)
    assert row, "docs/model.md: no row `sim/cli.py` | `python -m sim {...}`"
    sub = next(a for a in cli._parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert sorted(row.group(1).split(",")) == sorted(sub.choices)
