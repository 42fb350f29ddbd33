"""Writes ``tests/data/default_shapes.json``: a draw of the study's shapes as the
code drew them before ``particles.aspect_ratio`` existed.

:func:`sim.shapes.make_shapes` with every setting at its default, 20 particles
from ``numpy.random.default_rng(1)``: their corner counts, generating semi-axes
and body-frame corners, and the next integer the generator gives after the
draw (how far the draw moved the random stream).  The file was written at
the commit before the setting was added; tests/test_shape_aspect.py checks
that the default draw is still this one, so rerun this script only for a
change that is meant to change the study's shapes::

    .venv/bin/python tests/default_shapes.py
"""

import json
import subprocess
from pathlib import Path

import numpy as np

from sim.shapes import make_shapes

SEED = 1
N = 20
FILE = Path(__file__).parent / "data" / "default_shapes.json"


def draw(seed=SEED, n=N):
    """The default draw of ``n`` shapes from ``default_rng(seed)`` and the stream after it.

    Parameters
    ----------
    seed, n : int

    Returns
    -------
    shapes : sim.shapes.Shapes
    after : int
        The generator's next ``integers(2**62)`` after the draw.
    """
    rng = np.random.default_rng(seed)
    shapes = make_shapes(rng, n)
    return shapes, int(rng.integers(2**62))


def write(out=FILE):
    """Write the default draw to ``out`` (floats as Python writes them: exact)."""
    shapes, after = draw()
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip()
    record = {"written_at_commit": commit, "seed": SEED, "n": N,
              "node_count": shapes.node_count.tolist(),
              "semi_a": shapes.semi_a.tolist(), "semi_b": shapes.semi_b.tolist(),
              "node_x": shapes.node_x.tolist(), "node_y": shapes.node_y.tolist(),
              "next_integer": after}
    out.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    write()
