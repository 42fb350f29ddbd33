"""Serial and parallel Numba builds of one kernel, cached apart.

Kernels that run on every step or pair-list rebuild exist in a serial and a
parallel build: below a few hundred particles starting a parallel region
costs more than the work (on a busy machine a region's start waits for a
core, milliseconds each time).  The builds are compiled from copies of the
kernel under distinct names, because Numba's on-disk cache does not tell a
``parallel=True`` build from a serial one of the same function (numba issue
6845): under one name, whichever build was compiled first served both.
"""

from __future__ import annotations

import types

from .kernel_cache import njit


def build(kernel, parallel, nrt=True):
    """A Numba build of ``kernel`` cached under a name of its own per build.

    Parameters
    ----------
    kernel : function
        Plain Python function (its ``prange`` loops run in parallel only in
        the parallel build).
    parallel : bool
        Build with ``parallel=True``.
    nrt : bool
        Keep Numba's reference counting (needed by a kernel that allocates).

    Returns
    -------
    numba dispatcher
        Named ``<kernel>_parallel`` or ``<kernel>_serial``.

    Notes
    -----
    Built with ``error_model="numpy"``: a float division by zero gives inf or
    nan (which the run's checks catch) instead of Numba's default test of
    every divisor for zero before dividing, a branch per division in the hot
    loops.  No kernel divides by zero on purpose; the results of every other
    division are the same bits.
    """
    tag = "parallel" if parallel else "serial"
    clone = types.FunctionType(kernel.__code__, kernel.__globals__,
                               f"{kernel.__name__}_{tag}", kernel.__defaults__,
                               kernel.__closure__)
    clone.__qualname__ = f"{kernel.__qualname__}_{tag}"
    clone.__doc__ = kernel.__doc__
    return njit(cache=True, parallel=parallel, _nrt=nrt, error_model="numpy")(clone)
