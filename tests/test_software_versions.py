"""Every output records the versions that made it (issue 29), and the environment is the
one the committed results were made with: the versions pinned in
workflow/envs/constraints.txt, which decide the bits of a pour (numpy, numba, llvmlite)."""

import re
from importlib.metadata import version
from pathlib import Path

import numpy as np
import xarray as xr

from analysis.netcdf import write_dataset
from sim.config import ModelParams
from sim.engine import Simulation
from sim.io import save_state
from sim.shapes import make_shapes

CONSTRAINTS = Path(__file__).resolve().parents[1] / "workflow" / "envs" / "constraints.txt"


def test_a_state_file_names_the_versions_that_decide_its_bits(tmp_path):
    sim = Simulation(make_shapes(np.random.default_rng(1), 3), ModelParams(), gravity=(0.0, -9.81))
    for k in range(3):
        sim.place(k, 0.01 * k, 0.01, 0.0)
    save_state(sim, tmp_path / "s.nc", {}, stage="poured")
    with xr.open_dataset(tmp_path / "s.nc") as ds:
        software = ds.attrs["software"]
    for name in ("numpy", "numba", "llvmlite", "xarray", "netCDF4"):
        assert f"{name} {version(name)}" in software
    assert software.startswith("python 3.")


def test_an_analysis_file_names_its_versions(tmp_path):
    ds = xr.Dataset({"a": ("x", np.zeros(2), {"units": "1", "long_name": "a"})})
    write_dataset(ds, str(tmp_path / "a.nc"), title="t", params={})
    with xr.open_dataset(tmp_path / "a.nc") as out:
        assert all(f"{n} {version(n)}" in out.attrs["software"] for n in ("numpy", "scipy", "xarray", "netCDF4"))


def test_the_environment_has_the_pinned_versions():
    pins = dict(re.findall(r"^([A-Za-z0-9_.\-]+)==(\S+)$", CONSTRAINTS.read_text(), flags=re.M))
    for name in ("numpy", "numba", "llvmlite", "scipy", "xarray", "netCDF4", "snakemake"):
        assert pins[name] == version(name), f"{name}: installed {version(name)}, pinned {pins[name]}"
