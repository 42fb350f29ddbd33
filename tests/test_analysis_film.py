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
from sim import protocols
from sim.config import SimConfig

INTERVAL = 0.01
CFG = SimConfig.from_dict({"pour": {"n_particles": 15, "rate": 300.0, "frame_interval": INTERVAL,
                                    "progress_interval": 1e9},
                           "model": {"integrator": "verlet"}})


@pytest.fixture(scope="module")
def poured(tmp_path_factory):
    """A tiny pour with its frames: (poured state path, frames path)."""
    folder = tmp_path_factory.mktemp("film")
    out, frames = folder / "poured.nc", folder / "frames.nc"
    protocols.pour(CFG, "wedge", 5, out, frames=frames)
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
