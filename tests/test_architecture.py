"""The layers of the package: the core (numpy, numba) imports nothing from VTK or from the
layers above it, no modules of the package import each other in a cycle, and the VTK
algorithms never import pyvista (ParaView's VTK has none).

Every ``import`` and ``from ... import`` statement of every module under ``fancloud_vtk/``
counts, at module level or inside a function (a lazy import is still a dependency).
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = "fancloud_vtk"
ROOT = Path(__file__).resolve().parent.parent / PACKAGE

#: what the core must not import: VTK, PyVista and the layers above it
CORE_FORBIDDEN = re.compile(
    r"^(vtk|vtkmodules|pyvista"
    r"|fancloud_vtk\.(algorithms|io|accessor|cli|demo|_?bench[^.]*)"
    r")(\.|$)"
)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES.get(name, Path()).name == "__init__.py"


def _imports(name: str) -> list[tuple[int, str]]:
    """(line, imported module) of every import statement of module ``name``, anywhere in it.

    ``from pkg import x`` counts as an import of ``pkg.x`` when that is a module of the
    package, else of ``pkg``; relative imports are resolved against ``name``.
    """
    path = MODULES[name]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if _is_package(name) else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                sub = f"{module}.{alias.name}"
                out.append((node.lineno, sub if sub in MODULES else module))
    return out


GRAPH = {name: _imports(name) for name in MODULES}
CORE = sorted(n for n in MODULES if n == f"{PACKAGE}.core" or n.startswith(f"{PACKAGE}.core."))
ALGORITHMS = sorted(n for n in MODULES if n.startswith(f"{PACKAGE}.algorithms"))


def _core_edges(name: str) -> set[str]:
    return {m for _, m in GRAPH[name] if m in CORE and m != name}


def _closure(name: str) -> set[str]:
    """The core modules that ``name`` imports, directly or through others."""
    seen, todo = set(), [name]
    while todo:
        for m in _core_edges(todo.pop()):
            if m not in seen:
                seen.add(m)
                todo.append(m)
    return seen


def _package_edges(name: str) -> set[str]:
    return {m for _, m in GRAPH[name] if m in MODULES and m != name}


def _cycles(nodes=None, edges=None) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan): of the core
    modules by default, else of ``nodes`` with ``edges``."""
    nodes = CORE if nodes is None else nodes
    edges = _core_edges if edges is None else edges
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges(v)):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in nodes:
        if v not in index:
            visit(v)
    return out


# -- the parser sees what it should (else the checks below would pass on nothing) ------


def test_the_import_graph_is_read():
    assert {f"{PACKAGE}.core.hierarchy", f"{PACKAGE}.core.reduction",
            f"{PACKAGE}.core.refinement", f"{PACKAGE}.algorithms.convert"} <= set(MODULES)
    assert f"{PACKAGE}.core.hierarchy" in _core_edges(f"{PACKAGE}.core.refinement")
    assert f"{PACKAGE}.core._reduction_kernels" in _core_edges(f"{PACKAGE}.core.reduction")
    # function-level imports count: mesh.py imports mesh_stats inside functions only
    assert f"{PACKAGE}.core.mesh_stats" in _core_edges(f"{PACKAGE}.core.mesh")
    assert ("vtkmodules.vtkIOXML" in {m for _, m in GRAPH[f"{PACKAGE}.algorithms.convert"]})
    assert CORE_FORBIDDEN.match("fancloud_vtk.bench_vdfc")
    assert CORE_FORBIDDEN.match("fancloud_vtk._bench_peers")
    assert CORE_FORBIDDEN.match("vtkmodules.util.numpy_support")
    assert not CORE_FORBIDDEN.match("fancloud_vtk.params")
    assert not CORE_FORBIDDEN.match("vtk_like_name")


# -- (a) the core imports neither VTK nor the layers above it ---------------------------


@pytest.mark.parametrize("name", CORE)
def test_core_module_imports_nothing_from_vtk_or_above(name):
    bad = [f"line {line}: {m}" for line, m in GRAPH[name] if CORE_FORBIDDEN.match(m)]
    # the package itself re-exports the filters and the VTK files (lazily): not from the core
    bad += [f"line {line}: {m} (the top-level package)" for line, m in GRAPH[name]
            if m == PACKAGE]
    assert not bad, f"{name} imports from VTK or a layer above the core: {bad}"


def test_importing_the_package_and_the_core_loads_no_vtk():
    code = (
        "import sys\n"
        f"import {PACKAGE}\n"
        + "".join(f"import {m}\n" for m in CORE)
        + "bad = sorted(m for m in sys.modules\n"
        "             if m.split('.')[0] in ('vtk', 'vtkmodules', 'pyvista')\n"
        f"             or m.startswith(('{PACKAGE}.algorithms', '{PACKAGE}.accessor')))\n"
        "assert not bad, bad\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]


# -- (b) no import cycle among the core modules -----------------------------------------


def test_no_import_cycle_in_the_core():
    cycles = _cycles()
    assert not cycles, f"import cycles among core modules: {cycles}"


def test_no_import_cycle_in_the_package():
    """Nor anywhere else: the command and the demo, say, share their console helpers
    (``_console``) rather than import each other."""
    cycles = _cycles(sorted(MODULES), _package_edges)
    assert not cycles, f"import cycles in the package: {cycles}"
    # the check sees a cycle where there is one
    fake = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(sorted(fake), fake.__getitem__) == [["a", "b", "c"]]


def test_reduction_and_refinement_do_not_import_each_other():
    red, ref = f"{PACKAGE}.core.reduction", f"{PACKAGE}.core.refinement"
    assert ref not in _closure(red), f"{red} imports {ref} (directly or through others)"
    assert red not in _closure(ref), f"{ref} imports {red} (directly or through others)"
    hier = f"{PACKAGE}.core.hierarchy"
    assert not {red, ref} & _closure(hier), "the hierarchy imports neither verb"


# -- (c) the VTK algorithms never import pyvista ----------------------------------------


@pytest.mark.parametrize("name", ALGORITHMS)
def test_algorithms_never_import_pyvista(name):
    bad = [f"line {line}: {m}" for line, m in GRAPH[name]
           if m == "pyvista" or m.startswith("pyvista.")]
    assert not bad, f"{name} imports pyvista (ParaView's VTK has none): {bad}"
