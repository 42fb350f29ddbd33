"""The digest of a package's sources that the workflow's rules carry as param
``code`` (workflow/rules/common.smk): Snakemake re-runs a job whose recorded
params changed, so an edit of sim/ re-runs the simulations and an edit of
analysis/ the analysis, without listing every source file as an input of every
job (which made each job's entry in the log 33 file names long, issue 29 item 7).
"""

import hashlib
from pathlib import Path


def code_digest(folder) -> str:
    """The first 16 hex digits of the SHA-256 of the ``*.py`` files of `folder`.

    Each file's name, a NUL byte and its content, in sorted order: for sim/
    the code version :func:`sim.io.code_version` writes into every state file.
    Computed from the files in `folder`, not from an imported package, which
    need not be the one there.

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
