"""The equal-slope decision's committed pages and records are what its tools make of them.

* the pick of the control (docs/reproduction/equal_slope/pick.md) is what
  ``decision pick`` prints from the committed pilot records, so the page rests
  on them and on the rule's code alone;
* every committed record of the decision ensemble is one of its registered
  piles, poured at the registration's commit or a later one
  (:func:`workflow.tools._records.check_registered`): the pre-registration is
  older than every pile it judges.
"""

import re
from pathlib import Path

import pytest

from workflow.tools import decision_pages as decision
from workflow.tools._records import check_registered, read_records

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "reproduction"
PLANS = [(REPO / "config" / "decision_equal_slope.yaml", DOCS / "decision_equal_slope"),
         (REPO / "config" / "decision_equal_slope_3500.yaml", DOCS / "decision_equal_slope_3500"),
         (REPO / "config" / "step_error.yaml", DOCS / "step_error"),
         (REPO / "config" / "step_error_limit.yaml", DOCS / "step_error_limit")]


def test_the_pick_page_is_the_rule_read_from_the_committed_pilot():
    page = decision.pick(DOCS / "equal_slope" / "pilot2", REPO / "config" / "equal_slope_pilot2.yaml",
                         DOCS / "decision", "wedge funnel")
    assert page == (DOCS / "equal_slope" / "pick.md").read_text()


@pytest.mark.parametrize("plan, folder", PLANS, ids=lambda p: p.name)
def test_every_decision_record_was_poured_after_its_registration(plan, folder):
    records = read_records(folder) if any(folder.glob("*.json")) else {}
    check_registered(records, plan, replaces="stress_column")


def test_the_verdict_page_is_the_tools_reading_of_the_committed_records():
    """docs/reproduction/decision_equal_slope.md is what ``decision verdict`` prints now."""
    plan = REPO / "config" / "decision_equal_slope.yaml"
    page = decision.verdict(DOCS / "decision_equal_slope", plan)
    assert page == (DOCS / "decision_equal_slope.md").read_text()


def test_the_verdict_reports_every_secondary_the_registration_names():
    """Each statistic in the registration's "Secondary" section is a row of the verdict's
    secondary table, or (D1 on arm plus angle) the shape check's sentence."""
    text = (DOCS / "preregistration_equal_slope.md").read_text()
    section = text.split("## Secondary")[1].split("**At the paper's size**")[0]
    named = [t.removeprefix("analysis.decision.") for t in re.findall(r"`([^`]+)`", section)]
    page = (DOCS / "decision_equal_slope.md").read_text()
    secondary = page.split("Secondary (own Holm family")[1]
    assert len(named) == 9
    for name in named:
        if name == "shape_check":
            assert "Fitted on arm plus angle" in page
        else:
            assert f"\n| {name} |" in secondary, name
