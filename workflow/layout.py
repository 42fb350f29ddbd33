"""Where a configuration's files lie under a Snakemake working directory.

Each configuration writes everything it makes into its own results folder
(config ``results``, e.g. ``results/study``): ``piles/``, ``fields/``,
``ensemble/``, ``figures/``, ``logs/``, ``benchmarks/`` (issue 29, item 2).
A working directory filled before that (a sweep or variant poured by an
older clone) has them one level up: ``results/piles/``, ``results/fields/``
and ``logs/``, ``benchmarks/`` beside ``results/``. The tools that read
such directories (workflow/tools/setting_sweep.py, probe_levels.py) find
both through :func:`folders`.
"""

from pathlib import Path


def folders(work, results):
    """The results folder and the benchmarks folder of the configuration whose
    ``results`` setting is `results`, in the working directory `work`.

    Parameters
    ----------
    work : path-like
        A Snakemake working directory (``--directory``).
    results : str
        The configuration's ``results`` setting.

    Returns
    -------
    (pathlib.Path, pathlib.Path)
        ``work/results`` and ``work/results/benchmarks``; for a working
        directory filled before the results folders (no ``work/results`` but a
        ``work/results/piles`` or ``work/results/fields``), ``work/results``
        and ``work/benchmarks``.
    """
    work = Path(work)
    folder = work / results
    legacy = work / "results"
    if not folder.is_dir() and ((legacy / "fields").is_dir() or (legacy / "piles").is_dir()):
        return legacy, work / "benchmarks"
    return folder, folder / "benchmarks"
