"""The command lines of the rules: ``python -m sim ...`` with the Numba
environment, and ``python ...`` for the analysis and the tools (``-m workflow.tools``).

The rule files call :meth:`Commands.sim_shell` and :meth:`Commands.py_shell`
as ``study.commands`` (:class:`workflow.study.Study`).
"""

import shlex


class Commands:
    """Shell commands run by one Python interpreter.

    Snakemake sets OMP_NUM_THREADS from ``threads:`` but not
    NUMBA_NUM_THREADS, so every simulation command sets it, and the Numba
    cache (filled once by rule compile_kernels before the jobs fan out).

    Parameters
    ----------
    python : str
        The interpreter: Snakemake's own (the project's venv under ``make
        run``), or ``python`` where a conda environment provides it.
    numba_cache : path-like
        The Numba cache folder of the jobs (NUMBA_CACHE_DIR).
    """

    def __init__(self, python, numba_cache):
        self.python = python
        #: ``python -m sim`` without the Numba settings, for commands that run no kernels.
        self.py_sim = f"{shlex.quote(python)} -m sim"
        #: ``python -m sim`` with the Numba settings; keeps ``{threads}`` for Snakemake.
        self.sim_cmd = (f"NUMBA_NUM_THREADS={{threads}} NUMBA_CACHE_DIR={shlex.quote(str(numba_cache))} "
                        f"{self.py_sim}")

    def sim_shell(self, command, numba=True):
        """Shell command of a rule: ``python -m sim <command>``, with the Numba
        environment unless numba=False."""
        return f"{self.sim_cmd if numba else self.py_sim} {command}"

    def py_shell(self, command):
        """Shell command ``python <command>``, e.g.
        ``shell: py_shell("-m analysis fields ... > {log:q} 2>&1")``. Writing
        ``{PY}`` in a shell string directly works too, but snakemake --lint
        flags it."""
        return f"{shlex.quote(self.python)} {command}"
