"""The parameter studies on medium piles (workflow/tools/setting_sweep.py):
the settings they lay over the study, the comparison table against numbers
worked by hand, and a bad setting refused before anything is poured."""

from pathlib import Path

import numpy as np
import pytest

from analysis.params import resolve_params

from workflow.tools import setting_sweep as sweep


def test_overlay_and_merge_change_only_the_swept_setting():
    assert sweep.overlay("pour.rate", 400.0) == {"pour": {"rate": 400.0}}
    base = {"pour": {"rate": 100.0, "n_particles": 3500}, "threads": 2}
    assert sweep.merged(base, sweep.overlay("pour.rate", 400.0)) == \
        {"pour": {"rate": 400.0, "n_particles": 3500}, "threads": 2}
    assert base["pour"]["rate"] == 100.0
    assert [sweep.label(v) for v in (100.0, 0.25, False, 3)] == ["100", "0.25", "False", "3"]


def test_table_gives_means_standard_errors_and_the_largest_gap():
    quantities = sweep.quantities(resolve_params({}))
    piles = {"wedge": {"1": [{q: v for q in quantities} for v in (1.0, 2.0, 3.0)],
                       "2": [{q: v for q in quantities} for v in (5.0, 6.0, 7.0)]}}
    text = sweep.table({"piles": piles}, ["1", "2"], quantities)
    # means 2 and 6, standard errors 1/sqrt(3) each: gap 4 / sqrt(2/3) = 4.9
    row = next(line for line in text.splitlines() if "angle of repose" in line)
    assert row == f"| wedge | angle of repose (deg) | 2 ± 0.58 | 6 ± 0.58 | {4 / np.sqrt(2 / 3):.1f} |"


@pytest.mark.parametrize("setting, value, words", [("pour.rate", -5, ["pour.rate", "-5", "minimum"]),
                                                    ("pour.rat", 100, ["rat", "rate"]),
                                                    ("physics.rotation", "maybe", ["physics.rotation", "boolean"])])
def test_a_bad_setting_is_refused_by_name_before_any_pile(setting, value, words):
    with pytest.raises(SystemExit) as err:
        sweep.check_values(setting, [100.0, value] if setting == "pour.rate" else [value])
    assert all(w in str(err.value) for w in words)


def test_same_run_names_a_run_under_the_runs_folder_or_an_absolute_one(tmp_path):
    assert sweep.same_run("0.02=friction/0.5", tmp_path) == (0.02, tmp_path / "friction" / "0.5")
    assert sweep.same_run(f"0={tmp_path}/friction/0.5", Path("/elsewhere")) == (0, tmp_path / "friction" / "0.5")
    with pytest.raises(SystemExit, match="expected VALUE=NAME/VALUE"):
        sweep.same_run("0.02", tmp_path)


def _benchmark(path, cpu):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"s\tcpu_time\n{2 * cpu}\t{cpu}\n")


@pytest.mark.parametrize("layout", ["results folder", "before the results folders"])
def test_the_piles_of_a_value_are_read_in_either_layout(tmp_path, layout):
    """A value's working directory holds its piles in the configuration's
    results folder (results/study/fields, results/study/benchmarks: issue 29,
    item 2), or, poured by an older clone (--from), in results/fields with
    benchmarks/ beside results/; both are read."""
    if layout == "results folder":
        fields, benchmarks = tmp_path / "results" / "study" / "fields", tmp_path / "results" / "study" / "benchmarks"
    else:
        fields, benchmarks = tmp_path / "results" / "fields", tmp_path / "benchmarks"
    (fields / "wedge").mkdir(parents=True)
    for rule, cpu in (("pour", 100.0), ("relax", 10.0)):
        _benchmark(benchmarks / rule / "wedge" / "seed1.tsv", cpu)
    _benchmark(benchmarks / "probe" / "wedge" / "seed1_reduced.tsv", 1.0)
    assert sweep.folders(tmp_path, "results/study") == (fields.parent, benchmarks)
    assert sweep.cpu_seconds(tmp_path, "wedge", 1) == 111.0
    assert np.isnan(sweep.cpu_seconds(tmp_path, "wedge", 2))
    assert sweep.results_setting(sweep.MEDIUM, {}) == "results/study"
