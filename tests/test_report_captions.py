"""Every page of the report (workflow/report/*.rst) renders for any non-empty
set of protocols (issue 47 item 8): run_times.rst read
``protocols["layered"]``, so the report of a wedge-only configuration (the
shipped config/numerics_piles*.yaml) failed. Each page is rendered here as
``snakemake --report`` renders it (Jinja with the same options, then
docutils), with every name it uses required to exist, under the
configurations of each set of protocols."""

from pathlib import Path
from types import SimpleNamespace

import pytest
from docutils.core import publish_parts
from jinja2 import Environment, StrictUndefined

from workflow_config import REPO, configuration
from workflow.reporting import piles_per_protocol, report_words

PAGES = sorted((REPO / "workflow" / "report").rglob("*.rst"))

#: Configurations of each set of protocols: the shipped wedge-only one, one
#: of the layered sequence alone, and the smoke scene with both.
CONFIGURATIONS = {
    "wedge only (config/numerics_piles.yaml)": lambda: configuration(base="config/numerics_piles.yaml"),
    "layered only": lambda: configuration({"protocols": {"layered": {"seeds": [7]}}},
                                          base="config/numerics_piles.yaml"),
    "both (config/smoke.yaml)": lambda: configuration(),
}


def render(page: Path, config: dict) -> str:
    """The HTML of `page` as the report shows it, under `config` (with ``_report`` as the Snakefile sets it)."""
    config = dict(config, _report=report_words(["config/x.yaml"], config["results"],
                                                "0 of 2 piles made so far", "", config["protocols"]))
    protocol, spec = next(iter(config["protocols"].items()))
    wildcards = SimpleNamespace(protocol=protocol, seed=spec["seeds"][0], stage="relaxed")
    env = Environment(trim_blocks=True, lstrip_blocks=True, undefined=StrictUndefined)
    text = env.from_string(page.read_text()).render(
        snakemake=SimpleNamespace(config=config, wildcards=wildcards), categories={}, files=[])
    return publish_parts(text, writer="html", settings_overrides={"halt_level": 2})["body"]


def test_the_report_has_its_pages():
    assert {p.name for p in PAGES} >= {"run_times.rst", "workflow.rst", "film.rst", "fig2_vertical_strain.rst"}


@pytest.mark.parametrize("name", list(CONFIGURATIONS))
@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(REPO / "workflow" / "report")) for p in PAGES])
def test_every_page_renders_for_the_protocols_of_the_configuration(page, name):
    config = CONFIGURATIONS[name]()
    html = " ".join(render(page, config).split())
    for protocol in {"wedge", "layered"} - set(config["protocols"]):
        assert f"0 {protocol}" not in html and f"{protocol} piles" not in html, (page.name, html)
    if '_report"]["protocols"]' in page.read_text():
        assert piles_per_protocol(config["protocols"]) in html, (page.name, html)


def test_the_piles_per_protocol_in_words():
    assert piles_per_protocol({"wedge": {"seeds": [1, 2, 3, 4, 5, 6]}}) == "6 wedge"
    assert piles_per_protocol({"wedge": {"seeds": [1, 2]}, "layered": {"seeds": [3, 4]}}) == \
        "2 wedge and 2 layered"
