"""2D discrete-element simulator of soft, shape-invariant convex polygons.

Implements Section 2 and the Appendix of Roul, Schinner & Kassner,
"Mechanical properties of non-cohesive polygonal particle aggregates",
Granular Matter (2010).

Importing the package points Numba's on-disk cache at a folder named by a
digest of the package's sources (:func:`source_digest`), under
``NUMBA_CACHE_DIR`` (default: :func:`default_cache_dir`, ``.numba_cache``
beside the package in a checkout, the user's cache folder when the package
lies where the user cannot write, as in a system-wide install).  Numba
keys a cached kernel by the modification time of its own file only, so a
kernel of ``sim/step.py`` that inlines a helper from ``sim/warmstart.py``
would otherwise keep running the old helper after an edit.
"""

import hashlib
import os
from pathlib import Path

import numba

__version__ = "0.1.0"


def source_digest(package_dir=Path(__file__).parent):
    """A 12-digit digest of the contents of every ``.py`` file of the package.

    Parameters
    ----------
    package_dir : pathlib.Path
        The package's folder (its subpackages included).

    Returns
    -------
    str
    """
    h = hashlib.sha256()
    for path in sorted(Path(package_dir).rglob("*.py")):
        h.update(path.relative_to(package_dir).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:12]


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
