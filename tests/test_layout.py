"""The tree's shape: no import cycle between the project's modules, and short modules.

The import graph is read from the source with ``ast`` (every ``import`` statement, also those inside
functions; ``if TYPE_CHECKING:`` blocks excepted), so a cycle hidden by a late import is found too.
``from package import name`` counts as importing the submodule ``package.name`` when that is a module,
else the package itself.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("calib", "stereo_classic", "detectors", "benchmarks")
#: Modules allowed past the length limit: the numba kernels, unrolled by hand for speed.
LONG_MODULES = {"stereo_classic.matching._kernels.aggregate"}
MAX_LINES = 600


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """Project modules that module ``name`` imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules:
                    found.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                if sub in modules:
                    found.add(sub)
                elif base in modules:
                    found.add(base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    found.discard(name)
    return found


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def strongconnect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return out


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_import_reader_sees_late_and_relative_imports(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("def f():\n    from pkg import b\nfrom . import c\nfrom typing import TYPE_CHECKING\n"
                    "if TYPE_CHECKING:\n    import pkg.d\n")
    modules = {"pkg": path, "pkg.m": path, "pkg.b": path, "pkg.c": path, "pkg.d": path}
    assert _imports("pkg.m", path, modules) == {"pkg.b", "pkg.c"}


def test_no_import_cycle():
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    assert _cycles(graph) == []


def test_leaf_packages_import_no_other_project_package():
    """calib and detectors are leaves: stereo_classic and benchmarks build on them, never the other way."""
    modules = _modules()
    for leaf in ("calib", "detectors"):
        for name, path in modules.items():
            if name == leaf or name.startswith(leaf + "."):
                others = {m.split(".")[0] for m in _imports(name, path, modules)} - {leaf}
                assert not others, f"{name} imports {sorted(others)}"


def test_the_long_modules_exist():
    assert LONG_MODULES <= set(_modules())


@pytest.mark.parametrize("name", sorted(set(_modules()) - LONG_MODULES))
def test_module_is_short(name):
    lines = len(_modules()[name].read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{name} has {lines} lines (at most {MAX_LINES})"
