"""analysis/draw.py (python -m analysis draw): pictures of particle states and
the Eq. 2 particle pressure, on a tiny hand-made state file that follows
docs/formats.md#state-files."""

import numpy as np
import pytest
import xarray as xr

from analysis import draw
from analysis.__main__ import main as analysis_main
from analysis.states import load_state
from analysis.stress import particle_stress

A = 0.01        # side of the squares, m
DENSITY = 2500.0  # kg/m^2
G = 9.81        # m/s^2
M = DENSITY * A * A  # mass of one square, kg


def _square(side):
    h = side / 2
    return [-h, h, h, -h], [-h, -h, h, h]  # counter-clockwise


def write_state(path, theta=(0.0, 0.0, 0.0)):
    """Three squares of side A at rest: B on the support, T on top of B, and
    L alone on the support at x = 3A. Forces balance the weights by hand."""
    xs = np.array([0.0, 0.0, 3 * A])
    ys = np.array([A / 2, 3 * A / 2, A / 2])
    sx, sy = _square(A)
    node_x = np.array(sx * 3)
    node_y = np.array(sy * 3)
    mg = M * G
    # contact 0: T (i) on B (j), at the middle of their common edge; the
    #            force on T is +mg upwards, B gets -mg.
    # contact 1: B (i) on the support (j = -1): carries B and T, 2 mg.
    # contact 2: L (i) on the support: mg.
    ds = xr.Dataset(
        {
            "x": ("particle", xs, {"units": "m", "long_name": "x"}),
            "y": ("particle", ys, {"units": "m", "long_name": "y"}),
            "theta": ("particle", np.array(theta), {"units": "rad", "long_name": "angle"}),
            "vx": ("particle", np.zeros(3)),
            "vy": ("particle", np.zeros(3)),
            "omega": ("particle", np.zeros(3)),
            "mass": ("particle", np.full(3, M)),
            "inertia": ("particle", np.full(3, M * A * A / 6)),
            "area": ("particle", np.full(3, A * A)),
            "node_count": ("particle", np.array([4, 4, 4], dtype=np.int32)),
            "node_x": ("node", node_x),
            "node_y": ("node", node_y),
            "contact_i": ("contact", np.array([1, 0, 2], dtype=np.int32)),
            "contact_j": ("contact", np.array([0, -1, -1], dtype=np.int32)),
            "contact_x": ("contact", np.array([0.0, 0.0, 3 * A])),
            "contact_y": ("contact", np.array([A, 0.0, 0.0])),
            "force_x": ("contact", np.zeros(3)),
            "force_y": ("contact", np.array([mg, 2 * mg, mg])),
            "normal_x": ("contact", np.zeros(3)),
            "normal_y": ("contact", np.array([-1.0, -1.0, -1.0])),
            "overlap_area": ("contact", np.full(3, 1e-9)),
        },
        attrs={
            "Conventions": "CF-1.10", "title": "test state", "source": "test",
            "history": "", "config": "{}", "time": 0.0, "gravity": G,
            "protocol": "wedge", "seed": 0,
        },
    )
    ds.to_netcdf(path)
    return path


def test_pressure_matches_hand_computed_values(tmp_path):
    state = load_state(write_state(tmp_path / "relaxed.nc"))
    mg = M * G
    sigma = particle_stress(state)
    # T: branch (0, -A/2) x force (0, mg), over A^2.
    assert sigma[1] == pytest.approx(np.array([[0, 0], [0, -mg / (2 * A)]]))
    # B: (0, A/2) x (0, -mg) from T plus (0, -A/2) x (0, 2 mg) from the support.
    assert sigma[0] == pytest.approx(np.array([[0, 0], [0, -3 * mg / (2 * A)]]))
    p = draw.particle_pressure(state)
    assert p == pytest.approx([3 * mg / (4 * A), mg / (4 * A), mg / (4 * A)])
    assert np.all(p > 0)  # compression gives a positive pressure


def test_polygons_rotate_about_the_centre(tmp_path):
    state = load_state(write_state(tmp_path / "s.nc", theta=(0.0, np.pi / 4, 0.0)))
    polys = draw.polygons_world(state)
    assert len(polys) == 3
    # Unrotated bottom square: corners at the centre +- A/2.
    assert polys[0] == pytest.approx(np.array(
        [[-A / 2, 0], [A / 2, 0], [A / 2, A], [-A / 2, A]]))
    # The top square turned by 45 degrees: its first corner (-A/2, -A/2)
    # goes straight below the centre, at distance A/sqrt(2).
    assert polys[1][0] == pytest.approx([0.0, 3 * A / 2 - A / np.sqrt(2)])
    assert polys[1].mean(axis=0) == pytest.approx([0.0, 3 * A / 2])


@pytest.mark.parametrize("extra", [[], ["--no-forces", "--color-by", "none"]])
def test_main_writes_a_png(tmp_path, extra):
    state = write_state(tmp_path / "relaxed.nc")
    out = tmp_path / "figs" / "wedge_seed0_relaxed.png"
    assert analysis_main(["draw", "--input", str(state), "--out", str(out), *extra]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 1000
    # No temporary file left behind.
    assert [f.name for f in out.parent.iterdir()] == [out.name]


def test_main_fails_clearly(tmp_path, capsys):
    assert analysis_main(["draw", "--input", str(tmp_path / "missing.nc"), "--out", str(tmp_path / "x.png")]) == 1
    assert "missing.nc" in capsys.readouterr().err
    bad = tmp_path / "bad.nc"
    xr.Dataset({"x": ("particle", np.zeros(2))}).to_netcdf(bad)
    assert analysis_main(["draw", "--input", str(bad), "--out", str(tmp_path / "x.png")]) == 1
    err = capsys.readouterr().err
    assert "missing variable" in err and "node_count" in err
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("name, words", [("pile.xyz", ["cannot be written as .xyz", ".png", ".svg"]),
                                         ("pile", ["no extension"])])
def test_a_picture_format_matplotlib_cannot_write_is_refused_first(tmp_path, capsys, name, words):
    """Before the fix, .xyz ended in matplotlib's ValueError traceback after the state
    was read and drawn; now the option is named before the input is even opened."""
    out = tmp_path / name
    assert analysis_main(["draw", "--input", str(tmp_path / "not_read.nc"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"--out {out}" in err and all(w in err for w in words) and "not_read.nc" not in err
    assert list(tmp_path.iterdir()) == []


def _lattice_and_stray(ncol, nrow, stray, on_support):
    """Squares of side A on a lattice resting on the support, and one more at
    `stray` (its centre), touching the support or nothing."""
    from synthetic_states import make_state, square_lattice, square_nodes

    x, y, c = square_lattice(ncol, nrow, A)
    k = x.size
    if on_support:
        c = {"i": np.append(c["i"], k), "j": np.append(c["j"], -1),
             "cx": np.append(c["cx"], stray[0]), "cy": np.append(c["cy"], 0.0)}
    state = make_state(np.append(x, stray[0]), np.append(y, stray[1]), square_nodes(A), c)
    return state, k


def _frame_of(state):
    from synthetic_states import as_state

    s = as_state(state)
    return draw.pile_frame(s, draw.polygons_world(s))


def test_the_frame_holds_the_pile_not_a_stray_particle():
    """3 x 2 squares on the support and a seventh 1 m away in mid-air, touching
    nothing: the frame is the pile's corners (x from -A/2 to 2.5 A, y from the
    support to 2 A), and the stray one is named as out of it."""
    state, stray = _lattice_and_stray(3, 2, (1.0, 0.5), on_support=False)
    xlim, ylim, out = _frame_of(state)
    assert xlim == pytest.approx((-A / 2, 2.5 * A)) and ylim == pytest.approx((0.0, 2 * A))
    assert out.tolist() == [stray]


def test_a_particle_far_along_the_support_is_out_of_frame_too():
    """In a pile of 100 squares a particle that rolled 0.5 m away along the
    support touches it, but lies far beyond the 99th percentile of x (the
    pile's last column, 9 A) and the margin (0.1 x 9 A + 2 x A/2 = 1.9 A)."""
    state, stray = _lattice_and_stray(10, 10, (0.5, A / 2), on_support=True)
    xlim, ylim, out = _frame_of(state)
    assert xlim == pytest.approx((-A / 2, 9.5 * A)) and ylim == pytest.approx((0.0, 10 * A))
    assert out.tolist() == [stray]


def test_a_pile_without_strays_is_framed_whole(tmp_path):
    """B, T and L (L alone on the support 3 A away, part of the picture):
    every corner is in the frame, nothing is out."""
    state = load_state(write_state(tmp_path / "s.nc"))
    xlim, ylim, out = draw.pile_frame(state, draw.polygons_world(state))
    assert xlim == pytest.approx((-A / 2, 3.5 * A)) and ylim == pytest.approx((0.0, 2 * A))
    assert out.size == 0


def test_the_picture_names_the_particle_out_of_frame(tmp_path, capsys):
    from synthetic_states import write_state as write_synthetic

    state, stray = _lattice_and_stray(3, 2, (1.0, 0.5), on_support=False)
    path = write_synthetic(tmp_path / "relaxed.nc", state)
    out = tmp_path / "relaxed.png"
    assert analysis_main(["draw", "--input", path, "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert capsys.readouterr().err == (f"[analysis] draw {out}: 1 particle out of frame (framed on the "
                                       f"pile): #{stray} at (1, 0.5) m\n")
