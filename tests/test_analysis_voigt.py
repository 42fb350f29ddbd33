"""The affine (Voigt) stiffness of an RVE from its contacts (analysis/voigt.py, issue 27 item 4).

A square lattice of pressed squares on the support, whose Voigt stiffness is
written down by hand; and a disordered packing of turned, stretched, jostled
hexagons, where the stress change of small affine strains, computed with the
simulator's own narrow phase and force law, is ``C : ε``.  About 3 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from synthetic_states import as_state, make_state, mapped_hex_lattice, square_lattice, square_nodes

from analysis import rve as _rve
from analysis.fields import compute_fields
from analysis.params import parse_params
from analysis.stress import particle_stress_moment, rve_stress
from analysis.voigt import contact_stiffness, isotropic_projection, particle_voigt_moment, rve_voigt_stiffness

Y = 1e7


def test_a_square_lattice_on_the_support_has_its_voigt_stiffness_by_hand():
    """Squares of side a at spacing d = a (1 - eta), the lowest row pressed
    into the support by (a - d)/2.  Particle pairs: contact line L = a, force
    point halfway, r_i = r_j = d/2, so l = d/4 and k_n = 4 Y a/d; on the
    support r = l = d/2, k_n = 2 Y a/d; k_t = 2/7 Y everywhere.  A contact end
    adds sym(b x K (l . eps)) with b = l/2 (pairs) or b = l = (0, -d/2)
    (support), so per member particle: C11 = k_n d^2 (two horizontal ends),
    C22 = k_n d^2 (two vertical ends; bottom row: one, plus k_n,s d^2/4),
    C33 = k_t d^2 (bottom row: 3/4 k_t d^2 + k_t d^2/8), C12 = 0; then / V."""
    a, eta = 0.004, 1e-3
    d = a * (1 - eta)
    x, y, c = square_lattice(14, 12, d, x0=-6.5 * d)
    state = make_state(x, y, square_nodes(a), c, attrs={"youngs_modulus": Y, "friction": 0.5,
                                                        "support_friction": 0.5})
    state["overlap_area"] = np.where(c["j"] >= 0, a * (a - d), a * (a - d) / 2)
    s = as_state(state)
    k = contact_stiffness(s)
    pp = c["j"] >= 0
    np.testing.assert_allclose(k["length"], a, rtol=1e-12)
    np.testing.assert_allclose(k["k_n"][pp], 4 * Y * a / d, rtol=1e-12)
    np.testing.assert_allclose(k["k_n"][~pp], 2 * Y * a / d, rtol=1e-12)
    np.testing.assert_allclose(k["k_t"], 2 / 7 * Y, rtol=1e-15)
    np.testing.assert_allclose(k["depth_ratio"][pp], (a - d) / (d / 4), rtol=1e-12)
    assert not k["sliding"].any()                                   # no force at all

    centres = np.array([[0.0, 6 * d], [0.0, 2.5 * d]])               # inside; touching the support row
    size = 5.2 * d
    W = _rve.membership(centres, s.x, s.y, "square", size)
    V = _rve.rve_area(centres[:, 1], "square", size)
    C = rve_voigt_stiffness(W, particle_voigt_moment(s), V)
    kn, kns, kt = 4 * Y * a / d, 2 * Y * a / d, 2 / 7 * Y
    for r in range(2):
        members = W[r].indices
        bottom = np.sum(np.isclose(s.y[members], d / 2))
        top = members.size - bottom
        expected = np.zeros((3, 3))
        expected[0, 0] = members.size * kn * d * d
        expected[1, 1] = top * kn * d * d + bottom * (kn * d * d / 2 + kns * d * d / 4)
        expected[2, 2] = top * kt * d * d + bottom * (0.75 * kt * d * d + kt * d * d / 8)
        np.testing.assert_allclose(C[r], expected / V[r], rtol=1e-12, atol=1e-9 * kn)
        assert (r == 0) == (bottom == 0)
    K, G = isotropic_projection(C[0])
    assert K == pytest.approx(C[0, 0, 0] / 2, rel=1e-12)                         # C11 = C22, C12 = 0
    assert G == pytest.approx((2 * C[0, 0, 0] + 2 * C[0, 2, 2]) / 8, rel=1e-12)
    # an RVE of 5 x 5 cells (no centre on its edge) has the lattice's k_n, k_n, k_t per unit area
    full = _rve.membership(np.array([[0.5 * d, 6.5 * d]]), s.x, s.y, "square", 5 * d)
    assert full.nnz == 25
    C25 = rve_voigt_stiffness(full, particle_voigt_moment(s), np.array([(5 * d) ** 2]))[0]
    np.testing.assert_allclose(C25, np.diag([kn, kn, kt]), rtol=1e-12, atol=1e-9 * kn)


def test_a_contact_line_along_a_face_is_that_face_or_the_crossings():
    """A small square pressed face first into a large one, both turned by an
    odd angle: the contact line runs along the large square's face (its corners
    lie on the line to rounding) between the small square's sides, L = its side;
    pressed corner first, between the crossings.  Both as the simulator's narrow
    phase has them; l and k_n = Y L / l from the force point's distances."""
    from sim.geometry import polygon_overlap

    big, small = square_nodes(0.01), square_nodes(0.004)
    for turn, small_turn in ((0.3, 0.3), (1.1, 1.1 + np.pi / 4)):
        rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
        centres = np.array([[0.0, 0.0], [0.007 - 1e-5, 0.0004]]) @ rot.T + [0.1, 0.3]
        if small_turn != turn:
            centres[1] = np.array([0.005 + 0.002 * np.sqrt(2) - 1e-5, 0.0004]) @ rot.T + [0.1, 0.3]
        theta = np.array([turn, small_turn])
        world = [c + p @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
                 for c, p, a in zip(centres, (big, small), theta)]
        out = np.empty(10)
        assert polygon_overlap(world[0][:, 0], world[0][:, 1], world[1][:, 0], world[1][:, 1], *centres[0],
                               *centres[1], 1e-12, out)
        c = {"i": [0], "j": [1], "cx": [out[5]], "cy": [out[6]], "nx": [out[7]], "ny": [out[8]]}
        state = make_state(centres[:, 0], centres[:, 1], [big, small], c, theta=theta,
                           attrs={"youngs_modulus": Y})
        k = contact_stiffness(as_state(state))
        assert k["length"][0] == pytest.approx(out[9], rel=1e-9)
        if small_turn == turn:
            assert out[9] == pytest.approx(0.004, rel=1e-9)
        r = [np.hypot(*(out[5:7] - centres[q])) for q in (0, 1)]
        assert k["k_n"][0] == pytest.approx(Y * out[9] * (r[0] + r[1]) / (r[0] * r[1]), rel=1e-9)


def sim_state(x, y, theta, pairs, nodes, ref, friction=0.5):
    """A state of rigidly placed polygons whose contact forces are the simulator's:
    overlap, force point, normal and contact line from :func:`sim.geometry.polygon_overlap`,
    ``F = Y A / l`` (:mod:`sim.contact_law`), the Cundall–Strack spring loaded by the
    relative tangential displacement since ``ref`` (positions, no rotation) in one step."""
    from sim.contact_law import characteristic_length, elastic_force, tangential_force
    from sim.geometry import polygon_overlap

    out = np.empty(10)
    eps = 1e-9 * float(np.max(np.hypot(nodes[:, 0], nodes[:, 1])))
    world = []
    for p in range(x.size):
        cth, sth = np.cos(theta[p]), np.sin(theta[p])
        world.append((x[p] + cth * nodes[:, 0] - sth * nodes[:, 1], y[p] + sth * nodes[:, 0] + cth * nodes[:, 1]))
    c = {k: [] for k in ("i", "j", "cx", "cy", "fx", "fy", "nx", "ny", "area", "length")}
    for i, j in pairs:
        if not polygon_overlap(*world[i], *world[j], x[i], y[i], x[j], y[j], eps, out):
            continue
        area, sx, sy, nx, ny = out[0], out[5], out[6], out[7], out[8]
        l = characteristic_length(np.hypot(sx - x[i], sy - y[i]), np.hypot(sx - x[j], sy - y[j]))
        f_n = elastic_force(area, l, Y)
        slide = ((x[i] - ref[0][i]) - (x[j] - ref[0][j])) * -ny + ((y[i] - ref[1][i]) - (y[j] - ref[1][j])) * nx
        f_t, _ = tangential_force(0.0, slide, f_n, 0.0, Y, friction, 1.0)
        for k, v in zip(c, (i, j, sx, sy, -f_n * nx + f_t * ny, -f_n * ny - f_t * nx, nx, ny, area, out[9])):
            c[k].append(v)
    c = {k: np.array(v) for k, v in c.items()}
    state = make_state(x, y, nodes, c, theta=theta, attrs={"youngs_modulus": Y, "friction": friction})
    state["overlap_area"] = c["area"]
    return state, c


def disordered_packing(compression, seed=7):
    """Hexagons stretched and turned (faces of three lengths, normals off the
    branch vectors), pressed together by ``compression`` of their spacing, each
    then turned by up to ``0.1 compression`` rad and its centre moved by up to
    ``0.1 compression`` of the spacing: trapezoidal overlaps of many depths,
    with forces from the simulator (:func:`sim_state`)."""
    rng = np.random.default_rng(seed)
    turn = np.radians(35.0)
    mapping = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]) @ np.diag([1.8, 1.0])
    x, y, pairs, nodes, lattice = mapped_hex_lattice(12, 0.003, mapping, compression=compression)
    spacing = float(np.min(np.hypot(lattice[:, 0], lattice[:, 1])))
    x = x + 0.1 * compression * spacing * rng.uniform(-1, 1, x.size)
    y = y + 0.1 * compression * spacing * rng.uniform(-1, 1, y.size) + 0.2
    theta = 0.1 * compression * rng.uniform(-1, 1, x.size)
    return x, y, theta, pairs, nodes


MANDEL_UNITS = (np.array([[1.0, 0], [0, 0]]), np.array([[0, 0], [0, 1.0]]),
                np.array([[0, 1.0], [1.0, 0]]) / np.sqrt(2))


def test_the_stress_change_of_a_small_affine_strain_of_a_disordered_packing_is_c_eps():
    """Moving every centre of a disordered packing by +-x . eps (no rotation,
    eps = 1e-8 times each Mandel unit strain) and recomputing every contact
    force with the simulator's narrow phase and law changes the Eq. 2 RVE
    stress by C eps, to the neglected order: the overlap depth over l (module
    docstring of analysis.voigt).  The misfit is 0.6 times the median
    A / (L l) at two compressions four times apart, so it is that order and
    nothing else; the contact lines recovered from the polygons are the
    simulator's."""
    misfit = {}
    for compression in (2e-3, 5e-4):
        x, y, theta, pairs, nodes = disordered_packing(compression)
        base, c = sim_state(x, y, theta, pairs, nodes, (x, y))
        assert c["i"].size == len(pairs)
        s0 = as_state(base)
        k = contact_stiffness(s0)
        np.testing.assert_allclose(k["length"], c["length"], rtol=1e-9)
        assert np.ptp(k["k_n"]) > 0.3 * np.median(k["k_n"])                     # contacts of many stiffnesses
        centre = np.array([[0.0, 0.2]])
        W = _rve.membership(centre, s0.x, s0.y, "square", 0.035)
        V = _rve.rve_area(centre[:, 1], "square", 0.035)
        C = rve_voigt_stiffness(W, particle_voigt_moment(s0, k), V)[0]
        strain = 1e-8
        fd = np.zeros((3, 3))
        for col, e in enumerate(MANDEL_UNITS):
            sig = []
            for sign in (1, -1):
                du = np.column_stack([x, y]) @ (sign * strain * e)
                moved, _ = sim_state(x + du[:, 0], y + du[:, 1], theta, pairs, nodes, (x, y))
                m = rve_stress(W, particle_stress_moment(as_state(moved)), V)[0]
                m = 0.5 * (m + m.T)
                sig.append(np.array([m[0, 0], m[1, 1], np.sqrt(2) * m[0, 1]]))
            fd[:, col] = (sig[0] - sig[1]) / (2 * strain)
        scale = np.abs(C).max()
        misfit[compression] = np.abs(fd - C).max() / scale
        assert misfit[compression] < np.median(k["depth_ratio"])
        assert np.abs(C[0, 1]) > 0.1 * scale and np.abs(C[1, 2]) > 0.05 * scale   # a full, anisotropic matrix
        # the tangential springs' share is far above the misfit: a wrong k_t would be seen
        kt_only = dict(k, k_n=0 * k["k_n"])
        assert np.abs(rve_voigt_stiffness(W, particle_voigt_moment(s0, kt_only), V)[0]).max() > 0.05 * scale
    assert misfit[2e-3] < 1e-2
    assert misfit[5e-4] == pytest.approx(misfit[2e-3] / 4, rel=0.1)


def test_fields_carry_the_voigt_stiffness_and_an_ensemble_takes_files_without_it():
    """compute_fields writes voigt_stiffness (Mandel, N/m) and its projections,
    masked where the RVE is; an ensemble of a file with and one without them
    (an older record) averages them over the one that has them."""
    d = 0.004 * (1 - 1e-3)
    x, y, c = square_lattice(20, 20, d, x0=-9.5 * d)
    state = make_state(x, y, square_nodes(0.004), c, attrs={"youngs_modulus": Y})
    params = parse_params('{"grid": {"x_min": -0.02, "x_max": 0.02, "y_min": 0.02, "y_max": 0.09, '
                          '"spacing": 0.01}, "rve": {"size": 0.02, "min_particles": 10}}')
    ds = compute_fields(as_state(state), None, params, ())
    C = ds["voigt_stiffness"]
    assert C.dims == ("y", "x", "mandel_i", "mandel_j") and C.attrs["units"] == "N m-1"
    assert list(ds["mandel_i"].values) == ["xx", "yy", "xy"]
    inside = ds["mask_reason"] == 0
    assert bool((np.isnan(C.isel(mandel_i=0, mandel_j=0)) == ~inside).all()) and int(inside.sum()) > 4
    K, G = isotropic_projection(C.values)
    np.testing.assert_array_equal(ds["voigt_bulk_modulus"].values, K)
    np.testing.assert_array_equal(ds["voigt_shear_modulus"].values, G)
    assert "voigt_depth_ratio_median" in ds.attrs and ds.attrs["voigt_sliding_fraction"] == 0.0

    from analysis.ensemble import ensemble_fields

    old = ds.drop_vars(["voigt_stiffness", "voigt_bulk_modulus", "voigt_shear_modulus", "mandel_i", "mandel_j"])
    ens = ensemble_fields([old, ds], ["old", "new"])
    np.testing.assert_array_equal(ens["voigt_bulk_modulus"].values, ds["voigt_bulk_modulus"].values)
    assert int(ens["voigt_bulk_modulus_count"].max()) == 1
    with pytest.raises(Exception, match="not in every file"):
        ensemble_fields([old.drop_vars("solid_fraction"), ds], ["old", "new"])


def test_the_comparison_with_the_fit_is_the_median_ratio_over_the_core(tmp_path, capsys):
    """A committed pile's fields with a Voigt K and G set to 2.5 and 4 times its
    own isotropic fit (average, m = 5) in the core: python -m analysis voigt
    gives those ratios over the core RVEs where both are finite, and another
    fit's ratio where its K differs."""
    from pathlib import Path

    from analysis.__main__ import main
    from analysis.elastic import moduli_dataset
    from analysis.netcdf import read_dataset, write_dataset
    from analysis.voigt import compare_with_fit

    params = parse_params("{}")
    ds = read_dataset(str(Path(__file__).parents[1] / "docs/reproduction/layered/seed6.fields.nc"))
    fit = moduli_dataset(ds, [], params).sel(fit="average", points=5)
    ds["voigt_bulk_modulus"] = (2.5 * fit["bulk_modulus"]).transpose("y", "x")
    ds["voigt_shear_modulus"] = (4.0 * fit["shear_modulus"]).transpose("y", "x")
    for v in ("voigt_bulk_modulus", "voigt_shear_modulus"):
        ds[v].attrs = {"units": "N m-1", "long_name": v}
    got = compare_with_fit(ds, moduli_dataset(ds, [], params))
    core = (np.abs(ds["x"]) <= 0.03) & (ds["y"] <= 0.05)
    n = int((np.isfinite(fit["bulk_modulus"]) & np.isfinite(fit["shear_modulus"]) & core).sum())
    assert got["average/m5"]["n"] == n > 3
    assert got["average/m5"]["bulk_ratio"] == pytest.approx(2.5, rel=1e-12)
    assert got["average/m5"]["shear_ratio"] == pytest.approx(4.0, rel=1e-12)
    assert got["modulus/m1"]["bulk_ratio"] != pytest.approx(2.5, rel=1e-3)
    path = tmp_path / "f.nc"
    write_dataset(ds, str(path), title="test", params=params)
    assert main(["voigt", "--fields", str(path), "--out", str(tmp_path / "v.json")]) == 0
    assert "Voigt/fit K 2.5, G 4 (median over" in capsys.readouterr().out


def test_formats_doc_names_the_voigt_variables():
    from test_formats_doc import Section

    sec = Section(("Fields",))
    for name in ("voigt_stiffness", "voigt_bulk_modulus", "voigt_shear_modulus", "mandel_i", "mandel_j",
                 "voigt_depth_ratio_median", "voigt_sliding_fraction"):
        assert sec.mentions(name), name
