"""The general 2D elastic fit (analysis.general_elastic): a known anisotropic
stiffness is recovered from its own stress-strain samples to rounding; one
probe (strains all in one direction) is reported as not identifying it, and
so are gravity probes of any number (their strains span two shapes); the
isotropic and cubic laws of the paper are its special cases, with the
directional Young's modulus of analysis.elastic's closed forms; the stiffness
axis turns with the material, checked against a rotation of the fourth-order
tensor built independently of the Mandel algebra; and a lattice of
identical hexagons, with the simulator's contact forces under three affine
strains, has the affine Voigt stiffness of its closed form."""

import numpy as np
import pytest

from analysis import general_elastic as ge
from analysis.elastic import cubic_engineering_moduli, youngs_modulus_2d

RNG = np.random.default_rng(14)


def sym(a):
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def random_stiffness(scale=1e6):
    """A symmetric positive definite Mandel stiffness with no symmetry of the material."""
    q = RNG.normal(size=(3, 3))
    return scale * (q @ q.T + 0.5 * np.eye(3))


def stress_of(c, strains):
    """Δσ (…, 2, 2) of Mandel stiffness `c` for strains (…, 2, 2), by the Mandel rules."""
    s = np.einsum("ij,...j->...i", c, ge.mandel(strains))
    out = np.empty(strains.shape)
    out[..., 0, 0], out[..., 1, 1] = s[..., 0], s[..., 1]
    out[..., 0, 1] = out[..., 1, 0] = s[..., 2] / np.sqrt(2)
    return out


def test_a_known_anisotropic_stiffness_is_recovered_to_rounding():
    c = random_stiffness()
    strains = sym(RNG.normal(scale=1e-4, size=(4, 3, 5, 2, 2)))   # 4x3 RVEs, 5 samples each
    fit = ge.fit_general_stiffness(stress_of(c, strains), strains)
    assert np.all(fit["flag"] == 0) and np.all(fit["n_samples"] == 5)
    np.testing.assert_allclose(fit["stiffness"], np.broadcast_to(c, (4, 3, 3, 3)), rtol=1e-9,
                               atol=1e-9 * np.abs(c).max())
    assert np.all(fit["condition"] < 50)
    assert ge.explained_fraction(fit["stiffness"], stress_of(c, strains), strains) == \
        pytest.approx(np.ones((4, 3)), abs=1e-12)


def test_invalid_samples_are_left_out():
    c = random_stiffness()
    strains = sym(RNG.normal(scale=1e-4, size=(6, 2, 2)))
    sigma = stress_of(c, strains)
    sigma[2, 0, 0] = np.nan
    strains[4] = np.nan
    fit = ge.fit_general_stiffness(sigma, strains)
    assert fit["n_samples"] == 4 and fit["flag"] == 0
    np.testing.assert_allclose(fit["stiffness"], c, rtol=1e-9)
    lone = ge.fit_general_stiffness(sigma[:1], strains[:1])
    assert lone["flag"] & ge.GENERAL_INSUFFICIENT_SAMPLES and np.isnan(lone["stiffness"]).all()


def test_one_probe_does_not_identify_the_general_stiffness():
    """A gravity reduction at five neighbouring points: strains of one shape,
    amplitudes and directions differing by a percent. The stresses are fitted,
    but the condition number says the six constants are not pinned."""
    c = random_stiffness()
    base = np.array([[-1.0e-4, 2.0e-5], [2.0e-5, 3.0e-4]])
    strains = np.array([(1 + 0.1 * k) * base + 1e-6 * sym(RNG.normal(size=(2, 2)))
                        for k in range(5)])
    fit = ge.fit_general_stiffness(stress_of(c, strains), strains)
    assert fit["condition"] > ge.MAX_CONDITION
    assert fit["flag"] & ge.GENERAL_NOT_IDENTIFIED and np.isnan(fit["stiffness"]).all()
    # three probes of independent strain shapes at the same points do identify it
    shapes = [np.array([[2.0e-4, 0.0], [0.0, -1.0e-4]]), np.array([[0.0, 2.0e-4], [2.0e-4, 0.0]])]
    three = np.concatenate([strains] + [np.array([(1 + 0.1 * k) * t for k in range(5)]) for t in shapes])
    fit3 = ge.fit_general_stiffness(stress_of(c, three), three)
    assert fit3["flag"] == 0 and fit3["condition"] < 10
    np.testing.assert_allclose(fit3["stiffness"], c, rtol=1e-9)


def test_gravity_probes_alone_pin_five_of_the_six_constants():
    """In a linear elastic pile the strain at a point is linear in the change
    of gravity, a vector with two components: whatever reductions and tilts
    are probed, the strains at one point span two shapes, and the symmetric
    C + t w w^T (w normal to both) fits them all as well as C does."""
    c = random_stiffness()
    shape_y = np.array([[-0.3e-4, 0.2e-5], [0.2e-5, 1.0e-4]])    # response to a change of g_y
    shape_x = np.array([[0.4e-5, 0.6e-4], [0.6e-4, -0.2e-5]])    # response to a change of g_x
    probes = [(0.10, 0.0), (0.0, 0.05), (0.0, -0.05), (0.05, 0.02)]   # (reduction, tilt)
    strains = np.array([dy * shape_y + dx * shape_x for dy, dx in probes]) * 10
    fit = ge.fit_general_stiffness(stress_of(c, strains), strains)
    assert fit["condition"] > 1e10 and fit["flag"] & ge.GENERAL_NOT_IDENTIFIED
    w = np.cross(ge.mandel(shape_y), ge.mandel(shape_x))
    other = c + 1e5 * np.outer(w, w) / (w @ w)
    np.testing.assert_allclose(stress_of(other, strains), stress_of(c, strains), rtol=1e-9, atol=1e-9)


def test_the_isotropic_law_is_a_special_case():
    K, G = 8.0e5, 3.0e5
    c = ge.isotropic_stiffness(K, G)
    strains = sym(RNG.normal(scale=1e-4, size=(7, 2, 2)))
    sigma = stress_of(c, strains)
    # the paper's definitions: tr Δσ = 2K tr Δu, deviators 2G
    tr = np.trace(sigma, axis1=-2, axis2=-1)
    np.testing.assert_allclose(tr, 2 * K * np.trace(strains, axis1=-2, axis2=-1), rtol=1e-12)
    np.testing.assert_allclose(sigma[:, 0, 1], 2 * G * strains[:, 0, 1], rtol=1e-12)
    axes = ge.stiffness_axes(c)
    assert axes["anisotropy"] == pytest.approx(1.0, abs=1e-12) and np.isnan(axes["axis_deg"])
    np.testing.assert_allclose(ge.directional_modulus(c), youngs_modulus_2d(K, G), rtol=1e-12)
    assert ge.explained_fraction(c, sigma, strains) == pytest.approx(1.0, abs=1e-12)


def test_the_cubic_law_and_its_moduli_along_the_axes_and_bisectors():
    l1, l2, l3 = 1.2e6, 0.4e6, 0.15e6
    c = ge.cubic_stiffness(l1, l2, l3)
    eng = cubic_engineering_moduli(l1, l2, l3)
    e = ge.directional_modulus(c, np.array([0.0, 90.0, 45.0, -45.0]))
    np.testing.assert_allclose(e[:2], eng["E_p"], rtol=1e-12)      # along y and x
    np.testing.assert_allclose(e[2:], eng["E_b"], rtol=1e-12)      # along the bisectors
    axes = ge.stiffness_axes(c)
    # lambda3 < (lambda1 - lambda2)/2: stiffest along the cube axes, E(0) = E(90 deg),
    # the first of them on the grid of directions is the vertical
    assert eng["E_p"] > eng["E_b"] and axes["axis_deg"] == 0.0
    assert axes["anisotropy"] == pytest.approx(eng["E_p"] / eng["E_b"], rel=1e-4)


def fourth_order(c):
    """C_ijkl of a Mandel stiffness, element by element (σ_ij = C_ijkl u_kl)."""
    index = {(0, 0): 0, (1, 1): 1, (0, 1): 2, (1, 0): 2}
    weight = {0: 1.0, 1: 1.0, 2: 1.0 / np.sqrt(2)}
    out = np.zeros((2, 2, 2, 2))
    for (i, j), a in index.items():
        for (k, l), b in index.items():
            out[i, j, k, l] = c[a, b] * weight[a] * weight[b]
    return out


def test_the_stiffness_axis_turns_with_the_material():
    """A material stiffest along x (E_max at 90 deg from the vertical), rotated
    by beta counter-clockwise as a fourth-order tensor: its axis is at 90 + beta."""
    c = np.diag([3.0e6, 1.0e6, 0.8e6])
    c[0, 1] = c[1, 0] = 0.3e6
    for beta in (20.0, -35.0, 60.0):
        b = np.radians(beta)
        r = np.array([[np.cos(b), -np.sin(b)], [np.sin(b), np.cos(b)]])
        rotated4 = np.einsum("ia,jb,kc,ld,abcd->ijkl", r, r, r, r, fourth_order(c))
        strains = sym(RNG.normal(scale=1e-4, size=(6, 2, 2)))
        sigma = np.einsum("ijkl,nkl->nij", rotated4, strains)
        fit = ge.fit_general_stiffness(sigma, strains)
        axes = ge.stiffness_axes(fit["stiffness"])
        expected = (90.0 + beta + 90.0) % 180.0 - 90.0
        assert axes["axis_deg"] == pytest.approx(expected, abs=0.5), beta
        unrotated = ge.stiffness_axes(c)
        assert axes["anisotropy"] == pytest.approx(unrotated["anisotropy"], rel=1e-3)


def probe_file(stress, strain, probes):
    """A per-pile probe file as python -m analysis probes writes it."""
    import xarray as xr

    n_probe, ny, nx = stress.shape[:3]
    dims = ("probe", "y", "x", "i", "j")
    return xr.Dataset({"stress_increment": (dims, stress), "strain_increment": (dims, strain)},
                      coords={"probe": probes, "y": 0.01 * np.arange(ny), "x": 0.01 * np.arange(nx),
                              "i": ["x", "y"], "j": ["x", "y"]}, attrs={"protocol": "wedge"})


def test_the_ensemble_fit_recovers_the_stiffness_with_its_scatter_and_the_reversibility():
    """Five piles of one material C, each probed in three load shapes with
    strains that differ from pile to pile, and restored to 30 % of the
    reduction's strain: the fit of the ensemble means is C, identified, with
    standard errors zero to rounding (every pile's fit is C too); the general
    law explains everything, the isotropic one less; reversibility 0.7."""
    from analysis.params import parse_params
    from analysis.probes import general_fit_dataset

    c = random_stiffness()
    probes = ["reduced", "tiltp05", "tiltm05", "restored"]
    piles = []
    for _ in range(5):
        shapes = sym(RNG.normal(scale=1e-4, size=(3, 1, 1, 2, 2)))
        strain = shapes * (1 + 0.05 * RNG.normal(size=(3, 3, 4, 1, 1)))       # (probe, y, x, 2, 2)
        restored = 0.3 * strain[:1]
        strain = np.concatenate([strain, restored])
        stress = stress_of(c, strain)
        stress[3] = 0.0                                                        # unloaded again
        piles.append(probe_file(stress, strain, probes))
    ds = general_fit_dataset(piles, parse_params('{"moduli": {"min_points": 3}}'))
    assert ds.attrs["loading_probes"] == "reduced tiltp05 tiltm05" and ds.attrs["n_seeds"] == 5
    for m in (1, 5):
        fit = ds.sel(points=m)
        inner = fit.isel(y=1, x=slice(1, 3))
        assert (inner["general_flag"] == 0).all()
        np.testing.assert_allclose(inner["stiffness"].values, np.broadcast_to(c, (2, 3, 3)), rtol=1e-8)
        assert float(np.nanmax(inner["stiffness_sem"].values)) <= 1e-8 * np.abs(c).max()
        assert np.allclose(inner["explained_general"].values, 1.0, atol=1e-10)
        assert (inner["explained_isotropic"].values < inner["explained_general"].values).all()
    np.testing.assert_allclose(ds["reversibility"].values, 0.7, rtol=1e-12)
    assert (ds["reversibility_count"].values == 5).all()


def test_a_pile_that_slipped_under_a_probe_is_left_out_of_the_fit_there_but_not_of_the_reversibility():
    """Four piles of one material; one of them slips at one RVE under the
    tilt (a strain 60 times its median there, with a stress that does not
    follow C).  With the slip rule (ratio 10) that pile's tilt is left out
    there, counted in slip_left_out, and the fit of the other samples is C
    again; without it (null) the fit there is not C.  The reversibility
    keeps the slipped pile: the slip comes back only to 0.3 there."""
    from analysis.params import parse_params
    from analysis.probes import general_fit_dataset

    c = random_stiffness()
    probes = ["reduced", "tiltp05", "tiltm05", "restored"]
    shapes = sym(RNG.normal(scale=1e-4, size=(3, 1, 1, 2, 2)))
    piles = []
    for k in range(4):
        strain = shapes * (1 + 0.05 * RNG.normal(size=(3, 3, 4, 1, 1)))
        strain = np.concatenate([strain, 0.1 * strain[:1]])                  # restored: 0.9 comes back
        stress = stress_of(c, strain)
        stress[3] = 0.0
        if k == 2:                                                            # pile 2 slips at (1, 2) ...
            strain[1, 1, 2] *= 60.0
            stress[1, 1, 2] *= 3.0
            strain[0, 1, 2] = 60.0 * strain[0, 1, 2]                           # ... under the reduction too,
            stress[0, 1, 2] = 3.0 * stress[0, 1, 2]
            strain[3, 1, 2] = 0.7 * strain[0, 1, 2]                            # and keeps most of it
        piles.append(probe_file(stress, strain, probes))
    ds = general_fit_dataset(piles, parse_params('{"moduli": {"min_points": 3}}'))
    out = ds["slip_left_out"]
    assert int(out.sel(probe="tiltp05").values[1, 2]) == 1 and int(out.sel(probe="reduced").values[1, 2]) == 1
    assert int(out.sum()) == 2 and ds.attrs["slip_left_out_total"] == 2
    assert int(out.sel(probe="restored").sum()) == 0
    fit = ds.sel(points=1)
    np.testing.assert_allclose(fit["stiffness"].values[1, 2], c, rtol=1e-8)
    expected_rev = np.array([0.9, 0.9, 0.3, 0.9])
    assert float(ds["reversibility"].values[1, 2]) == pytest.approx(expected_rev.mean(), rel=1e-12)
    assert float(ds["reversibility"].values[1, 1]) == pytest.approx(0.9, rel=1e-12)
    plain = general_fit_dataset(piles, parse_params('{"moduli": {"min_points": 3}, '
                                                    '"ensemble": {"slip_strain_ratio": null}}'))
    assert int(plain["slip_left_out"].sum()) == 0
    got = plain.sel(points=1)["stiffness"].values[1, 2]
    assert not np.allclose(got, c, rtol=1e-2)


def test_probe_increments_are_the_imposed_strains_of_each_probe():
    """A jittered hexagon packing displaced affinely in two different ways (two
    probes): python -m analysis probes gives each probe's imposed strain
    (symmetric part) at every filled RVE, its reduced entry is the fields'
    increment of that stage, and a probe that only scales the contact forces
    by 1.2 has the stress increment 0.2 sigma."""
    from synthetic_states import as_state, displaced, hex_lattice, make_state

    from analysis.fields import compute_fields
    from analysis.params import parse_params
    from analysis.probes import probe_increments

    x, y, c, nodes = hex_lattice(24, 24, 0.007, jitter=0.0015, seed=3)
    base = make_state(x, y, nodes, c)
    base["force_y"] = np.full(base["force_y"].shape, -0.01)       # some stress to change
    r = np.column_stack([base["x"], base["y"]])
    eps = {"reduced": np.array([[2.0e-4, -3.0e-4], [0.7e-4, -1.1e-4]]),
           "tiltp05": np.array([[-1.0e-4, 0.5e-4], [0.9e-4, 3.0e-4]])}
    probes = {k: as_state(displaced(base, r @ e)) for k, e in eps.items()}
    probes["tiltm05"] = as_state(displaced(base, 0.0 * r, force_scale=1.2))
    params = parse_params('{"grid": {"x_min": 0.06, "x_max": 0.1, "y_min": 0.06, "y_max": 0.1, '
                          '"spacing": 0.02}, "rve": {"size": 0.05, "min_particles": 10}}')
    relaxed = as_state(base)
    ds = probe_increments(relaxed, probes, params)
    assert list(ds["probe"].values) == ["reduced", "tiltp05", "tiltm05"]
    for k, stage in enumerate(["reduced", "tiltp05"]):
        u = ds["strain_increment"].values[k]
        filled = np.isfinite(u[..., 0, 0])
        assert filled.sum() >= 4
        np.testing.assert_allclose(u[filled], np.broadcast_to(sym(eps[stage]), u[filled].shape),
                                   atol=1e-12)
    fields = compute_fields(relaxed, probes["reduced"], params, ("strain",))
    np.testing.assert_array_equal(ds["stress_increment"].values[0], fields["stress_increment"].values)
    np.testing.assert_array_equal(ds["strain_increment"].values[0], fields["strain_increment"].values)
    filled = np.isfinite(fields["stress"].values[..., 0, 0])
    np.testing.assert_allclose(ds["stress_increment"].values[2][filled], 0.2 * fields["stress"].values[filled],
                               rtol=1e-12)


def test_a_fit_that_is_not_positive_definite_is_flagged_and_has_no_axes():
    c = np.diag([2.0e6, 1.0e6, -0.3e6])                  # a shear that releases energy
    strains = sym(RNG.normal(scale=1e-4, size=(6, 2, 2)))
    fit = ge.fit_general_stiffness(stress_of(c, strains), strains)
    assert fit["flag"] == ge.GENERAL_NOT_POSITIVE
    np.testing.assert_allclose(fit["stiffness"], c, rtol=1e-9, atol=1e-3)
    axes = ge.stiffness_axes(fit["stiffness"])
    assert all(np.isnan(axes[k]) for k in ("axis_deg", "anisotropy", "E_max", "E_min"))


def lattice_state(x, y, pairs, nodes, ref_x, ref_y, youngs_modulus, friction):
    """A state of the hexagon lattice whose contact forces are the simulator's.

    Overlap area, force point and normal come from the simulator's narrow
    phase (:func:`sim.geometry.polygon_overlap`), the normal force from its
    law ``F = Y A / l`` with ``l`` the characteristic length of the force
    point's distances to both centres (:mod:`sim.contact_law`), and the
    Cundall–Strack spring from the relative tangential displacement of the
    pair since the reference ``(ref_x, ref_y)``: a quasi-static path without
    slip, loaded as one step of :func:`sim.contact_law.tangential_force`
    with no damping mass.  No particle rotates (the affine assumption).
    """
    from synthetic_states import make_state

    from sim.contact_law import characteristic_length, elastic_force, tangential_force
    from sim.geometry import polygon_overlap

    out = np.empty(10)
    eps = 1e-9 * float(np.max(np.hypot(nodes[:, 0], nodes[:, 1])))
    c = {k: [] for k in ("i", "j", "cx", "cy", "fx", "fy", "nx", "ny")}
    for i, j in pairs:
        assert polygon_overlap(nodes[:, 0] + x[i], nodes[:, 1] + y[i], nodes[:, 0] + x[j], nodes[:, 1] + y[j],
                               x[i], y[i], x[j], y[j], eps, out)
        area, sx, sy, nx, ny = out[0], out[5], out[6], out[7], out[8]
        l = characteristic_length(np.hypot(sx - x[i], sy - y[i]), np.hypot(sx - x[j], sy - y[j]))
        f_n = elastic_force(area, l, youngs_modulus)
        slide = ((x[i] - ref_x[i]) - (x[j] - ref_x[j])) * -ny + ((y[i] - ref_y[i]) - (y[j] - ref_y[j])) * nx
        f_t, _ = tangential_force(0.0, slide, f_n, 0.0, youngs_modulus, friction, 1.0)
        assert abs(f_t) < friction * f_n                                  # the contact sticks
        for k, v in zip(c, (i, j, sx, sy, -f_n * nx + f_t * ny, -f_n * ny - f_t * nx, nx, ny)):
            c[k].append(v)
    return make_state(x, y, nodes, {k: np.array(v) for k, v in c.items()})


def voigt_stiffness(nodes, branches, youngs_modulus, particles_per_area):
    """The affine (Voigt) Mandel stiffness of a lattice of identical
    centrally symmetric polygons in flat face-to-face contact, in closed form.

    ``C_ijkl = (N/V) Σ_c (k_n n_i l_j n_k l_l + k_t t_i l_j t_k l_l)`` over the
    contacts ``c`` of one particle counted once per pair (``branches``:
    one ``l`` per neighbour direction), symmetrised in ``ij`` and ``kl``.
    Two faces of length ``L`` pressed together by the depth ``δ`` overlap by
    ``A = L δ`` (to first order in ``δ / L``), and the force point of the
    symmetric pair lies halfway, at ``|l|/2`` from both centres, so the
    paper's ``F = Y A / l`` with ``l = r_i r_j / (r_i + r_j) = |l| / 4``
    gives ``k_n = dF/dδ = 4 Y L / |l|``; the Cundall–Strack spring gives
    ``k_t = (2/7) Y``.  ``n`` is the normal of the face that meets the
    neighbour, ``t = (−n_y, n_x)``.
    """
    c = np.zeros((3, 3))
    edges = np.roll(nodes, -1, axis=0) - nodes
    normals = np.column_stack([edges[:, 1], -edges[:, 0]]) / np.hypot(edges[:, 0], edges[:, 1])[:, None]
    for lv in branches:
        face = np.argmax(normals @ lv)                      # the face looking at the neighbour
        n = normals[face]
        t = np.array([-n[1], n[0]])
        k_n = 4.0 * youngs_modulus * np.hypot(*edges[face]) / np.hypot(*lv)
        k_t = 2.0 / 7.0 * youngs_modulus
        m, q = ge.mandel(np.outer(n, lv)), ge.mandel(np.outer(t, lv))
        c += k_n * np.outer(m, m) + k_t * np.outer(q, q)
    return particles_per_area * c


def test_a_lattice_of_hexagons_has_the_affine_voigt_stiffness():
    """Identical hexagons, stretched and turned so that their faces differ in
    length and face normals differ from branch vectors, tile the plane and are
    pressed together by 1e-4 of their spacing; three affine strains of 1e-6
    (no particle rotates), with contact forces from the simulator's narrow
    phase and force law, go through the whole probe chain (Eq. 2 stress,
    Cambou strain, general fit per RVE).  The fitted stiffness is the closed
    form of :func:`voigt_stiffness` over the RVE's own particles, to the
    neglected orders: the preload's share of the increments and the overlap
    corners, both ~δ/L ~ 2e-4, and the nonlinearity ~ε|l|/δ ~ 1e-2 of the
    corrections, so 1e-3 of the largest constant.  The lattice is anisotropic
    (E_max / E_min about 1.2) and the fit has its Young's modulus in every
    direction."""
    from synthetic_states import as_state, mapped_hex_lattice

    from analysis.params import parse_params
    from analysis.probes import general_fit_dataset, probe_increments

    Y, mu, eta, strain = 1e7, 0.5, 1e-4, 1e-6
    turn = np.radians(25.0)
    mapping = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]) @ np.diag([1.6, 1.0])
    x, y, pairs, nodes, lattice = mapped_hex_lattice(30, 0.003, mapping, compression=eta)
    x, y = x + 0.00123, y + 0.15037                     # no centre on an RVE edge
    relaxed = lattice_state(x, y, pairs, nodes, x, y, Y, mu)
    probes = {}
    for stage, e in (("reduced", [[1, 0], [0, 0]]), ("tiltp05", [[0, 0], [0, 1]]),
                     ("tiltm05", [[0, 0.5], [0.5, 0]])):
        du = np.column_stack([x, y]) @ (strain * np.array(e, float)).T
        probes[stage] = as_state(lattice_state(x + du[:, 0], y + du[:, 1], pairs, nodes, x, y, Y, mu))
    size = 0.05
    params = parse_params('{"grid": {"x_min": -0.02, "x_max": 0.02, "y_min": 0.13, "y_max": 0.17, '
                          '"spacing": 0.01}, "rve": {"size": %r, "min_particles": 10}, '
                          '"moduli": {"min_points": 3}}' % size)
    fit = general_fit_dataset([probe_increments(as_state(relaxed), probes, params)], params).sel(points=1)
    assert (fit["general_flag"] == 0).all() and float(fit["condition"].max()) < 10
    for iy, cy in enumerate(fit["y"].values):
        for ix, cx in enumerate(fit["x"].values):
            members = np.sum((np.abs(x - cx) <= size / 2) & (np.abs(y - cy) <= size / 2))
            expected = voigt_stiffness(nodes, (1 - eta) * lattice, Y, members / size ** 2)
            got = fit["stiffness"].values[iy, ix]
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-3 * np.abs(expected).max())
            closed = ge.stiffness_axes(expected)
            assert closed["anisotropy"] > 1.15
            assert ge.stiffness_axes(got)["anisotropy"] == pytest.approx(closed["anisotropy"], rel=1e-3)
            np.testing.assert_allclose(ge.directional_modulus(got), ge.directional_modulus(expected), rtol=1e-3)
