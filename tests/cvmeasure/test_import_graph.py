"""cvmeasure's imports run one way: no cycle between its modules or between its packages.

The graph is read from the source (every ``import``, at module top and inside functions),
so an import moved into a function to hide a cycle still counts. Between the units of the
package -- each subpackage (``cvmeasure.part``, ``cvmeasure.driver`` ...) and each
top-level module (``cvmeasure.gcode`` ...) -- annotation-only imports (``if
TYPE_CHECKING:``) count too; between modules they do not (a component typing the object
that holds it, as the app's pages type their ``Operator``, never runs that import).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import cvmeasure

PACKAGE = Path(cvmeasure.__file__).parent


def _modules(package: Path) -> dict[str, Path]:
    out = {}
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _imported(module: str, path: Path, typing: bool) -> Iterator[str]:
    """The dotted names ``module`` imports (``from a import b`` gives ``a.b``); with
    ``typing`` False, not those under ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = set()
    if not typing:
        for node in ast.walk(tree):
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                skip |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's package up
                pkg = module if path.name == "__init__.py" else module.rpartition(".")[0]
                for _ in range(node.level - 1):
                    pkg = pkg.rpartition(".")[0]
                base = f"{pkg}.{base}" if base else pkg
            yield from (f"{base}.{a.name}" for a in node.names)


def import_graph(package: Path, *, typing: bool = True) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (the root ``__init__`` left out)."""
    modules = _modules(package)
    root = package.name
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        for name in _imported(module, path, typing):
            while name and name not in modules:  # a name in a module -> that module
                name = name.rpartition(".")[0]
            if name and name not in (root, module):
                graph[module].add(name)
    return graph


def unit_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The same graph between units: ``cvmeasure.<subpackage or module>``."""

    def unit(m: str) -> str:
        return ".".join(m.split(".")[:2])

    out: dict[str, set[str]] = {}
    for a, targets in graph.items():
        out.setdefault(unit(a), set()).update(unit(b) for b in targets if unit(b) != unit(a))
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def test_the_package_import_graph_is_acyclic():
    graph = import_graph(PACKAGE)
    assert len(graph) > 100 and "cvmeasure.part.measure" in graph["cvmeasure.api"]
    assert cycles(unit_graph(graph)) == []
    assert cycles(import_graph(PACKAGE, typing=False)) == []


def test_a_cycle_is_found(tmp_path):
    """The check itself: a package whose two subpackages import each other (one of them
    inside a function) is reported."""
    pkg = tmp_path / "pkg"
    for sub in ("a", "b"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "a" / "x.py").write_text("from pkg.b.y import f\n")
    (pkg / "b" / "y.py").write_text("def f():\n    from ..a import x\n")
    (pkg / "c.py").write_text("import pkg.a.x\n")
    graph = import_graph(pkg)
    assert cycles(unit_graph(graph)) == [["pkg.a", "pkg.b"]]
    assert cycles(graph) == [["pkg.a.x", "pkg.b.y"]]
