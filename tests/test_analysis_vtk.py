"""analysis/vtk.py (python -m analysis export): a particle state as VTK files
for ParaView, checked for content on a tiny hand-made state that follows
docs/formats.md#state-files, read back with meshio and with VTK's own reader (ParaView's; the ``vtk``
package is a test dependency); and the frames of a simulated pour as a
ParaView time series (.pvd collection of one .vtu per frame), read back with
VTK's reader and checked against the simulator's own state."""

import os
import subprocess
import sys

import meshio
import vtk  # VTK's own reader (ParaView's), beside meshio
import numpy as np
import pytest
import xarray as xr

from analysis.__main__ import main as analysis_main
from analysis.vtk import contacts_path, export_frames, export_state, wrap_angle

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
A = 0.01          # side of the squares, m
H = A / 2
DENSITY = 2500.0  # kg/m^2
G = 9.81          # m/s^2
M = DENSITY * A * A  # mass of one square, kg
MG = M * G
R2 = A / np.sqrt(2)  # centre-to-corner distance of a square

# Particles: 0 B (square on the support), 1 T (square on top of B), 2 L (square
# on the support next to B, touching it without force), 3 a triangle in flight
# turned by 90 degrees, 4 D a square in flight turned by 45 degrees. Corner
# counts 4, 4, 4, 3, 4: three runs, so the file holds several polygon blocks.
CENTRES = [(0.0, H), (0.0, 3 * H), (A, H), (7 * A, 2 * A), (4 * A, 2 * A)]
THETA = [0.0, 0.0, 0.0, np.pi / 2, np.pi / 4]
SQUARE = [(-H, -H), (H, -H), (H, H), (-H, H)]            # counter-clockwise
TRIANGLE = [(-H, -A / 3), (H, -A / 3), (0.0, 2 * A / 3)]  # centroid at the origin, area A^2/2
BODIES = [SQUARE, SQUARE, SQUARE, TRIANGLE, SQUARE]
AREA = [A * A] * 3 + [A * A / 2, A * A]
# Lab-frame corners by hand.
WORLD = [
    [(-H, 0), (H, 0), (H, A), (-H, A)],
    [(-H, A), (H, A), (H, 2 * A), (-H, 2 * A)],
    [(H, 0), (3 * H, 0), (3 * H, A), (H, A)],
    # (x, y) -> (-y, x) about (7A, 2A)
    [(7 * A + A / 3, 2 * A - H), (7 * A + A / 3, 2 * A + H), (7 * A - 2 * A / 3, 2 * A)],
    # 45 degrees about (4A, 2A): the corner (-h, -h) goes straight below the centre
    [(4 * A, 2 * A - R2), (4 * A + R2, 2 * A), (4 * A, 2 * A + R2), (4 * A - R2, 2 * A)],
]
VELOCITY = [(0, 0), (0, 0), (0, 0), (0.3, 0.1), (0.1, -0.2)]
OMEGA = [0.0, 0.0, 0.0, -1.5, 0.5]

# Contacts (force acting on contact_i, normal from i towards j):
#   0: T on B at the middle of their common edge, +mg upwards on T;
#   1: B on the support, carries B and T: 2 mg;
#   2: L on the support: mg, and a tangential (friction) part 0.3 mg along +x;
#   3: B touching L, side by side, without force.
CONTACT_I = [1, 0, 2, 0]
CONTACT_J = [0, -1, -1, 2]
CONTACT_XY = [(0.0, A), (0.0, 0.0), (A, 0.0), (H, H)]
FORCE = [(0.0, MG), (0.0, 2 * MG), (0.3 * MG, MG), (0.0, 0.0)]
NORMAL = [(0, -1), (0, -1), (0, -1), (1, 0)]
NORMAL_FORCE = [MG, 2 * MG, MG, 0.0]        # compression positive
TANGENTIAL_FORCE = [0.0, 0.0, 0.3 * MG, 0.0]
# Lines: centre to centre, or centre to contact point for the support.
LINES = [[(0, 3 * H), (0, H)], [(0, H), (0, 0)], [(A, H), (A, 0)], [(0, H), (A, H)]]

# Eq. 2 by hand (see tests/test_analysis_draw.py for the three squares):
# p = -(sxx + syy)/2: B 3mg/(4A), T and L mg/(4A), the free particles 0.
PRESSURE = [3 * MG / (4 * A), MG / (4 * A), MG / (4 * A), 0.0, 0.0]
COORDINATION = [2, 1, 1, 0, 0]   # B: T and L; the support does not count
SUPPORT_CONTACTS = [1, 0, 1, 0, 0]


def write_state(path, contacts=True, drop=(), theta=THETA):
    """The five-particle state above as a contract file (``contacts=False``: none;
    ``theta``: other orientations)."""
    n = len(CENTRES)
    node_x = [bx for body in BODIES for bx, _ in body]
    node_y = [by for body in BODIES for _, by in body]
    k = slice(None) if contacts else slice(0, 0)
    c = {
        "contact_i": np.array(CONTACT_I, dtype=np.int32)[k],
        "contact_j": np.array(CONTACT_J, dtype=np.int32)[k],
        "contact_x": np.array([p[0] for p in CONTACT_XY])[k],
        "contact_y": np.array([p[1] for p in CONTACT_XY])[k],
        "force_x": np.array([f[0] for f in FORCE])[k],
        "force_y": np.array([f[1] for f in FORCE])[k],
        "normal_x": np.array([v[0] for v in NORMAL], dtype=float)[k],
        "normal_y": np.array([v[1] for v in NORMAL], dtype=float)[k],
        "overlap_area": np.full(len(CONTACT_I), 1e-9)[k],
    }
    mass = DENSITY * np.array(AREA)
    ds = xr.Dataset(
        {
            "x": ("particle", np.array([p[0] for p in CENTRES]), {"units": "m", "long_name": "x"}),
            "y": ("particle", np.array([p[1] for p in CENTRES]), {"units": "m", "long_name": "y"}),
            "theta": ("particle", np.array(theta, dtype=float), {"units": "rad", "long_name": "orientation"}),
            "vx": ("particle", np.array([v[0] for v in VELOCITY], dtype=float)),
            "vy": ("particle", np.array([v[1] for v in VELOCITY], dtype=float)),
            "omega": ("particle", np.array(OMEGA)),
            "mass": ("particle", mass),
            "inertia": ("particle", mass * A * A / 6),
            "area": ("particle", np.array(AREA)),
            "node_count": ("particle", np.array([len(b) for b in BODIES], dtype=np.int32)),
            "node_x": ("node", np.array(node_x)),
            "node_y": ("node", np.array(node_y)),
            **{name: ("contact", v) for name, v in c.items()},
        },
        attrs={"Conventions": "CF-1.10", "title": "test state", "source": "test", "history": "",
               "config": "{}", "time": 0.0, "gravity": G, "protocol": "wedge", "seed": 0},
    )
    ds = ds.drop_vars(list(drop))
    assert n == ds.sizes["particle"]
    ds.to_netcdf(path)
    return path


def _cells(mesh, kind):
    """Cells of one meshio type in file order (as lists of point indices) and
    the cell data concatenated over the blocks of that type."""
    cells, data = [], {}
    for b, block in enumerate(mesh.cells):
        assert block.type == kind
        cells.extend(list(block.data))
        for name, blocks in mesh.cell_data.items():
            data.setdefault(name, []).append(np.asarray(blocks[b]))
    return cells, {name: np.concatenate(v) for name, v in data.items()}


@pytest.fixture()
def exported(tmp_path):
    state = write_state(tmp_path / "relaxed.nc")
    out = tmp_path / "vtk" / "relaxed.vtu"
    assert analysis_main(["export", "--input", str(state), "--vtk", str(out)]) == 0
    return out, tmp_path / "vtk" / "relaxed_contacts.vtu"


def test_files_written_atomically_next_to_each_other(exported):
    out, contacts = exported
    assert contacts_path(str(out)) == str(contacts)
    # Both files, no temporary left behind.
    assert sorted(f.name for f in out.parent.iterdir()) == ["relaxed.vtu", "relaxed_contacts.vtu"]
    for f in (out, contacts):
        head = f.read_bytes()[:400]
        assert b"<VTKFile" in head and b'type="UnstructuredGrid"' in head


def test_polygons_are_the_particles_in_order_with_their_world_corners(exported):
    mesh = meshio.read(exported[0])
    assert mesh.points.shape == (sum(len(b) for b in BODIES), 3)
    assert np.all(mesh.points[:, 2] == 0.0)  # the plane z = 0
    cells, data = _cells(mesh, "polygon")
    assert len(cells) == len(CENTRES)  # one polygon per particle, every one with its own corner count
    assert [len(c) for c in cells] == [4, 4, 4, 3, 4]
    np.testing.assert_array_equal(data["particle"], np.arange(len(CENTRES)))
    for p, cell in enumerate(cells):
        np.testing.assert_allclose(mesh.points[cell, :2], np.array(WORLD[p], dtype=float), rtol=0, atol=1e-15,
                                   err_msg=f"corners of particle {p}")


def test_particle_fields_by_hand(exported):
    _, data = _cells(meshio.read(exported[0]), "polygon")
    np.testing.assert_allclose(data["pressure"], PRESSURE, rtol=1e-12, atol=1e-9)
    assert np.all(data["pressure"][:3] > 0)  # compression: positive pressure
    np.testing.assert_array_equal(data["coordination"], COORDINATION)
    np.testing.assert_array_equal(data["support_contacts"], SUPPORT_CONTACTS)
    np.testing.assert_allclose(data["velocity"], [(vx, vy, 0.0) for vx, vy in VELOCITY])
    np.testing.assert_allclose(data["angular_velocity"], OMEGA)
    np.testing.assert_allclose(data["orientation"], THETA)
    np.testing.assert_allclose(data["area"], AREA)
    np.testing.assert_allclose(data["mass"], DENSITY * np.array(AREA))
    # The full Eq. 2 tensor, row-major 3x3. L (particle 2): branch (0, -A/2)
    # to the support, force (0.3 mg, mg): sigma_yx = -0.15 mg/A, sigma_yy =
    # -mg/(2A), the rest zero (compression negative, not symmetrised).
    stress = data["stress"].reshape(-1, 3, 3)
    np.testing.assert_allclose(stress[2], [[0, 0, 0], [-0.15 * MG / A, -MG / (2 * A), 0], [0, 0, 0]],
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(-0.5 * (stress[:, 0, 0] + stress[:, 1, 1]), PRESSURE, rtol=1e-12, atol=1e-9)


def test_contact_lines_and_forces_by_hand(exported):
    mesh = meshio.read(exported[1])
    cells, data = _cells(mesh, "line")
    assert len(cells) == len(CONTACT_I)
    assert np.all(mesh.points[:, 2] == 0.0)
    for c, cell in enumerate(cells):
        np.testing.assert_allclose(mesh.points[cell, :2], np.array(LINES[c], dtype=float), rtol=0, atol=1e-15,
                                   err_msg=f"line of contact {c}")
    np.testing.assert_array_equal(data["contact"], np.arange(len(CONTACT_I)))
    np.testing.assert_array_equal(data["contact_i"], CONTACT_I)
    np.testing.assert_array_equal(data["contact_j"], CONTACT_J)
    np.testing.assert_allclose(data["normal_force"], NORMAL_FORCE, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(data["tangential_force"], TANGENTIAL_FORCE, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(data["force"], [(fx, fy, 0.0) for fx, fy in FORCE])
    np.testing.assert_allclose(data["normal"], [(nx, ny, 0.0) for nx, ny in NORMAL])
    np.testing.assert_allclose(data["length"], [A, H, H, A])


def test_vtk_reader_sees_the_same(exported):
    from vtk.util.numpy_support import vtk_to_numpy

    def read(path):
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(str(path))
        r.Update()
        assert r.GetErrorCode() == 0
        return r.GetOutput()

    grid = read(exported[0])
    assert grid.GetNumberOfCells() == len(CENTRES)
    assert {grid.GetCellType(c) for c in range(grid.GetNumberOfCells())} == {vtk.VTK_POLYGON}
    pts = vtk_to_numpy(grid.GetPoints().GetData())
    for p in range(len(CENTRES)):  # VTK cell id = particle index
        ids = grid.GetCell(p).GetPointIds()
        corners = pts[[ids.GetId(k) for k in range(ids.GetNumberOfIds())], :2]
        np.testing.assert_allclose(corners, np.array(WORLD[p], dtype=float), rtol=0, atol=1e-15)
    cd = grid.GetCellData()
    np.testing.assert_allclose(vtk_to_numpy(cd.GetArray("pressure")), PRESSURE, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(vtk_to_numpy(cd.GetArray("coordination")), COORDINATION)
    assert cd.GetArray("velocity").GetNumberOfComponents() == 3
    assert cd.GetArray("stress").GetNumberOfComponents() == 9

    lines = read(exported[1])
    assert lines.GetNumberOfCells() == len(CONTACT_I)
    assert {lines.GetCellType(c) for c in range(lines.GetNumberOfCells())} == {vtk.VTK_LINE}
    np.testing.assert_allclose(vtk_to_numpy(lines.GetCellData().GetArray("normal_force")), NORMAL_FORCE,
                               rtol=1e-12, atol=1e-15)


def test_state_without_contacts(tmp_path):
    state = write_state(tmp_path / "poured.nc", contacts=False)
    out, contacts = export_state(str(state), str(tmp_path / "poured.vtu"))
    cells, data = _cells(meshio.read(out), "polygon")
    assert len(cells) == len(CENTRES)
    np.testing.assert_array_equal(data["coordination"], 0)
    np.testing.assert_array_equal(data["pressure"], 0.0)
    assert os.path.exists(contacts)  # an empty network (meshio 5.3 cannot read a grid without cells back)


def test_vtk_reads_an_empty_contact_network(tmp_path):
    state = write_state(tmp_path / "poured.nc", contacts=False)
    _, contacts = export_state(str(state), str(tmp_path / "poured.vtu"))
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(contacts)
    r.Update()
    assert r.GetErrorCode() == 0 and r.GetOutput().GetNumberOfCells() == 0


def _one_error_line(err):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    return lines[0]


def test_bad_inputs_fail_with_one_line_naming_the_file(tmp_path, capsys):
    out = tmp_path / "x.vtu"
    missing = tmp_path / "missing.nc"
    assert analysis_main(["export", "--input", str(missing), "--vtk", str(out)]) == 1
    assert str(missing) in _one_error_line(capsys.readouterr().err)
    bad = write_state(tmp_path / "bad.nc", drop=("normal_y",))
    assert analysis_main(["export", "--input", str(bad), "--vtk", str(out)]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert str(bad) in line and "missing variable" in line and "normal_y" in line
    good = write_state(tmp_path / "good.nc")
    assert analysis_main(["export", "--input", str(good), "--vtk", str(tmp_path / "x.vtk")]) == 1
    assert ".vtu" in _one_error_line(capsys.readouterr().err)
    assert sorted(f.name for f in tmp_path.iterdir()) == ["bad.nc", "good.nc"]  # nothing written


def test_command_line_exit_status(tmp_path):
    bad = write_state(tmp_path / "bad.nc", drop=("node_count",))
    r = subprocess.run([sys.executable, "-m", "analysis", "export", "--input", str(bad), "--vtk",
                        str(tmp_path / "x.vtu")], capture_output=True, text=True, cwd=REPO)
    assert r.returncode != 0
    line = _one_error_line(r.stderr)
    assert str(bad) in line and "node_count" in line
    assert not (tmp_path / "x.vtu").exists()


# --- orientation: wrapped to one turn in every export --------------------------

def test_orientation_is_wrapped_to_minus_pi_exclusive_pi_inclusive(tmp_path):
    """theta beyond one turn, and exactly pi and -pi, come out in (-pi, pi]:
    pi stays pi and -pi becomes pi (the same direction), by hand."""
    theta = [np.pi, -np.pi, -3 * np.pi, 1.5 * np.pi, 6 * np.pi + 0.25]
    expected = [np.pi, np.pi, np.pi, -np.pi / 2, 0.25]
    state = write_state(tmp_path / "turned.nc", theta=theta)
    out, _ = export_state(str(state), str(tmp_path / "turned.vtu"))
    _, data = _cells(meshio.read(out), "polygon")
    assert data["orientation"][0] == np.pi and data["orientation"][1] == np.pi
    np.testing.assert_allclose(data["orientation"], expected, rtol=0, atol=1e-12)
    assert np.all(data["orientation"] > -np.pi) and np.all(data["orientation"] <= np.pi)


def test_wrap_angle_stays_in_the_half_open_turn_at_its_edges():
    """Next to the edges (one float away from +-pi and from odd multiples of
    pi) the wrapped angle stays in (-pi, pi] and is the same direction."""
    edges = np.array([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 101 * np.pi])
    theta = np.concatenate([edges, np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf),
                            [0.0, -0.0, 1e-300, -1e-300, 2 * np.pi, -2 * np.pi, 1e3, -1e3]])
    w = wrap_angle(theta)
    assert w.dtype == np.float64
    assert np.all(w > -np.pi) and np.all(w <= np.pi), theta[(w <= -np.pi) | (w > np.pi)]
    np.testing.assert_allclose(np.cos(w), np.cos(theta), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(theta), rtol=0, atol=1e-12)
    assert np.isnan(wrap_angle([np.nan])[0])


# --- the frames of a pour as a ParaView time series ------------------------------

FRAME_INTERVAL = 0.004   # s
RELEASES = {1: (0.02, 0.03, 4.0), 3: (0.0, 0.03, -4.5), 5: (-0.02, 0.03, 3 * np.pi)}  # frame: (x, y, theta)


@pytest.fixture(scope="module")
def poured_frames(tmp_path_factory):
    """Frames of a tiny pour by the simulator: two polygons at rest on the
    support (turned beyond +-pi) from the start, three more released later
    (the first frame before any release: an empty grid). Returns the frames
    file and, per frame, the simulator's centres and orientations (float64)."""
    from scenes import rectangle, regular_polygon, scene
    from sim.frames import FrameRecorder

    polygons = [rectangle(6e-3, 4e-3), regular_polygon(5, 3e-3), regular_polygon(6, 3e-3, 0.1),
                rectangle(5e-3, 5e-3), regular_polygon(3, 3.5e-3)]
    sim = scene(polygons, [], gravity=(0.0, -9.81), support=True)
    recorder = FrameRecorder(sim.shapes, len(polygons), FRAME_INTERVAL)
    truth = []
    placed = [(-0.01, 0.0025, -3 * np.pi), (0.01, 0.0035, -np.pi - 1.0)]   # just above the support
    for k in range(8):
        if k == 1:
            for x, y, th in placed:
                sim.place(sim.n, x, y, th)
        if k in RELEASES:
            sim.place(sim.n, *RELEASES[k], 0.0, -0.5, 2.0)
        taken = len(recorder.times)
        recorder(sim)
        assert len(recorder.times) == taken + 1
        truth.append((sim.position, sim.theta, sim.shapes))
        sim.run(duration=1.5 * FRAME_INTERVAL)   # past the next frame time whatever the step
    recorder.finish(sim)
    truth.append((sim.position, sim.theta, sim.shapes))
    path = tmp_path_factory.mktemp("pour_frames") / "frames.nc"
    recorder.save(path, {"model": {}}, protocol="wedge", seed=1)
    with xr.open_dataset(path) as f:
        assert f.sizes["frame"] == len(truth)   # one frame per call, the last by finish()
    return path, truth


def _read_pvd(path):
    """(timestep, file) of each DataSet of a .pvd collection, parsed as XML."""
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    return [(float(d.get("timestep")), d.get("file")) for d in root.find("Collection").findall("DataSet")]


def _vtk_grid(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    assert r.GetErrorCode() == 0, path
    return r.GetOutput()


def _polygon_points(grid, cell):
    from vtk.util.numpy_support import vtk_to_numpy

    pts = vtk_to_numpy(grid.GetPoints().GetData())
    ids = grid.GetCell(cell).GetPointIds()
    return pts[[ids.GetId(k) for k in range(ids.GetNumberOfIds())]]


def _rotated(cx, cy, theta, bx, by):
    """Lab-frame corners, corner by corner: centre + R(theta) (body-frame corner)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([(cx + c * x - s * y, cy + s * x + c * y) for x, y in zip(bx, by)])


def test_frames_become_a_paraview_time_series(poured_frames, tmp_path):
    from vtk.util.numpy_support import vtk_to_numpy

    frames, truth = poured_frames
    out = tmp_path / "series" / "pour.pvd"
    assert analysis_main(["export", "--frames", str(frames), "--vtk", str(out)]) == 0
    entries = _read_pvd(out)
    with xr.open_dataset(frames) as f:
        times = f["time"].values
        x, y, theta, speed = (f[v].values.astype(float) for v in ("x", "y", "theta", "speed"))
        counts, bx, by = f["node_count"].values, f["node_x"].values, f["node_y"].values
    offsets = np.concatenate([[0], np.cumsum(counts)])
    assert len(entries) == len(times) == len(truth)
    assert [t for t, _ in entries] == [float(t) for t in times]   # every digit of the simulated time
    assert sorted(p.name for p in out.parent.iterdir()) == ["pour", "pour.pvd"]  # no temporary left
    assert sorted(p.name for p in (out.parent / "pour").iterdir()) == sorted(
        os.path.basename(name) for _, name in entries)
    released = [int(np.isfinite(x[k]).sum()) for k in range(len(times))]
    assert released[0] == 0 and released[-1] == len(counts)   # an empty first frame, then all of them
    for k, (t, name) in enumerate(entries):
        assert not os.path.isabs(name) and name.startswith("pour/")
        grid = _vtk_grid(out.parent / name)
        assert grid.GetNumberOfCells() == released[k], name
        assert {grid.GetCellType(c) for c in range(grid.GetNumberOfCells())} <= {vtk.VTK_POLYGON}
        cd = grid.GetCellData()
        np.testing.assert_array_equal(vtk_to_numpy(cd.GetArray("particle")), np.arange(released[k]))
        np.testing.assert_array_equal(vtk_to_numpy(cd.GetArray("speed")), speed[k, :released[k]])
        orientation = vtk_to_numpy(cd.GetArray("orientation"))
        assert np.all(orientation > -np.pi) and np.all(orientation <= np.pi)
        np.testing.assert_allclose(np.cos(orientation), np.cos(theta[k, :released[k]]), atol=1e-12)
        np.testing.assert_allclose(np.sin(orientation), np.sin(theta[k, :released[k]]), atol=1e-12)
        for p in range(released[k]):   # each polygon: the frame's centre, turned body corners
            np.testing.assert_allclose(
                _polygon_points(grid, p), np.column_stack([_rotated(
                    x[k, p], y[k, p], theta[k, p], bx[offsets[p]:offsets[p + 1]],
                    by[offsets[p]:offsets[p + 1]]), np.zeros(counts[p])]),
                rtol=0, atol=1e-15, err_msg=f"frame {k}, particle {p}")
    # One polygon against the simulator itself: its centre, orientation (float64,
    # beyond one turn) and body-frame corners at the last frame; the frames keep
    # float32 centres and angles, hence the tolerance.
    position, angle, shapes = truth[-1]
    grid = _vtk_grid(out.parent / entries[-1][1])
    for p in range(len(counts)):
        corners = _rotated(*position[p], angle[p], *shapes.corners(p))
        np.testing.assert_allclose(_polygon_points(grid, p)[:, :2], corners, rtol=0, atol=1e-8)
    assert abs(angle[4]) > np.pi   # the orientations turned beyond one turn were exported wrapped


def test_a_second_export_replaces_the_series(poured_frames, tmp_path):
    frames, _ = poured_frames
    out = tmp_path / "pour.pvd"
    folder = tmp_path / "pour"
    folder.mkdir()
    (folder / "pour_9999.vtu").write_text("stale")
    pvd, files = export_frames(str(frames), str(out))
    assert pvd == str(out) and all(os.path.exists(f) for f in files)
    assert sorted(os.listdir(folder)) == sorted(os.path.basename(f) for f in files)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pour", "pour.pvd"]


def test_bad_frames_inputs_fail_with_one_line_naming_the_option(poured_frames, tmp_path, capsys):
    from sim.frames import FrameRecorder
    from scenes import rectangle, scene

    frames, _ = poured_frames
    out = tmp_path / "out" / "pour.pvd"
    missing = tmp_path / "missing.nc"
    assert analysis_main(["export", "--frames", str(missing), "--vtk", str(out)]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert f"--frames {missing}: no such file" in line and "python -m sim pour --frames" in line
    state = write_state(tmp_path / "relaxed.nc")
    assert analysis_main(["export", "--frames", str(state), "--vtk", str(out)]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert f"--frames {state}: not a frames file (missing time" in line
    sim = scene([rectangle(4e-3, 4e-3)], [(0.0, 0.002, 0, 0, 0, 0)], support=True)
    empty = tmp_path / "empty.nc"
    FrameRecorder(sim.shapes, 1, 0.5).save(empty)          # no frame taken
    assert analysis_main(["export", "--frames", str(empty), "--vtk", str(out)]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert f"--frames {empty}: holds no frame" in line
    assert analysis_main(["export", "--frames", str(frames), "--vtk", str(tmp_path / "pour.vtu")]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert "--vtk" in line and "pour.vtu" in line and ".pvd" in line
    assert analysis_main(["export", "--input", str(state), "--vtk", str(tmp_path / "pour.pvd")]) == 1
    assert ".vtu" in _one_error_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.nc", "relaxed.nc"]   # nothing written
    with pytest.raises(SystemExit) as exc:   # a state and frames at once: argparse refuses
        analysis_main(["export", "--input", str(state), "--frames", str(frames), "--vtk", str(out)])
    assert exc.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err
