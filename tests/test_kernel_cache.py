"""Numba's kernel cache is kept per version of the simulator's sources.

Numba invalidates a cached kernel only when the kernel's own file changes, not
when a helper it inlines from another file does; the cache folder is
therefore named by a digest of every source file (sim/__init__.py).
"""

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
