"""Where a kernel's time goes, per instruction: python -m sim numerics kernel-profile.

This machine's virtual processors have no hardware performance counters
(``perf stat`` says: not supported), but clock samples (``perf record -e
cpu-clock``) still land on the instruction a core was at.  The kernels are
compiled at run time, so perf knows no symbol for them; this command runs
the serial build of one kernel many times on a saved pile under ``perf
record``, copies the kernel's machine code out of that process with its
address, bins the samples by their offset into it and writes the
disassembly (``objdump``) with each instruction's sample count.  A sample
tends to fall on the instruction *after* a slow one (a division, a square
root, a load that missed), so read a hot spot together with the lines
above it.

Writes into ``--out`` (default ``logs/kernel-profile``): ``perf.data``,
``code.bin`` and ``code.json`` (the machine code, its address and the
kernel's symbol), ``annotated.txt`` (samples, offset, instruction) and
``summary.json``: samples in the kernel, in libm (the cosine and sine of the
placement), elsewhere, the kernel's ns per particle and call, and its
hottest 128-byte windows.  Needs ``perf`` (Debian's ``linux-perf``) and
``objdump`` (``binutils``).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from ..distinct_paths import PathRoles, check_distinct_paths

#: Set in the environment of the process that ``perf record`` runs.
CHILD = "POLYPILE_KERNEL_PROFILE_CHILD"
KERNELS = ("pairs", "gather", "predict")
WINDOW = 128  # bytes of machine code per line of the summary's hot windows


#: The files of the command line (:func:`sim.distinct_paths.check_distinct_paths`).
PATHS = PathRoles(inputs=("--state",), outputs=("--out",))


def _parser():
    ap = argparse.ArgumentParser(prog="python -m sim numerics kernel-profile",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--state", required=True, help="state file of a pile (.nc)")
    ap.add_argument("--kernel", choices=KERNELS, default="pairs")
    ap.add_argument("--repeats", type=int, default=3000, help="calls of the kernel (>= 1)")
    ap.add_argument("--out", default="logs/kernel-profile", help="folder of the results")
    return ap


def _mapping_end(address):
    """End of the memory mapping of this process that holds ``address``."""
    for line in Path("/proc/self/maps").read_text().splitlines():
        lo, hi = (int(v, 16) for v in line.split()[0].split("-"))
        if lo <= address < hi:
            return hi
    raise RuntimeError(f"address {address:#x} is in no mapping of this process")


def _run_kernel(args, out):
    """In the process perf records: call the kernel ``args.repeats`` times and
    dump its machine code; returns its thread CPU ns per particle and call."""
    import ctypes

    import numba
    numba.set_num_threads(1)
    from ..step import KERNELS_SERIAL
    from .bench import _load
    sim = _load(args.state, "verlet")
    sim.run(steps=5)
    predict, pairs, gather = KERNELS_SERIAL
    pt, pr, bodies = sim.kernel_state()
    law, motion, work = sim.law, sim.motion(), sim.work
    predict(sim.n, pt, motion, work)
    calls = {"predict": (predict, lambda: predict(sim.n, pt, motion, work)),
             "pairs": (pairs, lambda: pairs(pt, pr, law, motion.dt, work, False)),
             "gather": (gather, lambda: gather(sim.n, pt, pr, bodies, law, motion, work,
                                               sim.x_ref, sim.y_ref, False))}
    kernel, call = calls[args.kernel]
    call()
    t0 = time.thread_time()
    for _ in range(args.repeats):
        call()
    ns = (time.thread_time() - t0) / args.repeats / sim.n * 1e9
    cres = kernel.overloads[kernel.signatures[-1]]  # the build of the calls above
    symbol = cres.fndesc.llvm_func_name
    address = cres.library.get_pointer_to_function(symbol)
    size = min(1 << 16, _mapping_end(address) - address)
    (out / "code.bin").write_bytes(ctypes.string_at(address, size))
    (out / "code.json").write_text(json.dumps({"address": address, "size": size,
                                               "symbol": symbol, "kernel": args.kernel,
                                               "n_particles": sim.n, "repeats": args.repeats,
                                               "ns_per_particle_call": ns}))


def _disassembly(code, address):
    """``(offset, instruction)`` of every instruction of ``code.bin`` (objdump)."""
    text = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64",
                           f"--adjust-vma={address:#x}", str(code)],
                          capture_output=True, text=True, check=True).stdout
    rows = []
    for line in text.splitlines():
        m = re.match(r"\s+([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(.*)", line)
        if m:
            rows.append((int(m.group(1), 16) - address, m.group(2).strip()))
    return rows


def _annotate(out):
    """Bin perf's samples by offset into the kernel; write the annotation and the summary."""
    meta = json.loads((out / "code.json").read_text())
    address, size = meta["address"], meta["size"]
    script = subprocess.run(["perf", "script", "-F", "ip,dso", "-i", str(out / "perf.data")],
                            capture_output=True, text=True, check=True).stdout
    at = collections.Counter()
    where = collections.Counter()
    for line in script.splitlines():
        parts = line.split(None, 1)
        if not parts:
            continue
        offset = int(parts[0], 16) - address
        if 0 <= offset < size:
            at[offset] += 1
            where["kernel"] += 1
        elif "libm" in line:
            where["libm"] += 1
        else:
            where["elsewhere"] += 1
    rows = _disassembly(out / "code.bin", address)
    with open(out / "annotated.txt", "w") as f:
        f.write(f"# {meta['symbol']}: samples, offset, instruction\n")
        for offset, ins in rows:
            f.write(f"{at.get(offset, 0):6d} {offset:6x}  {ins}\n")
    windows = collections.Counter()
    for offset, count in at.items():
        windows[offset // WINDOW * WINDOW] += count
    in_kernel = max(1, where["kernel"])
    summary = dict(meta, samples=dict(where),
                   hot_windows=[{"offset": hex(o), "samples": c, "share": c / in_kernel}
                                for o, c in windows.most_common(12)])
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary


def main(argv):
    """Run the command; returns the exit status."""
    args = _parser().parse_args(argv)
    check_distinct_paths(args, PATHS)
    if args.repeats < 1:
        raise ValueError(f"--repeats = {args.repeats}: give at least 1")
    if not Path(args.state).is_file():
        raise ValueError(f"--state = {args.state}: no such file")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if os.environ.get(CHILD) == "1":
        _run_kernel(args, out)
        return 0
    missing = [tool for tool in ("perf", "objdump") if shutil.which(tool) is None]
    if missing:
        raise ValueError(f"kernel-profile needs {' and '.join(missing)} on the PATH "
                         "(Debian: linux-perf, binutils)")
    subprocess.run(["perf", "record", "-q", "-e", "cpu-clock", "-o", str(out / "perf.data"),
                    sys.executable, "-m", "sim", "numerics", "kernel-profile"] + list(argv),
                   env=dict(os.environ, **{CHILD: "1"}), check=True)
    summary = _annotate(out)
    print(json.dumps({k: summary[k] for k in ("kernel", "n_particles", "ns_per_particle_call",
                                              "samples", "hot_windows")}))
    return 0
