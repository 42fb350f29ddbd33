"""The data flow is one way (config → sim → state files → analysis): the
simulator imports nothing of the analysis, the analysis nothing of the
simulator but five light modules it shares with it: its reader of settings
files (it reads state files through the contract; settings, which precede
both, are read by one reader, :mod:`sim.settings_file`, so that a number or a
repeated key means the same to both), the check of a setting against its JSON
schema (:mod:`sim.schema`), and the check that no output of a command line is
an input or another output (:mod:`sim.distinct_paths`, one for both command lines), the
digests of code and of a file's content (:mod:`sim.digest`) and the one atomic
write (:mod:`sim.atomic`).  These import nothing of the simulator, and
loading one loads no Numba (the package's ``__init__`` runs nothing; the
kernels' modules set Numba's cache themselves, :mod:`sim.kernel_cache`).  No
module of either package imports itself through others (no import cycle).
Every import statement counts, also those inside functions."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "analysis")


def module_name(path):
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path):
    """Absolute names of the modules that ``path`` imports (relative imports resolved)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                stem = ".".join(base + ([node.module] if node.module else []))
            else:
                stem = node.module
            out.add(stem)
            # `from . import rve` imports the module sim.rve / analysis.rve
            out.update(f"{stem}.{alias.name}" for alias in node.names)
    return out


def graph():
    modules = {module_name(p): p for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py")}
    return {name: {m for m in imports(path) if m in modules and m != name}
            for name, path in modules.items()}, modules


#: What the analysis may import of the simulator: the one reader of settings, the
#: one check of a setting against its schema, the one check of a command line's
#: paths, the one code digest and data digest, and the one atomic write.
SHARED = ("sim.settings_file", "sim.schema", "sim.distinct_paths", "sim.digest", "sim.atomic")


@pytest.mark.parametrize("package,forbidden", [("sim", ("analysis", "workflow")), ("analysis", ("sim", "workflow"))])
def test_a_package_imports_nothing_of_the_other(package, forbidden):
    bad = sorted((str(path.relative_to(REPO)), m) for path in (REPO / package).rglob("*.py")
                 for m in imports(path) if m.split(".")[0] in forbidden
                 and not any(m == s or m.startswith(s + ".") for s in SHARED))
    assert bad == []


def test_no_import_cycle():
    edges, _ = graph()
    # a module's own package __init__ is imported by Python anyway: not an edge of a cycle
    edges = {m: {d for d in deps if not m.startswith(d + ".")} for m, deps in edges.items()}
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = "open"
        for d in sorted(edges[m]):
            if state.get(d) == "open":
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d, stack + [d])
        state[m] = "done"

    for m in sorted(edges):
        if m not in state:
            visit(m, [m])
    assert cycles == []


def test_the_walk_sees_the_imports():
    """The import walk itself: it finds known edges, relative and absolute."""
    edges, modules = graph()
    assert "sim.engine" in edges["sim.pour"]
    assert "analysis.stress" in edges["analysis.draw"]
    assert "analysis.states" in edges["analysis.draw"]
    assert len(modules) > 40


def test_the_shared_modules_import_nothing_of_the_simulator():
    edges, _ = graph()
    assert {m: sorted(edges[m]) for m in SHARED} == {m: [] for m in SHARED}


@pytest.mark.parametrize("module", SHARED)
def test_a_shared_module_loads_without_numba(module):
    """In a fresh interpreter, as the analysis loads it: neither Numba nor the
    kernels' cache folder (:mod:`sim.kernel_cache`) come with it."""
    code = (f"import sys, json, {module}; "
            "print(json.dumps(sorted(m for m in sys.modules "
            "if m.split('.')[0] in ('numba', 'llvmlite') or m == 'sim.kernel_cache')))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         check=True, env={**os.environ, "PYTHONPATH": str(REPO)}).stdout
    assert json.loads(out) == []


def test_every_kernel_module_takes_its_decorator_where_the_cache_is_set():
    """A module of the simulator that decorates with ``njit`` imports it from
    :mod:`sim.kernel_cache`, never straight from Numba: the cache folder is
    then set before its first kernel, whichever module is loaded first."""
    straight = []
    for path in sorted((REPO / "sim").rglob("*.py")):
        if path.name == "kernel_cache.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (isinstance(node, ast.ImportFrom) and node.module == "numba"
                    and any(alias.name == "njit" for alias in node.names)):
                straight.append(str(path.relative_to(REPO)))
    assert straight == []
