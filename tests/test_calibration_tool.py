"""The calibration tool runs piles side by side and reads their files one pile at a time.

The netCDF/HDF5 library is not thread-safe: two piles of the step-error table
read at once failed with "NetCDF: Can't open HDF5 attribute" and stopped the
run.  Here the piles' simulations are stood in for (nothing is poured) and the
reading of each pile is timed: with two threads, no two readings overlap, and
each pile's record is written whole.
"""

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from workflow.tools import calibration


def test_two_piles_side_by_side_are_read_one_at_a_time(tmp_path, monkeypatch):
    inside, most, guard = [0], [0], threading.Lock()

    def reading(cal, arm, seed, cfg, protocol, work, files):
        with guard:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        time.sleep(0.2)                                   # long enough for the other thread to arrive
        with guard:
            inside[0] -= 1
        return {"seed": seed, "cpu_s": {"total": 1.0}, "growth": {"flow_fraction": 0.5}}

    monkeypatch.setattr(calibration, "REPO", tmp_path)
    monkeypatch.setattr(calibration, "arm_config", lambda cal, arm, seed: {"pour": {}})
    monkeypatch.setattr(calibration, "targets", lambda cfg, protocol, seed: dict.fromkeys(
        ("fields", "summary", "base_pressure", "frames", "relaxed"), "x"))
    monkeypatch.setattr(calibration.subprocess, "run", lambda *a, **k: None)
    monkeypatch.setattr(calibration, "calibration_record", reading)
    cal = {"arms": {"wedge funnel": {"protocol": "wedge"}}}
    with ThreadPoolExecutor(2) as pool:
        paths = list(pool.map(lambda s: calibration.run_pile(cal, "wedge funnel", s, tmp_path / "records"),
                              [1, 2, 3, 4]))
    assert most[0] == 1
    assert [json.loads(p.read_text())["seed"] for p in paths] == [1, 2, 3, 4]
