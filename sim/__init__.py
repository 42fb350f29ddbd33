"""2D discrete-element simulator of soft, shape-invariant convex polygons.

Implements Section 2 and the Appendix of Roul, Schinner & Kassner,
"Mechanical properties of non-cohesive polygonal particle aggregates",
Granular Matter (2010).

Importing the package points Numba's on-disk cache at a folder named by a
digest of the package's sources (:func:`source_digest`), under
``NUMBA_CACHE_DIR`` (default: ``.numba_cache`` beside the package).  Numba
keys a cached kernel by the modification time of its own file only, so a
kernel of ``sim/forces.py`` that inlines a helper from ``sim/warmstart.py``
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


# before any kernel is decorated: the cache locator reads it then
numba.config.CACHE_DIR = os.path.join(
    os.environ.get("NUMBA_CACHE_DIR") or str(Path(__file__).parent.parent / ".numba_cache"),
    f"sim-{source_digest()}")
