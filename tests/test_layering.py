"""The data flow is one way (config → sim → state files → analysis): the
simulator imports nothing of the analysis, the analysis nothing of the
simulator but its reader of settings files (it reads state files through the
contract; settings, which precede both, are read by one reader,
:mod:`sim.settings_file`, so that a number or a repeated key means the same to
both), the check of a setting against its JSON schema (:mod:`sim.schema`),
and the check that no output of a command line is an input or another
output (:mod:`sim.paths`, one for both command lines), the digests of
code and of a file's content (:mod:`sim.digest`) and the one atomic write
(:mod:`sim.atomic`), and no module of either package imports itself through others (no
import cycle). Every import statement counts, also those inside functions."""

import ast
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
SHARED = ("sim.settings_file", "sim.schema", "sim.paths", "sim.digest", "sim.atomic")


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
