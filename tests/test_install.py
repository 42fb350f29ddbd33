"""The packages work installed, away from the checkout: ``sim`` and ``analysis``
read no file of the repository outside their own folders (each ships the
schema of its own settings), and pyproject.toml lists every file they need.

The files a wheel would hold (the packages' ``*.py`` and the package data that
pyproject.toml names) are copied into an empty folder, and ``python -m sim
--help`` and ``python -m analysis params`` run from there with that folder
alone on the path. (A real ``pip install .`` into a fresh virtual environment
does the same, and takes a minute to fetch the build backend.)
"""

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def wheel_files():
    """The repository's files that a wheel of pyproject.toml holds, relative to REPO."""
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    files = []
    for package in setuptools["packages"]:
        folder = REPO / package.replace(".", "/")
        patterns = ["*.py", *setuptools.get("package-data", {}).get(package, [])]
        files += [path.relative_to(REPO) for pattern in patterns for path in sorted(folder.glob(pattern))]
    return files


def test_every_schema_of_a_package_is_package_data():
    shipped = set(wheel_files())
    schemas = {path.relative_to(REPO) for package in ("sim", "analysis")
               for path in (REPO / package).rglob("*.schema.yaml")}
    assert schemas and schemas <= shipped


def test_the_packages_run_installed_away_from_the_checkout(tmp_path):
    site = tmp_path / "site-packages"
    for path in wheel_files():
        (site / path).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(REPO / path, site / path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    for command in (["-m", "sim", "--help"], ["-m", "analysis", "params"]):
        proc = subprocess.run([sys.executable, "-P", *command], cwd=elsewhere, env=env,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout
    found = subprocess.run([sys.executable, "-P", "-c", "import sim, analysis; print(sim.__file__, analysis.__file__)"],
                           cwd=elsewhere, env=env, capture_output=True, text=True).stdout.split()
    assert all(Path(f).is_relative_to(site) for f in found), found
