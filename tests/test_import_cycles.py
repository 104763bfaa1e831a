"""No import circles inside `lerobot_unidextok` (with `converters/` and `configs/`): every module's imports, read with `ast`.

Counted: every `import` / `from ... import` anywhere in a module, at the top or inside a function, and
`importlib.import_module("<literal>")`. A function-level import that closes a circle still ties the two
modules together (neither can be read or tested without the other); laziness is for heavy or optional
dependencies, never for hiding a circle. Not counted: the implicit import of a module's parent packages,
and imports of a computed name (the converters package found by `conversion.registry` at run time, the
way plugins are discovered).
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

PACKAGE = "lerobot_unidextok"
ROOT = Path(__file__).resolve().parents[1]
# the package and the checkout folders pyproject.toml's package-dir installs inside it
PACKAGE_DIR = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
SOURCES = {PACKAGE: ROOT / PACKAGE, **{name: ROOT / folder for name, folder in PACKAGE_DIR.items()}}


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package (a package is its `__init__`)."""
    out = {}
    for prefix, folder in SOURCES.items():
        for path in folder.rglob("*.py"):
            parts = [*prefix.split("."), *path.relative_to(folder).with_suffix("").parts]
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _imported_names(module: str, path: Path) -> set[str]:
    """Every dotted name the module imports (absolute), including `from x import y` as `x.y`."""
    names: set[str] = set()
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            names.update(f"{base}.{alias.name}" for alias in node.names)  # a module, or a name in module `base`
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            names.add(node.args[0].value)
    return names


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (a name that is not a module counts as its module)."""
    modules = _modules()
    graph = {}
    for module, path in modules.items():
        deps = set()
        for name in _imported_names(module, path):
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                deps.add(name)
        graph[module] = deps
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each as a closed path."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
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
                components.append(_closed_path(graph, sorted(component)))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def _closed_path(graph: dict[str, set[str]], component: list[str]) -> list[str]:
    """One circle through the component's first module (breadth-first back to it), for the message."""
    start, members = component[0], set(component)
    parents: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(parents[path[-1]])
                    return [*reversed(path), start]
                if w not in parents:
                    parents[w] = v
                    nxt.append(w)
        frontier = nxt
    return component


def test_the_package_has_no_import_cycles():
    cycles = import_cycles(import_graph())
    assert not cycles, "import circles (move the shared piece down a layer):\n" + "\n".join(
        " -> ".join(c) for c in cycles
    )


def test_the_checker_finds_circles_through_function_level_and_literal_imports(tmp_path):
    """The checker itself: a circle closed by a function-level import or by `importlib.import_module` of a
    literal is found; a one-way chain is not."""
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c", "a"]]
    module = tmp_path / "m.py"
    module.write_text(
        "import importlib\n"
        "from lerobot_unidextok.hands import spec\n"
        "def f():\n"
        "    from lerobot_unidextok.hands.registry import get\n"
        "    importlib.import_module('lerobot_unidextok.conversion.datatrove')\n"
    )
    assert _imported_names("lerobot_unidextok.m", module) >= {
        "lerobot_unidextok.hands.spec",
        "lerobot_unidextok.hands.registry.get",
        "lerobot_unidextok.conversion.datatrove",
    }
