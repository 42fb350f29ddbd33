"""A grid or a convergence point off the pile is refused by name (issue 28): before, the
fields came out NaN everywhere and the command exited 0."""

import numpy as np
import pytest
from synthetic_states import as_state, displaced, step_pyramid

from analysis.convergence import convergence_dataset
from analysis.errors import InputError
from analysis.fields import compute_fields
from analysis.params import resolve_params

A = 0.006  # a heap of squares 101 wide: x within ±0.3 m, y up to about 0.18 m


@pytest.fixture(scope="module")
def heap():
    s = step_pyramid(101, A, slope=0.6)
    r = displaced(s, np.column_stack([s["x"], s["y"]]) @ np.diag([1e-5, 2e-4]), 0.9, 0.9 * 9.81)
    return as_state(s, "relaxed.nc"), as_state(r, "reduced.nc")


def test_a_grid_beside_the_pile_is_refused_before_any_rve(heap):
    relaxed, reduced = heap
    params = resolve_params({"grid": {"x_min": 2.0, "x_max": 3.0, "y_min": 0.015, "y_max": 0.1, "spacing": 0.1}})
    with pytest.raises(InputError, match=r"analysis.grid lies off the pile.*grid centres x 2\.\.3 m.*"
                                         r"the pile's particles x -0\.3\.\.0\.3 m"):
        compute_fields(relaxed, reduced, params)


def test_a_grid_whose_rves_reach_the_pile_s_edge_but_hold_too_few_particles_is_refused(heap):
    relaxed, reduced = heap
    # centres 4 cm beside the outermost column: each RVE of 10 cm reaches one or two columns of the
    # heap's thin foot, far fewer than the 30 particles it needs
    params = resolve_params({"grid": {"x_min": 0.34, "x_max": 0.34, "y_min": 0.003, "y_max": 0.003,
                                      "spacing": 0.01}, "rve": {"size": 0.1, "min_particles": 30}})
    with pytest.raises(InputError, match="none of the 1 RVEs holds analysis.rve.min_particles = 30 particles"):
        compute_fields(relaxed, reduced, params)


def test_a_grid_on_the_pile_still_computes(heap):
    relaxed, reduced = heap
    params = resolve_params({"grid": {"x_min": -0.06, "x_max": 0.06, "y_min": 0.03, "y_max": 0.06,
                                      "spacing": 0.03}})
    ds = compute_fields(relaxed, reduced, params)
    assert int((ds["mask_reason"] == 0).sum()) == ds["mask_reason"].size


def test_a_convergence_point_off_the_pile_is_named(heap):
    relaxed, reduced = heap
    params = resolve_params({"convergence": {"points": [[0.0, 0.045], [1.5, 0.045]], "sizes": [0.03, 0.06]}})
    with pytest.raises(InputError, match=r"analysis.convergence.points\[1\] = \(1.5, 0.045\) m lies off the pile"):
        convergence_dataset(relaxed, reduced, params)


@pytest.fixture(scope="module")
def fields_file(heap, tmp_path_factory):
    """The heap's fields on a grid of rows 3, 6, ..., 30 cm: the heap is about
    18 cm high, so the rows from 21 cm up hold no RVE."""
    relaxed, reduced = heap
    params = resolve_params({"grid": {"x_min": -0.06, "x_max": 0.06, "y_min": 0.03, "y_max": 0.3,
                                      "spacing": 0.03}})
    ds = compute_fields(relaxed, reduced, params, ["strain", "fabric"])
    path = tmp_path_factory.mktemp("fields") / "fields.nc"
    ds.to_netcdf(path)
    on_pile = ds["y"].values[np.isfinite(ds["strain_increment"]).any(dim=["x", "i", "j"]).values]
    return path, on_pile


@pytest.mark.parametrize("figure", ["vertical-strain", "fabric"])
def test_figure_heights_that_all_miss_the_pile_are_refused(fields_file, tmp_path, capsys, figure):
    """Heights above the heap (nearest rows 27 and 30 cm, no RVE there) would
    draw empty axes: refused in one line naming the setting, its value and
    the heights the pile's values span, and nothing is written."""
    from analysis.__main__ import main

    path, on_pile = fields_file
    assert on_pile.min() == pytest.approx(0.03) and 0.15 <= on_pile.max() < 0.21  # the heap's top, 18 cm
    out = tmp_path / "fig.png"
    assert main(["figure", figure, "--inputs", f"wedge={path}", "--out", str(out),
                 "--params", "{figures: {heights: [0.27, 0.33]}}"]) == 1
    err = capsys.readouterr().err
    assert err == (f"error: analysis.figures.heights = [0.27, 0.33] m: every height misses the pile of wedge "
                   f"({path}), the figure {figure} would be empty; its "
                   f"{'strain_increment' if figure == 'vertical-strain' else 'fabric_trace'} has values at "
                   f"y = {on_pile.min():.4g}..{on_pile.max():.4g} m: give heights within that range\n")
    assert not out.exists()


def test_figure_heights_partly_off_the_pile_are_named_and_left_out(fields_file, tmp_path, capsys):
    from analysis.__main__ import main

    path, on_pile = fields_file
    out = tmp_path / "fig.png"
    assert main(["figure", "vertical-strain", "--inputs", f"wedge={path}", "--out", str(out),
                 "--params", "{figures: {heights: [0.06, 0.27]}}"]) == 0
    assert out.exists()
    assert (f"figure vertical-strain: heights [0.27] m miss the pile of wedge (its strain_increment has "
            f"values at y = {on_pile.min():.4g}..{on_pile.max():.4g} m), left out") in capsys.readouterr().err
