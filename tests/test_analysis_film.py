"""The film of a pour: its frames are the pour's own states (the last one is
the poured state, particle for particle, and a frame is taken at every
multiple of the frame interval), its polygons are those of the state file,
and the MP4 holds one picture per frame at the stated rate, also inside the
HTML page the report shows."""

import base64
import re

import numpy as np
import pytest
import xarray as xr

from analysis import film
from analysis.errors import InputError
from analysis.states import load_state
from sim.config import SimConfig
from sim.pour import pour

INTERVAL = 0.01
CFG = SimConfig.from_dict({"pour": {"n_particles": 15, "rate": 300.0, "frame_interval": INTERVAL,
                                    "release_speed": 0.3,
                                    "progress_interval": 1e9},
                           "model": {"integrator": "verlet"}})


@pytest.fixture(scope="module")
def poured(tmp_path_factory):
    """A tiny pour with its frames: (poured state path, frames path)."""
    folder = tmp_path_factory.mktemp("film")
    out, frames = folder / "poured.nc", folder / "frames.nc"
    pour(CFG, "wedge", 5, out, frames=frames)
    return out, frames


def test_the_frames_follow_the_pour_and_end_on_the_poured_state(poured):
    out, frames = poured
    with xr.open_dataset(frames) as f, xr.open_dataset(out) as s:
        times, released = f["time"].values, f["released"].values
        # one frame at the first step at or after every multiple of the interval,
        # and the last frame is the saved state itself
        k = np.floor(times[:-1] / INTERVAL + 1e-9)
        assert np.array_equal(k, np.arange(len(k))), times
        assert times[-1] == pytest.approx(s.attrs["time"], abs=0.0)
        # particles are released one after another and never vanish
        assert np.all(np.diff(released) >= 0) and released[-1] == s.sizes["particle"] == 15
        assert released[0] <= 1
        n = s.sizes["particle"]
        for name in ("x", "y", "theta"):
            np.testing.assert_array_equal(f[name].values[-1, :n], s[name].values.astype(np.float32))
        speed = np.hypot(s["vx"].values, s["vy"].values).astype(np.float32)
        np.testing.assert_allclose(f["speed"].values[-1, :n], speed, rtol=1e-6)
        # not yet released: NaN, never a made-up position
        first = f["x"].values[0]
        assert np.isnan(first[released[0]:]).all()
        np.testing.assert_array_equal(f["node_count"].values, s["node_count"].values)
        assert f.attrs["Conventions"] == "CF-1.10" and "config" in f.attrs


def test_the_film_draws_the_polygons_of_the_state_file(poured):
    """world_corners of the last frame against State.world_vertices of the
    poured state (an independent construction: padded arrays, float64)."""
    out, frames = poured
    state = load_state(str(out))
    with xr.open_dataset(frames) as f:
        corners = film.world_corners(f["x"].values[-1].astype(float), f["y"].values[-1].astype(float),
                                     f["theta"].values[-1].astype(float), f["node_count"].values,
                                     f["node_x"].values, f["node_y"].values)
    vx, vy, counts = state.world_vertices()
    expected = np.concatenate([np.column_stack((vx[p, :c], vy[p, :c])) for p, c in enumerate(counts)])
    # the frame holds float32 centres and angles: agreement to float32 rounding of ~0.1 m
    np.testing.assert_allclose(corners, expected, atol=2e-7)


def test_the_film_has_one_picture_per_frame_and_its_page_holds_it(poured, tmp_path):
    import imageio_ffmpeg

    _, frames = poured
    mp4, page = tmp_path / "film.mp4", tmp_path / "film.html"
    info = film.render_film(str(frames), str(mp4), str(page), fps=5)
    with xr.open_dataset(frames) as f:
        n_frames = f.sizes["frame"]
    assert info["frames"] == n_frames
    counted, seconds = imageio_ffmpeg.count_frames_and_secs(str(mp4))
    assert counted == n_frames
    assert seconds == pytest.approx(n_frames / 5, abs=0.21)
    text = page.read_text()
    data = re.search(r'src="data:video/mp4;base64,([^"]+)"', text).group(1)
    assert base64.b64decode(data) == mp4.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["film.html", "film.mp4"]


def test_bad_input_is_refused_before_drawing(poured, tmp_path):
    out, frames = poured
    with pytest.raises(InputError, match="not a frames file .missing time"):
        film.render_film(str(out), str(tmp_path / "f.mp4"))       # a state file, not frames
    with pytest.raises(InputError, match="fps = 0"):
        film.render_film(str(frames), str(tmp_path / "f.mp4"), fps=0)
    assert not list(tmp_path.iterdir())


def test_a_frame_interval_that_is_not_positive_is_refused():
    with pytest.raises(ValueError, match="pour.frame_interval"):
        SimConfig.from_dict({"pour": {"frame_interval": 0.0}})


def test_the_pour_command_takes_frames_without_a_file_as_none(tmp_path):
    """The workflow passes --frames with an empty value when the scene wants no
    film, and Snakemake drops an empty quoted field: the command line then ends
    in a bare --frames, which pours without frames."""
    import json
    import subprocess
    import sys

    params = json.dumps({"pour": {"n_particles": 3, "rate": 300.0, "progress_interval": 1e9},
                         "model": {"integrator": "verlet"}})
    out = tmp_path / "poured.nc"
    proc = subprocess.run([sys.executable, "-m", "sim", "pour", "--params", params, "--protocol", "wedge",
                           "--seed", "1", "--out", str(out), "--frames"], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poured.nc"]


def _pile_frames(stray=None, falling=True):
    """Two frames of a synthetic triangular pile of 1 cm squares (half-width
    0.3 m, height 0.15 m, about 450 particles): in the first the lower half
    of the pile and one particle falling at (0, 0.3 m), in the last the whole
    pile, and the particle ``stray`` = (x, y) (released in the last frame)."""
    a, half, height = 0.01, 0.3, 0.15
    centres = [(i * a, (j + 0.5) * a) for j in range(int(height / a)) for i in range(-40, 41)
               if abs(i * a) + a / 2 <= half * (1 - (j + 1) * a / height)]
    n = len(centres) + (stray is not None)
    x, y = np.full((2, n), np.nan), np.full((2, n), np.nan)
    x[1, :len(centres)], y[1, :len(centres)] = np.array(centres).T
    low = y[1] < height / 2
    x[0, low], y[0, low] = x[1, low], y[1, low]
    if falling:
        top = int(np.nanargmax(y[1]))
        x[0, top], y[0, top] = 0.0, 2 * height
    if stray is not None:
        x[1, -1], y[1, -1] = stray
    corner = np.tile([[-a / 2, -a / 2], [a / 2, -a / 2], [a / 2, a / 2], [-a / 2, a / 2]], (n, 1))
    return xr.Dataset({"time": ("frame", [0.0, 1.0]), "x": (("frame", "particle"), x),
                       "y": (("frame", "particle"), y), "theta": (("frame", "particle"), np.zeros((2, n))),
                       "speed": (("frame", "particle"), np.zeros((2, n))),
                       "node_count": ("particle", np.full(n, 4)),
                       "node_x": ("node", corner[:, 0]), "node_y": ("node", corner[:, 1])}), half, height


def test_the_film_frames_the_pile_not_a_stray_particle():
    """One particle far to the side and above (2 m, 0.9 m) of a pile 0.6 m wide
    leaves the frame where it is without it: around the pile with a margin
    (not +-2 m, the farthest particle), and as high as the particle falling
    onto the pile in the first frame (not 0.9 m)."""
    r = 1.5 * 0.01 / np.sqrt(2)     # 1.5 times the squares' circumradius
    plain, half, height = _pile_frames()
    strayed, _, _ = _pile_frames(stray=(2.0, 0.9))
    x_lo, x_hi, y_lo, y_hi = film.film_extent(strayed)
    # the same frame as without the stray, to 5 % of the pile's half-width (the
    # edge moves by one particle's column: the stray is one particle more)
    assert (x_lo, x_hi, y_lo, y_hi) == pytest.approx(film.film_extent(plain), abs=0.05 * half)
    assert x_lo == -x_hi                                  # centred on the pouring axis
    assert half + r < x_hi < 1.35 * half                  # the whole pile and a margin, not the stray
    assert y_hi == pytest.approx(2 * height + r)          # the falling particle is in the picture
    assert y_lo == pytest.approx(-0.05 * y_hi)
    # without the falling particle the top is the pile's top
    settled, _, _ = _pile_frames(stray=(2.0, 0.9), falling=False)
    pile_top = float(np.nanmax(settled["y"].values[:, :-1]))   # highest centre but the stray's
    assert pile_top < height and film.film_extent(settled)[3] == pytest.approx(pile_top + r)


def test_a_film_of_few_particles_still_leaves_a_stray_out():
    """Three particles and a stray: at least one particle is left beyond each
    edge, so the stray does not set the frame (with 1 % of 3 particles none would be)."""
    frames = xr.Dataset({"time": ("frame", [0.0]), "x": (("frame", "particle"), [[-0.01, 0.0, 0.01, 1.0]]),
                         "y": (("frame", "particle"), [[0.005, 0.005, 0.005, 0.005]]),
                         "theta": (("frame", "particle"), np.zeros((1, 4))),
                         "speed": (("frame", "particle"), np.zeros((1, 4))),
                         "node_count": ("particle", [3] * 4),
                         "node_x": ("node", [-0.004, 0.004, 0.0] * 4), "node_y": ("node", [-0.003, -0.003, 0.006] * 4)})
    x_lo, x_hi, _, _ = film.film_extent(frames)
    assert x_hi < 0.05


def test_frames_that_are_missing_or_empty_are_refused_naming_the_option(tmp_path):
    with pytest.raises(InputError, match=r"--input .*missing\.nc: no such file; expected a frames file"):
        film.read_frames(str(tmp_path / "missing.nc"))
    empty = tmp_path / "empty.nc"
    frames, _, _ = _pile_frames()
    frames.isel(frame=slice(0, 0)).to_netcdf(empty)
    with pytest.raises(InputError, match=r"--frames .*empty\.nc: holds no frame"):
        film.read_frames(str(empty), "--frames")
