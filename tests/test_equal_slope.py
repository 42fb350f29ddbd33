"""The equal-slope decision's committed pages and records are what its tools make of them.

* the pick of the control (docs/reproduction/equal_slope/pick.md) is what
  ``decision pick`` prints from the committed pilot records, so the page rests
  on them and on the rule's code alone;
* every committed record of the decision ensemble is one of its registered
  piles, poured at the registration's commit or a later one
  (:func:`workflow.tools._records.check_registered`): the pre-registration is
  older than every pile it judges.
"""

from pathlib import Path

import pytest

from workflow.tools import decision_pages as decision
from workflow.tools._records import check_registered, read_records

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "reproduction"
PLANS = [(REPO / "config" / "decision_equal_slope.yaml", DOCS / "decision_equal_slope"),
         (REPO / "config" / "decision_equal_slope_3500.yaml", DOCS / "decision_equal_slope_3500")]


def test_the_pick_page_is_the_rule_read_from_the_committed_pilot():
    page = decision.pick(DOCS / "equal_slope" / "pilot2", REPO / "config" / "equal_slope_pilot2.yaml",
                         DOCS / "decision", "wedge funnel")
    assert page == (DOCS / "equal_slope" / "pick.md").read_text()


@pytest.mark.parametrize("plan, folder", PLANS, ids=lambda p: p.name)
def test_every_decision_record_was_poured_after_its_registration(plan, folder):
    records = read_records(folder) if any(folder.glob("*.json")) else {}
    check_registered(records, plan, replaces="stress_column")
