"""The suite as another processor would run it (docs/testing.md).

A test that builds a chaotic heap (particles falling and colliding) gets other
last bits on another processor or with another numpy, and so another heap; a
threshold tuned to one host's heap then fails elsewhere.  Run as ::

    POLYPILE_PERTURB_GRAVITY=3 PYTHONPATH=$PWD/tests/perturb .venv/bin/python -m pytest

(an absolute PYTHONPATH: some tests start processes in other folders)

every Python process of the run, the test process and each one it starts
(a pour, a Snakemake job), imports this file at start-up; when the simulator's
module :mod:`sim.pour` is first imported, its gravity :data:`sim.pour.GRAVITY`,
which every pour, relaxation and probe uses, is moved K units in the last
place (K = ``POLYPILE_PERTURB_GRAVITY``, an integer, negative: downwards).
Every trajectory then differs in its last bits from the first step on, as on
another host, while every physical quantity stays the same to 1e-15: a test
that passes only without it asserts one host's bits.
"""

import importlib.abc
import os
import sys

_K = int(os.environ.get("POLYPILE_PERTURB_GRAVITY") or 0)


def _perturb(module):
    import numpy as np

    towards = np.inf if _K > 0 else 0.0
    for _ in range(abs(_K)):
        module.GRAVITY = float(np.nextafter(module.GRAVITY, towards))


class _AfterImport(importlib.abc.MetaPathFinder):
    """Finds nothing itself: wraps the loader of ``sim.pour`` so that the
    module is perturbed once it has run."""

    def find_spec(self, name, path, target=None):
        if name != "sim.pour":
            return None
        sys.meta_path.remove(self)
        try:
            import importlib.util

            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        loader = spec.loader
        exec_module = loader.exec_module

        def exec_and_perturb(module):
            exec_module(module)
            _perturb(module)

        loader.exec_module = exec_and_perturb
        return spec


if _K:
    sys.meta_path.insert(0, _AfterImport())
