"""Numba's kernel cache is kept per version of the kernels' sources.

Numba invalidates a cached kernel only when the kernel's own file changes, not
when a helper it inlines from another file does; the cache folder is
therefore named by a digest of the files the kernels are built from
(sim/kernel_cache.py), and of no other: editing the bench, a protocol or the
command line must not recompile the kernels.
"""

import os
import shutil
from pathlib import Path

import numba

import sim
from sim import kernel_cache


def test_cache_folder_is_named_by_the_sources():
    assert numba.config.CACHE_DIR.endswith(f"sim-{kernel_cache.source_digest()}")


def _copy(tmp_path):
    copy = tmp_path / "sim"
    shutil.copytree(Path(sim.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert kernel_cache.source_digest(copy) == kernel_cache.source_digest()
    return copy


def _edit(path):
    path.write_text(path.read_text() + "\n# an edit\n")


def test_editing_a_helper_file_moves_the_cache(tmp_path):
    copy = _copy(tmp_path)
    for helper in ("warmstart.py", "rotation.py", "contact_law.py", "builds.py"):
        before = kernel_cache.source_digest(copy)
        _edit(copy / helper)
        assert kernel_cache.source_digest(copy) != before, helper


def test_editing_what_no_kernel_is_built_from_keeps_the_cache(tmp_path):
    """The bench, the numerics, a protocol, the command line, the settings."""
    copy = _copy(tmp_path)
    before = kernel_cache.source_digest(copy)
    for other in ("numerics/bench.py", "numerics/__init__.py", "pour.py", "relax.py", "cli.py", "config.py",
                  "config.schema.yaml"):
        _edit(copy / other)
        assert kernel_cache.source_digest(copy) == before, other


def test_the_kernel_sources_are_the_kernel_modules_and_what_they_import():
    names = {p.name for p in kernel_cache.kernel_sources()}
    # the modules whose functions Numba compiles, and those they import
    assert {"step.py", "broadphase.py", "warmstart.py", "geometry.py", "rotation.py", "contact_law.py",
            "integrators.py", "builds.py", "kernel_cache.py"} <= names
    assert not names & {"pour.py", "cli.py", "relax.py", "probe.py", "config.py", "io.py"}
    assert all(p.parent == Path(sim.__file__).parent for p in kernel_cache.kernel_sources())


def test_the_cache_defaults_to_beside_a_writable_checkout(tmp_path):
    package = tmp_path / "checkout" / "sim"
    package.mkdir(parents=True)
    assert kernel_cache.default_cache_dir(package) == tmp_path / "checkout" / ".numba_cache"


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
    assert kernel_cache.default_cache_dir(site / "sim") == tmp_path / "xdg" / "polypile" / "numba"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert kernel_cache.default_cache_dir(site / "sim") == tmp_path / "home" / ".cache" / "polypile" / "numba"
