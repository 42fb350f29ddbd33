"""The growth record of a pour (analysis/growth.py) on heaps whose answer is known by construction.

A heap of discs stacked in columns under a triangle of known slope gives
back that slope; a film in which chosen particles move at chosen frames
gives back those counts, split into landing particles and the pile's own.
"""

import math

import numpy as np
import pytest
import xarray as xr

from analysis.growth import FLOW_MIN, OLD, flank_angle, growth, growth_statistics, landing_displacement

D = 0.007          # bin width (a mean diameter), m
SETTLED = 0.01     # settling speed of these films, m/s


def heap(angle_deg, half_width=0.3, plateau=0.0):
    """Particle centres x and tops filling a symmetric heap of flank angle `angle_deg`:
    one column per bin, topped at the heap's surface (a flat plateau of half-width `plateau`)."""
    x = np.arange(-half_width, half_width, D) + D / 2
    h = np.minimum(math.tan(math.radians(angle_deg)) * (half_width - np.abs(x)),
                   math.tan(math.radians(angle_deg)) * (half_width - plateau))
    return x, h


@pytest.mark.parametrize("angle", [12.0, 20.0, 27.0, 33.0])
def test_a_heap_gives_back_its_flank_angle(angle):
    x, top = heap(angle)
    # the fit runs over 20-80 % of the tip: a straight flank, so only the binning's half-bin offset is left
    assert flank_angle(x, top, D) == pytest.approx(angle, abs=0.05)


def test_a_plateau_does_not_steepen_the_flank():
    x, top = heap(20.0, plateau=0.1)
    assert flank_angle(x, top, D) == pytest.approx(20.0, abs=0.05)


def test_too_few_bins_on_a_side_give_nan():
    x = np.array([-0.001, 0.001])
    assert math.isnan(flank_angle(x, np.array([0.01, 0.01]), D))


def film(path, n=200, frames=40, dt=0.05, movers=None):
    """A film of `frames` frames `dt` apart in which particle k appears at frame k // 5 (five per
    frame), settled on a heap of 20 degrees, and moves (below the tip) only in the frames f whose
    ``movers[f]`` lists it; returns the particles' radii."""
    movers = movers or {}
    x0, top = heap(20.0, half_width=0.3)
    idx = np.linspace(0, len(x0) - 1, n).astype(int)
    x = np.full((frames, n), np.nan, np.float32)
    y = np.full((frames, n), np.nan, np.float32)
    speed = np.full((frames, n), np.nan, np.float32)
    released = np.zeros(frames, np.int32)
    t = dt * np.arange(frames)
    for f in range(frames):
        on = np.arange(n) < min(n, 5 * (f + 1))
        released[f] = on.sum()
        x[f, on] = x0[idx][on]
        y[f, on] = top[idx][on] - 0.5 * D
        speed[f, on] = 0.0
        for k in movers.get(f, ()):
            speed[f, k] = 10 * SETTLED
            y[f, k] = 0.0                       # below the tip: part of the pile
    xr.Dataset({"time": ("frame", t), "x": (("frame", "particle"), x), "y": (("frame", "particle"), y),
                "speed": (("frame", "particle"), speed), "released": ("frame", released)}).to_netcdf(path)
    return np.full(n, 0.5 * D)


def test_moving_particles_are_counted_and_old_ones_told_apart(tmp_path):
    # frame 30 (t = 1.5 s): particles 0-6 were released at t = 0 (old), 145-149 at t = 1.45 s (landing)
    movers = {30: [0, 1, 2, 3, 4, 5, 6, 145, 146, 147, 148, 149], 31: [10, 11]}
    radius = film(tmp_path / "f.nc", movers=movers)
    g = growth(tmp_path / "f.nc", radius, D, start=0.3, settled_speed=SETTLED)
    rows = {round(t, 6): r for t, *r in g}
    assert rows[1.5][2:] == [12, 7]               # all moving, of them old (released > OLD s before)
    assert rows[1.55][2:] == [2, 2]
    assert OLD < 1.5 - 0.0 and 1.5 - 1.45 < OLD    # the split the counts rely on
    quiet = [r for t, r in rows.items() if t not in (1.5, 1.55)]
    assert all(r[2] == 0 and r[3] == 0 for r in quiet)


def test_the_growth_window_and_the_flank_while_growing(tmp_path):
    radius = film(tmp_path / "f.nc")
    g = growth(tmp_path / "f.nc", radius, D, start=0.3, settled_speed=SETTLED)
    # from 30 % of 200 released (60, frame 11) to the last frame before all 200 are (frame 38)
    assert g[0, 1] == 60 and g[-1, 1] == 195
    # the flux: five particles per 0.05 s
    assert (g[-1, 1] - g[0, 1]) / (g[-1, 0] - g[0, 0]) == pytest.approx(100.0)
    # every frame's settled particles lie on the 20 degree heap's flanks
    finite = g[np.isfinite(g[:, 2]), 2]
    assert finite.size > 10 and np.all(np.abs(finite - 20.0) < 1.0)


def landings(path, lx, ly, last_x):
    """A frames file holding only what :func:`landing_displacement` reads: the landings and
    one frame (the last) of centres."""
    n = len(lx)
    xr.Dataset({"landing_x": ("particle", np.asarray(lx, float)),
                "landing_y": ("particle", np.asarray(ly, float)),
                "x": (("frame", "particle"), np.asarray(last_x, float).reshape(1, n))}).to_netcdf(path)
    return path


def test_the_interior_share_counts_the_particles_resting_within_a_diameter_of_their_landing(tmp_path):
    """Ten particles moved by 0, 0.5, 0.99, 1.01, 1.5, 1.99, 3, 4 and 5 diameters (one never landed): the
    share within one diameter is 3 of the 9 that landed, within two 5 of 9, and the median
    distance is the middle one's."""
    moved = np.array([0.0, 0.5, 0.99, 1.01, 1.5, 1.99, 3.0, 4.0, 5.0, 0.0]) * D
    lx = np.linspace(-0.1, 0.1, 10)
    ly = np.full(10, 0.02)
    x_rest, y_rest = lx + 0.6 * moved, ly - 0.8 * moved
    lx[-1] = ly[-1] = np.nan
    out = landing_displacement(landings(tmp_path / "f.nc", lx, ly, x_rest), x_rest, y_rest, D)
    assert out["landed"] == 9
    assert out["interior_share"] == pytest.approx(3 / 9)
    assert out["within_2d"] == pytest.approx(6 / 9)
    assert out["distance_q50"] == pytest.approx(1.5)


def test_a_table_pile_is_read_against_the_particles_it_kept(tmp_path):
    """Six released, two left the table (NaN in the last frame): the four kept, in release
    order, are matched with the relaxed state's four, and a mismatch of counts is refused."""
    lx = np.array([0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
    last = np.array([0.0, np.nan, 0.02, 0.03, np.nan, 0.05])
    path = landings(tmp_path / "t.nc", lx, np.zeros(6), last)
    kept = np.array([0.0, 0.02, 0.03, 0.05]) + np.array([0.0, 0.0, 2.0, 0.0]) * D
    out = landing_displacement(path, kept, np.zeros(4), D)
    assert out["landed"] == 4 and out["interior_share"] == pytest.approx(0.75)
    with pytest.raises(ValueError, match="not the same pile"):
        landing_displacement(path, kept[:3], np.zeros(3), D)


def test_the_growth_statistics_count_the_frames_in_which_the_flanks_flow():
    """Four frames (time, released, flank angle, moving, old moving): the flanks flow in
    those with at least FLOW_MIN old particles moving; the flux is released over time."""
    g = np.array([[1.0, 100, 20.0, 3, 0],
                  [2.0, 150, np.nan, 9, FLOW_MIN],
                  [3.0, 200, 24.0, 12, FLOW_MIN + 3],
                  [4.0, 250, 22.0, 1, FLOW_MIN - 1]])
    out = growth_statistics(g)
    assert out["frames"] == 4 and out["flow_fraction"] == 0.5
    assert out["old_moving_max"] == FLOW_MIN + 3 and out["old_moving_median"] == pytest.approx(FLOW_MIN - 0.5)
    assert out["moving_median"] == 6.0
    assert (out["flank_median_deg"], out["flank_max_deg"]) == (22.0, 24.0)      # the frame without an angle left out
    assert out["flank_p90_deg"] == pytest.approx(np.percentile([20.0, 24.0, 22.0], 90))
    assert out["flux_per_s"] == pytest.approx(50.0)
    assert growth_statistics(g, flow_min=1)["flow_fraction"] == 0.75
