"""Numba's kernel cache is kept per version of the simulator's sources.

Numba invalidates a cached kernel only when the kernel's own file changes, not
when a helper it inlines from another file does; the cache folder is
therefore named by a digest of every source file (sim/__init__.py).
"""

import os
import shutil
from pathlib import Path

import numba

import sim


def test_cache_folder_is_named_by_the_sources():
    assert numba.config.CACHE_DIR.endswith(f"sim-{sim.source_digest()}")


def test_editing_a_helper_file_moves_the_cache(tmp_path):
    copy = tmp_path / "sim"
    shutil.copytree(Path(sim.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    before = sim.source_digest(copy)
    assert before == sim.source_digest()
    helper = copy / "warmstart.py"
    helper.write_text(helper.read_text() + "\n# an edit\n")
    assert sim.source_digest(copy) != before


def test_the_cache_defaults_to_beside_a_writable_checkout(tmp_path):
    package = tmp_path / "checkout" / "sim"
    package.mkdir(parents=True)
    assert sim.default_cache_dir(package) == tmp_path / "checkout" / ".numba_cache"


def test_a_package_in_a_folder_the_user_cannot_write_caches_in_the_user_cache_home(
        tmp_path, monkeypatch):
    """A system-wide install: site-packages is read-only for the user (faked,
    as root may write anywhere), so the kernels go to $XDG_CACHE_HOME, or
    ~/.cache without it."""
    site = tmp_path / "site-packages"
    (site / "sim").mkdir(parents=True)
    writable = os.access
    monkeypatch.setattr(os, "access", lambda path, mode: (
        not Path(path).is_relative_to(site) and writable(path, mode)))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert sim.default_cache_dir(site / "sim") == tmp_path / "xdg" / "polypile" / "numba"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert sim.default_cache_dir(site / "sim") == tmp_path / "home" / ".cache" / "polypile" / "numba"
