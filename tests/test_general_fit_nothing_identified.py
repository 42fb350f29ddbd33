"""``python -m analysis general-fit`` on probes that moved nothing (every
strain increment zero) wrote a file of fits all flagged not identified and
exited 0 (issue 47 item 10); it now ends with one line saying that nothing
was identified, and writes nothing."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis import general_elastic as ge
from analysis.errors import InputError
from test_analysis_general_elastic import probe_file

REPO = Path(__file__).resolve().parents[1]
PROBES = ["reduced", "tiltp05", "tiltm05", "restored"]


def test_general_fit_of_probes_that_moved_nothing_fails_in_one_line(tmp_path):
    zero = np.zeros((4, 3, 4, 2, 2))
    for k in range(2):
        ds = probe_file(zero, zero, PROBES)
        for c in "xy":
            ds[c].attrs.update(units="m", long_name=c)
        ds.to_netcdf(tmp_path / f"pile{k}.nc")
    done = subprocess.run([sys.executable, "-m", "analysis", "general-fit", "--probes", "pile0.nc",
                           "pile1.nc", "--out", "general.nc"], capture_output=True, text=True,
                          cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=600)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 1 and len(lines) == 1, (done.returncode, lines)
    assert lines[0].startswith("error: general fit: nothing identified") and "zero" in lines[0]
    assert not (tmp_path / "general.nc").exists()


def test_zero_strains_at_some_rves_only_are_flagged_there_not_refused():
    """Off the pile (NaN) and a zero-strain RVE beside a strained one: the fit goes on."""
    rng = np.random.default_rng(3)
    u = rng.normal(scale=1e-4, size=(3, 6, 2, 2))
    u = 0.5 * (u + np.swapaxes(u, -1, -2))
    u[1] = 0.0
    u[2] = np.nan
    fit = ge.fit_general_stiffness(1e6 * u, u)
    assert fit["flag"][0] == 0 and fit["flag"][1] & ge.GENERAL_NOT_IDENTIFIED
    with pytest.raises(InputError, match="nothing identified"):
        ge.fit_general_stiffness(1e6 * u[1:], u[1:])
