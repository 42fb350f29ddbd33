"""analysis/vtk.py (python -m analysis export): a particle state as VTK files
for ParaView, checked for content on a tiny hand-made state that follows
docs/formats.md#state-files, read back with meshio and with VTK's own reader (ParaView's; the ``vtk``
package is a test dependency)."""

import os
import subprocess
import sys

import meshio
import vtk  # VTK's own reader (ParaView's), beside meshio
import numpy as np
import pytest
import xarray as xr

from analysis.__main__ import main as analysis_main
from analysis.vtk import contacts_path, export_state

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


def write_state(path, contacts=True, drop=()):
    """The five-particle state above as a contract file (``contacts=False``: none)."""
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
            "theta": ("particle", np.array(THETA), {"units": "rad", "long_name": "orientation"}),
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
