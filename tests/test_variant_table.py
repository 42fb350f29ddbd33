"""The side-by-side table of a full-size variant against the study
(workflow/tools/variant_table.py): the seeds it finds, the shape numbers it
reads against the records read here directly, and the paired difference,
which must vanish for a variant that holds copies of the study's piles."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.params import parse_params
from workflow.tools import variant_table

REPO = Path(__file__).resolve().parents[1]
TOOL = [sys.executable, "-m", "workflow.tools", "variant_table"]
STUDY = REPO / "docs" / "reproduction"


def test_flat_names_each_setting_by_its_dotted_path():
    assert variant_table.flat({"model": {"support_friction": 0.9, "friction": 0.7}, "threads": 1}) == \
        {"model.support_friction": 0.9, "model.friction": 0.7, "threads": 1}


def test_recorded_seeds_need_every_file(tmp_path):
    (tmp_path / "wedge").mkdir()
    for seed in (1, 2):
        for suffix in variant_table.NEEDED:
            (tmp_path / "wedge" / f"seed{seed}{suffix}").write_text("")
    (tmp_path / "wedge" / "seed2.base_pressure.nc").unlink()
    (tmp_path / "wedge" / "seed12.summary.json").write_text("")
    assert variant_table.recorded(tmp_path, "wedge") == [1]


@pytest.fixture(scope="module")
def copied_variant(tmp_path_factory):
    """A variant folder holding copies of two of the study's wedge piles and one layered pile."""
    folder = tmp_path_factory.mktemp("variant")
    for protocol, seeds in (("wedge", (2, 3)), ("layered", (1,))):
        (folder / protocol).mkdir()
        for s in seeds:
            for f in (STUDY / protocol).glob(f"seed{s}.*"):
                shutil.copy(f, folder / protocol / f.name)
    return folder


def test_shape_numbers_are_those_of_the_summaries(copied_variant):
    params = parse_params("{}")
    piles = variant_table.pile_set(copied_variant, ["wedge"], params)
    for seed, q in piles["wedge"].items():
        lines = [json.loads(s) for s in (STUDY / "wedge" / f"seed{seed}.summary.json").read_text().splitlines()
                 if s.strip()]
        rel = next(line for line in lines if line["stage"] == "relaxed")
        assert q["angle_deg"] == pytest.approx((rel["flank_left_deg"] + rel["flank_right_deg"]) / 2, rel=1e-12)
        assert q["height"] == rel["height"]
        tsv = (STUDY / "wedge" / f"seed{seed}.pour.tsv").read_text().splitlines()
        cpu = float(tsv[1].split("\t")[tsv[0].split("\t").index("cpu_time")])
        assert q["pour_cpu_min"] == pytest.approx(cpu / 60)


def test_copies_of_the_study_differ_from_it_by_nothing_when_paired(copied_variant, tmp_path):
    overlay = tmp_path / "copy.yaml"
    overlay.write_text("model:\n  support_friction: 0.9\nprotocols:\n  wedge:\n    seeds: [2, 3]\n")
    out = subprocess.run([*TOOL, "--study", str(STUDY), "--variant", str(copied_variant),
                          "--overlay", str(overlay)], capture_output=True, text=True, check=True).stdout
    assert out.startswith("# Variant copy: `model.support_friction` = 0.9, against the study")
    assert "variant wedge 2, 3; layered 1" in out
    row = next(line for line in out.splitlines() if line.startswith("| wedge | height (m) |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    # the study's mean over its wedge piles that have every file, worked here from the summaries
    heights = []
    for s in variant_table.recorded(STUDY, "wedge"):
        lines = [json.loads(x) for x in (STUDY / "wedge" / f"seed{s}.summary.json").read_text().splitlines()
                 if x.strip()]
        heights.append(next(line for line in lines if line["stage"] == "relaxed")["height"])
    assert cells[2].startswith(f"{np.mean(heights):.4g} ± ") and cells[2].endswith(f"({len(heights)})")
    assert cells[6] == "0 ± 0 (identical)"
    # one layered variant pile: its scatter is taken as the study's SD over piles
    lay = []
    for s in variant_table.recorded(STUDY, "layered"):
        lines = [json.loads(x) for x in (STUDY / "layered" / f"seed{s}.summary.json").read_text().splitlines()
                 if x.strip()]
        lay.append(next(line for line in lines if line["stage"] == "relaxed")["height"])
    row = next(line for line in out.splitlines() if line.startswith("| layered | height (m) |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    sd = np.std(lay, ddof=1)
    se = np.hypot(sd / np.sqrt(len(lay)), sd)
    d = lay[0] - np.mean(lay)  # the copy is the study's seed 1
    assert cells[4] == f"{d:+.3g} ± {se:.2g} ({d / se:+.1f}) †" and cells[6] == "n/a"


def test_the_paired_difference_is_the_mean_and_standard_error_of_the_per_seed_differences(copied_variant,
                                                                                            tmp_path):
    raised = tmp_path / "raised"
    shutil.copytree(copied_variant, raised)
    for seed, dh in ((2, 0.01), (3, 0.02)):
        f = raised / "wedge" / f"seed{seed}.summary.json"
        lines = [json.loads(s) for s in f.read_text().splitlines() if s.strip()]
        for line in lines:
            line["height"] += dh if line["stage"] == "relaxed" else 0.0
        f.write_text("".join(json.dumps(line) + "\n" for line in lines))
    params = parse_params("{}")
    study = variant_table.pile_set(STUDY, ["wedge"], params)
    variant = variant_table.pile_set(raised, ["wedge"], params)
    text = variant_table.side_by_side(study, variant, {"height": "height (m)"})
    row = next(line for line in text.splitlines() if line.startswith("| wedge | height (m) |"))
    # per-seed differences 0.01 and 0.02: mean 0.015, SD 0.00707, SE 0.005, z 3.0
    assert row.strip("|").split("|")[6].strip() == "+0.015 ± 0.005 (+3.0)"


def test_a_missing_folder_is_named(tmp_path):
    overlay = tmp_path / "v.yaml"
    overlay.write_text("model: {support_friction: 0.9}\n")
    res = subprocess.run([*TOOL, "--study", str(STUDY), "--variant", str(tmp_path / "nope"),
                          "--overlay", str(overlay)], capture_output=True, text=True)
    assert res.returncode != 0 and "--variant" in res.stderr and "no such folder" in res.stderr


def test_the_small_sample_note_gives_students_t_at_the_fewest_variant_piles():
    # Two-sided 5 % quantiles of Student's t, from tables: 1 degree of freedom 12.706, 2: 4.303.
    two = {"wedge": {1: {}, 2: {}}, "layered": {1: {}, 2: {}, 3: {}}}
    assert "With 2 variant piles" in variant_table.small_sample_note(two)
    assert "1 degree of freedom" in variant_table.small_sample_note(two)
    assert "beyond 12.7 " in variant_table.small_sample_note(two)
    three = {"wedge": {1: {}, 2: {}, 3: {}}, "layered": {1: {}}}  # a single pile borrows the study's scatter
    assert "beyond 4.3 " in variant_table.small_sample_note(three)
    assert variant_table.small_sample_note({"wedge": {1: {}}, "layered": {}}) == ""
    assert "guide" in variant_table.small_sample_note(three)
    # Four degrees of freedom: 2.776; from five piles on the z values are read against it, no longer a guide.
    five = {p: {s: {} for s in range(1, 6)} for p in ("wedge", "layered")}
    assert "beyond 2.78 " in variant_table.small_sample_note(five)
    assert "guide" not in variant_table.small_sample_note(five)


def test_the_rank_test_is_exact_mann_whitney():
    # Two piles below all eight others: 2 of the C(10, 2) = 45 equally likely rank sets are as extreme
    # (both lowest or both highest), so p = 2/45.
    assert variant_table.rank_p([0.0, 0.1], [1.0 + i for i in range(8)]) == f"{2 / 45:.2g}"
    # Interleaved sets: the lowest of four ranks each side, p = 1.
    assert variant_table.rank_p([1.0, 4.0], [2.0, 3.0]) == "1"
    assert variant_table.rank_p([], [1.0]) == "n/a"
