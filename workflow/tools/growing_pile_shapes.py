"""Shape of a pile while it grows: what sets its angle of repose.

Reads state files of one pour taken at different times (copies of its
``pour.checkpoint.nc``, frames of a film, or the poured and relaxed states)
and prints one JSON line per file: simulated time, particles released,
particles in contact, height, both flank angles
(:func:`sim.measure.flank_angles`) and how many particles move faster than
1 cm/s.  Height and flanks are over the particles that touch another
particle or the support: during a pour the particles in flight above the top
(up to ``pour.release_height`` higher) would otherwise count as the pile's
top, which ``python -m sim summary`` does not need to exclude in the poured
and relaxed states (nothing flies there).

Usage::

    .venv/bin/python -m workflow.tools growing_pile_shapes STATE.nc [STATE.nc ...]
"""

import json

import numpy as np

from sim.io import StateFileError, load_simulation
from sim.measure import flank_angles

from ._cli import ToolParser, existing_file, refuse

MOVING = 0.01
"""Speed (m/s) above which a particle counts as moving."""


def in_contact(n, contact_i, contact_j):
    """Mask of the ``n`` particles that appear in a contact (``j = -1``: the support)."""
    touching = np.zeros(n, dtype=bool)
    touching[contact_i] = True
    touching[contact_j[contact_j >= 0]] = True
    return touching


def growing_shape(path):
    """The row of one state file (see the module docstring)."""
    sim, ds = load_simulation(path)
    n = sim.n
    x, y = sim.position[:n, 0], sim.position[:n, 1]
    radius = sim.shapes.radius[:n]
    touching = in_contact(n, ds["contact_i"].values, ds["contact_j"].values)
    left, right = flank_angles(x[touching], y[touching], radius[touching])
    speed = np.hypot(ds["vx"].values, ds["vy"].values)
    return {"state": str(path), "stage": ds.attrs.get("stage", ""), "time": float(ds.attrs["time"]),
            "particles": int(n), "in_contact": int(touching.sum()),
            "height": float(np.max(y[touching] + radius[touching])),
            "flank_left_deg": left, "flank_right_deg": right,
            "moving": int(np.sum(speed[touching] > MOVING))}


def main(argv=None):
    """Command line: one JSON line per state file."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("states", nargs="+", type=existing_file, help="state files of one pour (.nc)")
    for path in ap.parse_args(argv).states:
        try:
            row = growing_shape(path)
        except StateFileError as exc:   # its own one line names the file and what is wrong
            refuse(str(exc))
        print(json.dumps(row), flush=True)
