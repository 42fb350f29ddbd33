"""Numba's on-disk cache of the simulator's kernels, a folder per version of their sources.

Importing this module points Numba's cache at a folder named by a digest of
the kernels' sources (:func:`source_digest` over :func:`kernel_sources`),
under ``NUMBA_CACHE_DIR`` (default: :func:`default_cache_dir`,
``.numba_cache`` beside the package in a checkout, the user's cache folder
when the package lies where the user cannot write, as in a system-wide
install).  Numba keys a cached kernel by the modification time of its own
file only, so a kernel of ``sim/step.py`` that inlines a helper from
``sim/warmstart.py`` would otherwise keep running the old helper after an
edit.  Only the modules the kernels are compiled from name the folder:
editing a protocol, the command line, the bench or the numerics
(``sim/numerics/``) recompiles nothing.

A module that compiles kernels takes its ``njit`` from here
(``from .kernel_cache import njit``, Numba's own decorator), so that the
folder is set before its first kernel is decorated, whichever module is
imported first.  The package itself (``sim/__init__.py``) sets nothing:
the modules that the analysis and the workflow share with the simulator
(:mod:`sim.atomic`, :mod:`sim.digest`, :mod:`sim.distinct_paths`, :mod:`sim.schema`,
:mod:`sim.settings_file`) load without Numba.
"""

import ast
import os
import re
from pathlib import Path

import numba
from numba import njit

from .digest import files_digest

__all__ = ["default_cache_dir", "kernel_sources", "njit", "source_digest"]


_KERNEL = re.compile(r"\bnjit\b|from \.builds import build\b")
"""What marks a module that defines Numba kernels: it decorates with ``njit``
or compiles through :func:`sim.builds.build`."""


def _relative_imports(path):
    """The top-level package modules that ``path`` imports relatively (``from .x import``)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_bytes())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            names.update([node.module.split(".")[0]] if node.module else [a.name for a in node.names])
    return names


def kernel_sources(package_dir=Path(__file__).parent):
    """The files the simulator's Numba kernels are compiled from.

    The top-level modules of the package that define kernels (they use
    ``njit`` or :func:`sim.builds.build`) and, transitively, every module of
    the package that those import: a kernel may inline a helper from any of
    them, and this module, which holds the rule (with :mod:`sim.digest`,
    which it imports).  Subpackages
    (``sim/numerics/``: the bench and the numerical studies) are not among
    them; their own kernels are cached by Numba's rule (the modification
    time of their file).

    Parameters
    ----------
    package_dir : pathlib.Path
        The package's folder.

    Returns
    -------
    list of pathlib.Path
        Sorted by name.
    """
    package_dir = Path(package_dir)
    todo = [Path(__file__).stem] + [p.stem for p in package_dir.glob("*.py")
                                    if _KERNEL.search(p.read_text(encoding="utf-8"))]
    found = set()
    while todo:
        name = todo.pop()
        path = package_dir / f"{name}.py"
        if name not in found and path.is_file():
            found.add(name)
            todo.extend(_relative_imports(path))
    return sorted(package_dir / f"{name}.py" for name in found)


def source_digest(package_dir=Path(__file__).parent):
    """A 12-digit digest of the kernels' source files: the first 12 hex digits
    of :func:`sim.digest.files_digest` over :func:`kernel_sources`.

    Parameters
    ----------
    package_dir : pathlib.Path
        The package's folder.

    Returns
    -------
    str
    """
    return files_digest(kernel_sources(package_dir), package_dir)[:12]


def default_cache_dir(package_dir=Path(__file__).parent):
    """The Numba cache folder used when ``NUMBA_CACHE_DIR`` is not set.

    ``.numba_cache`` beside the package (the checkout's, for an editable
    install) when it can be written there; else, as for a package installed
    into a folder the user cannot write, ``polypile/numba`` under the user's
    cache home (``XDG_CACHE_HOME``, default ``~/.cache``).

    Parameters
    ----------
    package_dir : pathlib.Path
        The package's folder.

    Returns
    -------
    pathlib.Path
    """
    beside = Path(package_dir).parent / ".numba_cache"
    if os.access(beside if beside.exists() else beside.parent, os.W_OK):
        return beside
    home = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(home) / "polypile" / "numba"


# before any kernel is decorated: the cache locator reads it then
numba.config.CACHE_DIR = os.path.join(
    os.environ.get("NUMBA_CACHE_DIR") or str(default_cache_dir()), f"sim-{source_digest()}")
