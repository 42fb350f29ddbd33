"""The digest of a package's sources: the one rule for every code digest of the project.

The simulator records it for ``sim/`` in every state file
(:func:`sim.io.code_version`), a pour resumes a checkpoint only under the
same one, the workflow carries it for ``sim/`` and ``analysis/`` as the
param ``code`` of its rules (an edit re-runs the jobs that run that code),
and ``python -m sim --version`` and ``python -m analysis --version`` print
it.  (The Numba cache is named by another digest, of the kernels' sources
alone: :func:`sim.source_digest`.)
"""

import hashlib
from pathlib import Path


def code_digest(folder) -> str:
    """The first 16 hex digits of the SHA-256 of the ``*.py`` files of `folder`.

    Each file's name, a NUL byte and its content, in sorted order; the
    files of subfolders do not count.  Computed from the files in `folder`,
    not from an imported package, which need not be the one there.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    str
    """
    digest = hashlib.sha256()
    for path in sorted(Path(folder).glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]
