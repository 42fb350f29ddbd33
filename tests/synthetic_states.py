"""Synthetic particle-state files that follow docs/formats.md#state-files.

Builders return plain dicts of arrays; :func:`to_dataset` / :func:`write_state`
turn them into contract datasets/files. Every geometry is simple enough that
stresses, strains and fabrics can be computed by hand.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from analysis.general_elastic import stiffness_axes

DENSITY = 1000.0  # kg/m² (2D)


def square_nodes(a: float) -> np.ndarray:
    """Corners of a square of side ``a`` around its centre, counter-clockwise."""
    h = a / 2
    return np.array([[-h, -h], [h, -h], [h, h], [-h, h]])


def hexagon_nodes(apothem: float) -> np.ndarray:
    """Regular hexagon whose edge normals point at 0°, 60°, …, counter-clockwise."""
    R = apothem / np.cos(np.pi / 6)
    ang = np.radians(30 + 60 * np.arange(6))
    return np.column_stack([R * np.cos(ang), R * np.sin(ang)])


def polygon_area(nodes: np.ndarray) -> float:
    x, y = nodes[:, 0], nodes[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def make_state(x, y, nodes, contacts=None, gravity=9.81, density=DENSITY, theta=None, attrs=None) -> dict:
    """Assemble a state dict; ``nodes`` is one (k, 2) array for all particles or a list of them.

    ``contacts`` is a dict with ``i, j, cx, cy, fx, fy`` (and optionally ``nx, ny``).
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = x.size
    if isinstance(nodes, np.ndarray) and nodes.ndim == 2:
        nodes = [nodes] * n
    area = np.abs(np.array([polygon_area(p) for p in nodes]))
    mass = density * area
    inertia = np.abs(np.array([density * _second_moment(p) for p in nodes]))
    c = contacts or {}
    i = np.asarray(c.get("i", []), np.int64)
    j = np.asarray(c.get("j", []), np.int64)
    cx, cy = np.asarray(c.get("cx", []), float), np.asarray(c.get("cy", []), float)
    fx, fy = np.asarray(c.get("fx", np.zeros(i.size)), float), np.asarray(c.get("fy", np.zeros(i.size)), float)
    if "nx" in c:
        nx_, ny_ = np.asarray(c["nx"], float), np.asarray(c["ny"], float)
    else:
        # normal from i towards j (towards -y for the support)
        other = np.where(j[:, None] >= 0, np.column_stack([x[np.maximum(j, 0)], y[np.maximum(j, 0)]]),
                         np.column_stack([x[i], np.full(i.size, -np.inf)]))
        d = other - np.column_stack([x[i], y[i]])
        d = np.where(np.isfinite(d), d, np.array([0.0, -1.0]))
        nrm = np.hypot(d[:, 0], d[:, 1])
        nrm[nrm == 0] = 1
        nx_, ny_ = d[:, 0] / nrm, d[:, 1] / nrm
    return {
        "x": x, "y": y, "theta": np.zeros(n) if theta is None else np.asarray(theta, float),
        "vx": np.zeros(n), "vy": np.zeros(n), "omega": np.zeros(n),
        "mass": mass, "inertia": inertia, "area": area,
        "node_count": np.array([len(p) for p in nodes], np.int32),
        "node_x": np.concatenate([p[:, 0] for p in nodes]), "node_y": np.concatenate([p[:, 1] for p in nodes]),
        "contact_i": i.astype(np.int32), "contact_j": j.astype(np.int32), "contact_x": cx, "contact_y": cy,
        "force_x": fx, "force_y": fy, "normal_x": nx_, "normal_y": ny_, "overlap_area": np.full(i.size, 1e-9),
        "attrs": {"time": 1.0, "gravity": float(gravity), "protocol": "synthetic", "seed": 0,
                  "youngs_modulus": 1e7, "damping": 0.1, "friction": 0.5, "density": density,
                  "dt": 1e-6, "integrator": "gear5", "config": "{}", **(attrs or {})},
    }


def _second_moment(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cr = x * y1 - x1 * y
    return float(np.sum(cr * (x * x + x * x1 + x1 * x1 + y * y + y * y1 + y1 * y1)) / 12)


PARTICLE = ("x", "y", "theta", "vx", "vy", "omega", "mass", "inertia", "area", "node_count")
NODE = ("node_x", "node_y")
CONTACT = ("contact_i", "contact_j", "contact_x", "contact_y", "force_x", "force_y", "normal_x", "normal_y",
           "overlap_area")
UNITS = {"x": "m", "y": "m", "theta": "rad", "vx": "m s-1", "vy": "m s-1", "omega": "rad s-1", "mass": "kg",
         "inertia": "kg m2", "area": "m2", "node_count": "1", "node_x": "m", "node_y": "m", "contact_i": "1",
         "contact_j": "1", "contact_x": "m", "contact_y": "m", "force_x": "N", "force_y": "N", "normal_x": "1",
         "normal_y": "1", "overlap_area": "m2"}


def to_dataset(state: dict) -> xr.Dataset:
    data = {}
    for names, dim in ((PARTICLE, "particle"), (NODE, "node"), (CONTACT, "contact")):
        for k in names:
            data[k] = xr.Variable(dim, state[k], {"units": UNITS[k], "long_name": k})
    return xr.Dataset(data, attrs=dict(state["attrs"]))


def write_state(path, state: dict) -> str:
    to_dataset(state).to_netcdf(path)
    return str(path)


def square_lattice(ncol: int, nrow: int, a: float, x0: float = 0.0, y0: float | None = None,
                   vertical: bool = True, horizontal: bool = True, support: bool = True):
    """Squares of side ``a`` on a touching square lattice, lowest row resting on y = 0.

    Returns ``(x, y, contacts)`` with zero forces; contact points are the
    midpoints of the shared edges.
    """
    y0 = a / 2 if y0 is None else y0
    cc, rr = np.meshgrid(np.arange(ncol), np.arange(nrow))
    idx = rr * ncol + cc
    x = (x0 + cc * a).ravel().astype(float)
    y = (y0 + rr * a).ravel().astype(float)
    I, J, CX, CY = [], [], [], []
    if horizontal:
        a_, b_ = idx[:, :-1].ravel(), idx[:, 1:].ravel()
        I.append(a_), J.append(b_), CX.append(x[a_] + a / 2), CY.append(y[a_])
    if vertical:
        a_, b_ = idx[:-1, :].ravel(), idx[1:, :].ravel()
        I.append(a_), J.append(b_), CX.append(x[a_]), CY.append(y[a_] + a / 2)
    if support:
        a_ = idx[0, :].ravel()
        I.append(a_), J.append(np.full(a_.size, -1)), CX.append(x[a_]), CY.append(y[a_] - a / 2)
    cat = (lambda L: np.concatenate(L) if L else np.zeros(0))
    return x, y, {"i": cat(I).astype(np.int64), "j": cat(J).astype(np.int64), "cx": cat(CX), "cy": cat(CY)}


def step_pyramid(n_base: int, a: float, slope: float = 0.5, gravity: float = 9.81, x_centre: float = 0.0,
                 density: float = DENSITY) -> dict:
    """A static heap of squares: columns of heights ``h_c``, exactly balanced by vertical forces.

    Column ``c`` holds ``h_c = max(1, round(h_max - slope*|c - c0|))`` squares.
    The support pushes the bottom square up with the column weight; the
    square at level ``k`` carries the ``h_c - k - 1`` squares above it;
    horizontal neighbours touch with zero force. Every particle is in force
    and torque balance, so Love's sum rule and the support reaction hold
    exactly.
    """
    c0 = (n_base - 1) / 2
    heights = np.maximum(1, np.round((n_base / 2) * slope - slope * np.abs(np.arange(n_base) - c0))).astype(int)
    xs, ys, col, lev = [], [], [], []
    for c, h in enumerate(heights):  # builder only; small loops over columns
        xs.append(np.full(h, x_centre + (c - c0) * a))
        ys.append(a / 2 + a * np.arange(h))
        col.append(np.full(h, c))
        lev.append(np.arange(h))
    x, y, col, lev = map(np.concatenate, (xs, ys, col, lev))
    n = x.size
    index = {(int(c), int(k)): p for p, (c, k) in enumerate(zip(col, lev))}
    m = density * a * a
    I, J, CX, CY, FX, FY = [], [], [], [], [], []
    for p in range(n):
        c, k, h = int(col[p]), int(lev[p]), int(heights[col[p]])
        if k == 0:
            I.append(p), J.append(-1), CX.append(x[p]), CY.append(0.0), FX.append(0.0), FY.append(h * m * gravity)
        if k + 1 < h:
            q = index[(c, k + 1)]
            I.append(p), J.append(q), CX.append(x[p]), CY.append(y[p] + a / 2)
            FX.append(0.0), FY.append(-(h - k - 1) * m * gravity)
        if (c + 1, k) in index:
            q = index[(c + 1, k)]
            I.append(p), J.append(q), CX.append(x[p] + a / 2), CY.append(y[p]), FX.append(0.0), FY.append(0.0)
    contacts = {"i": I, "j": J, "cx": CX, "cy": CY, "fx": FX, "fy": FY}
    return make_state(x, y, square_nodes(a), contacts, gravity=gravity, density=density)


def displaced(state: dict, du: np.ndarray, force_scale: float = 1.0, gravity: float | None = None) -> dict:
    """A copy of ``state`` with centres (and contact points, by the mean of the pair) moved by ``du`` (n, 2)."""
    s = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in state.items()}
    s["attrs"] = dict(state["attrs"])
    s["x"] = state["x"] + du[:, 0]
    s["y"] = state["y"] + du[:, 1]
    i, j = state["contact_i"], state["contact_j"]
    dj = np.where(j[:, None] >= 0, du[np.maximum(j, 0)], du[i])
    s["contact_x"] = state["contact_x"] + 0.5 * (du[i, 0] + dj[:, 0])
    s["contact_y"] = state["contact_y"] + 0.5 * (du[i, 1] + dj[:, 1])
    s["force_x"] = state["force_x"] * force_scale
    s["force_y"] = state["force_y"] * force_scale
    if gravity is not None:
        s["attrs"]["gravity"] = float(gravity)
    return s


def hex_lattice(ncol: int, nrow: int, d: float, x0: float = 0.0, y0: float | None = None, jitter: float = 0.0,
                seed: int = 0):
    """Regular hexagons (apothem d/2) on a triangular lattice of spacing ``d``; rows horizontal.

    Every interior particle touches six neighbours at 0°, 60°, …, 300° (contact
    points at the midpoints of the shared edges). ``jitter`` (m) displaces the
    centres randomly after the contact list is built (for strain tests).
    Returns ``(x, y, contacts, nodes)``; the lowest row does not touch the support.
    """
    from scipy.spatial import cKDTree

    y0 = d if y0 is None else y0
    cc, rr = np.meshgrid(np.arange(ncol), np.arange(nrow))
    x = (x0 + cc * d + (rr % 2) * d / 2).ravel().astype(float)
    y = (y0 + rr * d * np.sqrt(3) / 2).ravel().astype(float)
    pairs = np.array(sorted(cKDTree(np.column_stack([x, y])).query_pairs(d * 1.001)))
    i, j = pairs[:, 0], pairs[:, 1]
    contacts = {"i": i, "j": j, "cx": 0.5 * (x[i] + x[j]), "cy": 0.5 * (y[i] + y[j])}
    if jitter:
        rng = np.random.default_rng(seed)
        x = x + jitter * rng.uniform(-1, 1, x.size)
        y = y + jitter * rng.uniform(-1, 1, y.size)
        contacts["cx"] = 0.5 * (x[i] + x[j])
        contacts["cy"] = 0.5 * (y[i] + y[j])
    return x, y, contacts, hexagon_nodes(d / 2)


def as_state(state: dict, path: str = "<synthetic>"):
    """Validate a state dict through the contract reader and return an ``analysis.states.State``."""
    from analysis.states import state_from_dataset

    return state_from_dataset(to_dataset(state), path)


def mapped_hex_lattice(n: int, apothem: float, mapping: np.ndarray, compression: float = 0.0):
    """Translates of one centrally symmetric hexagon tiling the plane, pressed together.

    The regular hexagon of :func:`hexagon_nodes` and its triangular lattice
    (neighbours at ``2 apothem`` along 0°, 60°, 120°) are mapped by the
    linear ``mapping`` (2 × 2, positive determinant): the result still tiles
    the plane, face to face, but its faces differ in length and their normals
    are no longer along the branch vectors.  Centres on an ``n × n`` patch
    around the origin, then brought closer by the factor ``1 − compression``,
    so that every pair of face neighbours overlaps by the depth
    ``compression × (n · l)`` and no other pair touches.

    Returns
    -------
    x, y : numpy.ndarray
        Centres.
    pairs : numpy.ndarray
        ``(k, 2)`` face-neighbour pairs ``(i, j)``, each once.
    nodes : numpy.ndarray
        ``(6, 2)`` corners of the mapped hexagon about its centre, counter-clockwise.
    lattice : numpy.ndarray
        ``(3, 2)`` branch vectors ``x_j − x_i`` of the three neighbour
        directions of the pairs (before the compression).
    """
    mapping = np.asarray(mapping, float)
    d = 2.0 * apothem
    a = np.array([[d, 0.0], [0.5 * d, 0.5 * np.sqrt(3.0) * d]]) @ mapping.T       # rows: lattice vectors
    lattice = np.array([a[0], a[1], a[1] - a[0]])
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    index = ii * n + jj
    frac = np.column_stack([ii.ravel(), jj.ravel()]) - (n - 1) / 2.0
    centres = (1.0 - compression) * frac @ a
    pairs = []
    for di, dj in ((1, 0), (0, 1), (-1, 1)):
        ok = (ii + di >= 0) & (ii + di < n) & (jj + dj < n)
        pairs.append(np.column_stack([index[ok], (ii[ok] + di) * n + jj[ok] + dj]))
    return centres[:, 0], centres[:, 1], np.concatenate(pairs), hexagon_nodes(apothem) @ mapping.T, lattice


def mandel_stress(c: np.ndarray, strains: np.ndarray) -> np.ndarray:
    """Stress tensors ``(..., 2, 2)`` of the Mandel stiffness ``c`` (``(3, 3)`` or one per
    strain, ``(..., 3, 3)``) under the strain tensors ``(..., 2, 2)``: ``σ_M = C u_M``."""
    u = np.stack((strains[..., 0, 0], strains[..., 1, 1],
                  np.sqrt(2) * 0.5 * (strains[..., 0, 1] + strains[..., 1, 0])), axis=-1)
    s = np.einsum("...ij,...j->...i", c, u)
    out = np.empty(strains.shape)
    out[..., 0, 0], out[..., 1, 1] = s[..., 0], s[..., 1]
    out[..., 0, 1] = out[..., 1, 0] = s[..., 2] / np.sqrt(2)
    return out


#: A linear pile's strain under a change of g_y, of g_x and under the support stretch.
PROBE_SHAPES = {"y": np.array([[-0.3e-4, 0.2e-5], [0.2e-5, 1.0e-4]]),
                "x": np.array([[0.4e-5, 0.6e-4], [0.6e-4, -0.2e-5]]),
                "stretched": np.array([[1.0e-4, 0.1e-4], [0.1e-4, -0.3e-4]])}
#: (change of g_y, of g_x) of each gravity probe, in units of the shapes' loads.
GRAVITY_PROBES = {"reduced": (1.0, 0.0), "tiltp05": (0.0, 1.0), "tiltm05": (0.0, -1.0)}


def linear_probe_pile(c_field: np.ndarray, x: np.ndarray, y: np.ndarray, rng) -> tuple[xr.Dataset, xr.Dataset]:
    """Probe increments (``probes.nc``) and fields of a pile of a linear material of Mandel stiffness
    ``c_field`` ``(ny, nx, 3, 3)`` on the grid ``y``, ``x``: the gravity reduction and two tilts (their
    strains in the two shapes a linear pile's gravity changes give, each RVE with its own amplitude
    drawn from ``rng``) and the support stretch; fields with fabric axes 10° and stress axes −85° off
    each RVE's stiffest axis, the Voigt stiffness 2 C and the reduction's increments."""
    ny, nx = c_field.shape[:2]
    amp = 1.0 + 0.2 * rng.normal(size=(ny, nx, 1, 1))
    strains = {name: amp * (dy * PROBE_SHAPES["y"] + dx * PROBE_SHAPES["x"])
               for name, (dy, dx) in GRAVITY_PROBES.items()}
    strains["stretched"] = amp * PROBE_SHAPES["stretched"]
    probes = list(strains)
    strain = np.array([strains[p] for p in probes])
    stress = mandel_stress(c_field[None], strain)
    dims = ("probe", "y", "x", "i", "j")
    coords = {"y": y, "x": x, "i": ["x", "y"], "j": ["x", "y"]}
    probe_ds = xr.Dataset({"stress_increment": (dims, stress), "strain_increment": (dims, strain)},
                          coords={"probe": probes, **coords}, attrs={"protocol": "wedge", "seed": "1"})
    axis = stiffness_axes(c_field)["axis_deg"]
    fields = xr.Dataset({"fabric_orientation": (("y", "x"), axis - 10.0),
                         "stress_orientation": (("y", "x"), axis + 85.0),
                         "voigt_stiffness": (("y", "x", "mandel_i", "mandel_j"), 2.0 * c_field),
                         "stress_increment": (dims[1:], stress[0]), "strain_increment": (dims[1:], strain[0])},
                        coords=coords)
    return probe_ds, fields
