"""The engine's import graph has no cycle, and the engine imports no converter.

A cycle makes import order matter (a name half-defined when the other module
reads it) and hides which module is the foundation; the converters are plug-ins
on top of the engine, so ``gaslight_usd`` must never import ``converters`` and
no converter another. Imports inside functions count too (a lazy import that
closes a cycle is still a circle in the design); ``if TYPE_CHECKING:`` blocks do
not, and neither does the implicit import of a module's parent package.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"gaslight_usd": ROOT / "gaslight_usd", "gaslight_usd.converters": ROOT / "converters"}


def _modules() -> dict[str, Path]:
    found = {}
    for prefix, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join([prefix, *parts])] = path
    return found


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST) -> list[tuple[int, str | None, list[str]]]:
    """(level, module, names) of every import outside ``if TYPE_CHECKING:``."""
    out = []
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.Import):
            out.extend((0, alias.name, []) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            out.append((node.level, node.module, [a.name for a in node.names]))
        stack.extend(ast.iter_child_nodes(node))
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports."""
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        edges: set[str] = set()
        for level, module, names in _imports(ast.parse(path.read_text(), str(path))):
            if level:
                base = package.split(".")[: len(package.split(".")) - (level - 1)]
                target = ".".join(base + ([module] if module else []))
            else:
                target = module or ""
            for imported in names or [None]:
                full = f"{target}.{imported}" if imported else target
                if full in modules:
                    edges.add(full)
                elif target in modules:
                    edges.add(target)
        edges.discard(name)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first repeated last), or None."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (found := visit(start)):
            return found
    return None


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_engine_imports_no_converter_and_converters_not_each_other():
    for module, edges in import_graph().items():
        plugins = {e for e in edges if e.startswith("gaslight_usd.converters")}
        if module.startswith("gaslight_usd.converters"):
            assert not plugins, f"{module} imports another converter: {sorted(plugins)}"
        else:
            assert not plugins, f"the engine module {module} imports {sorted(plugins)}"


def test_the_graph_sees_imports():
    """The walk finds real edges (so an empty graph cannot pass the checks above)."""
    graph = import_graph()
    assert "gaslight_usd.registry" in graph["gaslight_usd.chain"]
    assert "gaslight_usd.poses.colmap" in graph["gaslight_usd.poses"]
