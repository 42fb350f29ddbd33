"""The README and the pages of docs/ stay usable: the guide's layout
(docs/guide.md) names every rule file, tool and workflow module by its file
name, and every folder of the two packages, and every file it names is there;
its table of configurations every file of config/, so that a newcomer finds
each one there; the README keeps the two commands on its first screen and
stays a landing page, well under its cap, as docs/performance.md stays short
(its measurements live in docs/performance/); the lists and numbers the pages
repeat from the tree (the SLURM test's checkpoint interval, the progress
line's intervals) match it; and every relative link of these pages points at
a file that exists and, with a #fragment, at a heading of that page."""

import re
from pathlib import Path
from urllib.parse import unquote

REPO = Path(__file__).resolve().parents[1]

README_MAX_LINES = 130
README_FIRST_SCREEN = 40
PERFORMANCE_MAX_LINES = 150
GUIDE = REPO / "docs" / "guide.md"


def layout_block():
    text = GUIDE.read_text(encoding="utf-8")
    return re.search(r"## The repository's layout\n\n```\n(.*?)```", text, re.S).group(1)


def _section(page, heading):
    """The text of a page's section `heading` (``## heading``) up to the next ``## ``."""
    text = page.read_text(encoding="utf-8")
    return re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## |\Z)", text, re.S | re.M).group(1)


def test_the_guide_lists_every_configuration_file_and_no_other():
    listed = set(re.findall(r"`(config/[\w/.-]+\.yaml)`", _section(GUIDE, "Configurations")))
    present = {p.relative_to(REPO).as_posix() for p in (REPO / "config").rglob("*.yaml")}
    assert {"missing": sorted(present - listed), "not there": sorted(listed - present)} == \
        {"missing": [], "not there": []}


def test_cluster_md_gives_the_slurm_tests_checkpoint_interval():
    from test_slurm import STUDY

    text = (REPO / "docs" / "cluster.md").read_text(encoding="utf-8")
    said = re.findall(r"checkpoint every ([\d.]+) s", _section(REPO / "docs" / "cluster.md",
                                                            "Tested against a real SLURM"))
    assert said == [f"{STUDY['pour']['checkpoint_interval']:g}"], text


def test_the_progress_lines_intervals_are_those_of_the_makefile_and_the_tool():
    """workflow.md and the README say "a minute after the start, then every 5
    minutes": the tool's first line (FIRST_LINE_S) and the Makefile's PROGRESS_EVERY."""
    from workflow.tools.study_progress import FIRST_LINE_S

    every = int(re.search(r"^PROGRESS_EVERY := (\d+)$", (REPO / "Makefile").read_text(), re.M).group(1))
    assert (FIRST_LINE_S, every) == (60, 300)
    workflow = " ".join((REPO / "docs" / "workflow.md").read_text(encoding="utf-8").split())
    readme = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    assert "prints one line a minute after it starts, then every 5 minutes" in workflow
    assert "comes a minute after the start, then every 5 minutes" in readme


def test_the_layout_names_every_rule_file_tool_and_package_folder():
    block = layout_block()
    names = [p.name for p in sorted((REPO / "workflow" / "rules").glob("*.smk"))]
    names += [p.name for p in sorted((REPO / "workflow" / "tools").glob("*.py"))]
    names += [p.name for p in sorted((REPO / "workflow").glob("*.py"))]
    folders = [f"{p.parent.relative_to(REPO).as_posix()}/" for package in ("sim", "analysis")
               for p in sorted((REPO / package).rglob("__init__.py"))]
    missing = [n for n in names if not re.search(rf"\b{re.escape(n)}\b", block)]
    missing += [f for f in folders if not re.search(rf"^{re.escape(f)} ", block, re.M)]
    assert missing == []


def test_every_file_the_layout_names_is_there():
    """Each file or folder the layout names (``study.py``, ``docs/run_times.md``, ``slurm/``)
    is in the tree, under its line's folder (the first column; ``workflow/*.py`` is
    ``workflow/``) or, named with its folder, under the repository; but the folders of
    results/, which the workflow makes."""
    missing, folder = [], None
    for line in layout_block().splitlines():
        first = re.match(r"(\S+) {2,}", line)
        folder = first.group(1).removesuffix("*.py") if first else folder
        if folder == "results/":
            continue
        for name in re.findall(r"(?<![\w./-])([\w.-]+(?:/[\w.-]+)*(?:\.(?:py|smk|yaml|json|md|txt)\b|/))",
                               line[first.end() if first else 0:]):
            if not any((REPO / base / name).exists() for base in (folder, "")):
                missing.append(f"{folder} {name}")
    assert missing == []


def test_the_readme_is_a_short_landing_page_that_starts_with_the_commands():
    lines = (REPO / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"
    first_screen = "\n".join(lines[:README_FIRST_SCREEN])
    for command in ("make run", "make test"):
        assert re.search(rf"^{command}\b", first_screen, re.M), \
            f"`{command}` is not a command line within the README's first {README_FIRST_SCREEN} lines"


def test_the_performance_page_is_short():
    lines = (REPO / "docs" / "performance.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= PERFORMANCE_MAX_LINES, f"docs/performance.md has {len(lines)} lines"


def _without_fences(text):
    """The text without fenced code blocks (a `# comment` there is no heading)."""
    return re.sub(r"^(```|~~~).*?^\1[ \t]*$", "", text, flags=re.S | re.M)


def _without_code(text):
    """The text without fenced code blocks and inline code, where `](...)` is no link."""
    return re.sub(r"`[^`\n]*`", "", _without_fences(text))


def anchors(page):
    """The fragments GitHub gives the headings of a Markdown page (lower case, punctuation
    and code marks dropped, spaces to hyphens, -1, -2, ... for repeats), and <a id/name>."""
    text = _without_fences(page.read_text(encoding="utf-8"))
    found, seen = set(), {}
    for heading in re.findall(r"^#{1,6}[ \t]+(.+?)[ \t#]*$", text, re.M):
        heading = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link: its text
        slug = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        found.add(slug if count == 0 else f"{slug}-{count}")
    found.update(re.findall(r"<a\s+(?:id|name)=\"([^\"]+)\"", text))
    return found


def _pages():
    docs = REPO / "docs"
    return [REPO / "README.md", *sorted(docs.glob("*.md")), *sorted((docs / "performance").glob("*.md"))]


def test_every_relative_link_points_at_an_existing_file_and_heading():
    broken = []
    for page in _pages():
        for target in re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", _without_code(page.read_text(encoding="utf-8"))):
            if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", target):  # http:, https:, mailto:
                continue
            path, _, fragment = target.partition("#")
            linked = (page.parent / unquote(path)).resolve() if path else page
            where = f"{page.relative_to(REPO)}: {target}"
            if not linked.exists():
                broken.append(f"{where} (no such file)")
            elif fragment and linked.suffix == ".md" and unquote(fragment) not in anchors(linked):
                broken.append(f"{where} (no such heading)")
    assert broken == []


def test_the_link_check_finds_what_it_must():
    """The anchors and links of the check above, on known cases: a heading with code and
    punctuation, a repeated heading, and links in and out of code."""
    page = REPO / "docs" / "performance" / "log-2026-12.md"
    found = anchors(page)
    assert "against-lammps-in-the-same-run---peer-lammps" in found
    assert "witnesses-of-one-byte-where-the-pair-passs-time-goes" in found
    assert "issue-26s-targets-against-what-is-measured" in found
    assert "no-such-heading" not in found
    assert re.findall(r"\]\(([^)\s]+)\)", _without_code("a `[x](nowhere.md)` and [y](here.md)\n"
                                                         "```\n[z](code.md)\n```\n")) == ["here.md"]


def test_the_pages_say_what_a_thing_is_for_not_which_issue_asked_for_it():
    """A reader has no access to the project's tracker: the README and the pages of
    docs/ cite no issue of ours by number (another project's, e.g. Numba's, may)."""
    cited = [f"{page.relative_to(REPO)}: {m.group(0)}"
             for page in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
             for m in re.finditer(r"(\w+ )?\bissues? #?\d+", _without_code(page.read_text(encoding="utf-8")),
                                  re.I)
             if not (m.group(1) or "").strip().lower() in ("numba",)]
    assert cited == []
