"""A job asked for 2 threads really runs the parallel kernels on 2 threads.

Numba's on-disk cache once served the serial build of each kernel to the
parallel one (their cache entries shared a name, numba issue 6845), so jobs
given 2 threads ran on one core.  The job here is a fresh process on the
project's kernel cache, which the serial builds reach first (a small pile
below the parallel threshold runs before the large one), as in a pour.

The test judges what the threads did, not how fast: the pair pass gives
each thread its own narrow-phase row (``Simulation.work.out[thread id]``,
:mod:`sim.step`), so after a step of a packing in contact the second
thread's row holds a contact's geometry only if that thread computed pairs.
The serial build runs on thread 0 alone and leaves the row zero.  Numba's
schedulers (OpenMP, workqueue) give every thread its share of the loop, so a
busy machine slows the threads but cannot take the second one's share away,
as it could take away the CPU-time ratio this test measured before (it failed
whenever other jobs ran on the 2-core machine).  The cores a job really uses
are the bench's figure (``cores_used``, docs/performance.md).
"""

import hashlib
import json
import os
import subprocess
import sys

import numba
import numpy as np

from sim.numerics.bench import dense_packing

JOB = """
import hashlib, json
import numba
import numpy as np
from sim.numerics.bench import dense_packing

small = dense_packing(50, seed=1)
small.run(steps=20)                      # serial kernels: compiled or loaded first
sim = dense_packing(1500, seed=2)
assert sim.n >= sim.parallel_threshold
sim.run(steps=20)
print(json.dumps({"threads": numba.get_num_threads(), "layer": numba.threading_layer(),
                  "rows": np.abs(sim.work.out).sum(axis=1).tolist(),
                  "contacts": len(sim.contacts()["i"]),
                  "bits": hashlib.sha256(sim.r.tobytes()).hexdigest()}))
"""


def _serial_bits():
    """The same run on one thread (the serial kernels), in this process."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        sim = dense_packing(1500, seed=2)
        sim.run(steps=20)
    finally:
        numba.set_num_threads(threads)
    return hashlib.sha256(sim.r.tobytes()).hexdigest()


def test_a_two_thread_job_computes_on_both_threads_and_gets_the_serial_bits():
    """In a fresh 2-thread process, the second thread's narrow-phase row holds
    contact geometry after the steps (it computed pairs), and the state is bit
    for bit that of the serial kernels (the parallel passes write no shared
    value)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", JOB], env=env, capture_output=True, text=True,
                         check=True)
    job = json.loads(out.stdout.strip().splitlines()[-1])
    assert job["threads"] == 2 and job["contacts"] > 100
    assert len(job["rows"]) == 2 and job["rows"][0] > 0
    assert job["rows"][1] > 0, f"thread 1 computed no pair ({job['layer']} threading layer)"
    assert job["bits"] == _serial_bits()


def test_a_run_does_not_take_numbas_process_shared_lock(monkeypatch):
    """Only making a simulation asks Numba for its thread count, the call that
    takes a lock shared with forked processes: its runs, the place a worker is
    killed, never do (a worker killed holding it hangs every other one)."""
    sim = dense_packing(50, seed=1)
    threads = sim.threads

    def asked():
        raise AssertionError("numba.get_num_threads() called during a run")

    monkeypatch.setattr(numba, "get_num_threads", asked)
    before = sim.step
    sim.run(steps=120)          # chunks between checks, rebuilds
    assert sim.step == before + 120 and sim.threads == threads
