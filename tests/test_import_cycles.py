"""No import circles inside `lerobot_unidextok` (with `converters/` and `configs/`), the simulator
`lerobot_env_unidextok` and the plugin `lerobot_policy_unidextok`: every module's imports, read with `ast`; and
function-local imports of the packages' own modules held at their count.

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
PACKAGES = (PACKAGE, "lerobot_env_unidextok", "lerobot_policy_unidextok")  # the distribution's three packages
ROOT = Path(__file__).resolve().parents[1]
# the package and the checkout folders pyproject.toml's package-dir installs inside it
PACKAGE_DIR = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
SOURCES = {**{name: ROOT / name for name in PACKAGES}, **{name: ROOT / folder for name, folder in PACKAGE_DIR.items()}}
# Function-local imports of the three packages' own modules (`local_imports`): each says why it is local (an
# optional dependency, start-up time). Issue 55 found 110 and asked for 102 at most; lower this when you remove one.
MAX_LOCAL_IMPORTS = 102


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


def test_the_simulator_is_in_the_graph_and_its_old_circle_is_gone():
    """`hand_model -> urdf_hand -> tasks -> hand_model` (and `urdf_model`) was closed by function-local imports;
    the choice of a hand's model is `sim_hands`, above both sources, and the objects' shapes are below them."""
    graph = import_graph()
    assert "lerobot_env_unidextok.hand_model" in graph and "lerobot_policy_unidextok" in graph
    assert graph["lerobot_env_unidextok.hand_model"].isdisjoint(
        {"lerobot_env_unidextok.urdf_hand", "lerobot_env_unidextok.urdf_model", "lerobot_env_unidextok.tasks"}
    )
    assert {"lerobot_env_unidextok.urdf_hand", "lerobot_env_unidextok.hand_model"} <= graph[
        "lerobot_env_unidextok.sim_hands"
    ]


def local_imports() -> list[str]:
    """`file:line` of every import of the packages' own modules inside a function (relative imports included)."""
    found = []
    for path in sorted(p for name in PACKAGES for p in (ROOT / name).rglob("*.py")):
        for fn in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                own = (isinstance(node, ast.Import) and any(a.name.split(".")[0] in PACKAGES for a in node.names)) or (
                    isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").split(".")[0] in PACKAGES)
                )
                if own:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return sorted(set(found))  # a function nested in another is walked twice


def test_function_local_imports_of_the_packages_own_modules_do_not_grow():
    found = local_imports()
    assert len(found) <= MAX_LOCAL_IMPORTS, (
        f"{len(found)} function-local imports of the packages' own modules (at most {MAX_LOCAL_IMPORTS}): import "
        "at the top unless the module is heavy or optional, and say why beside it:\n" + "\n".join(found)
    )


def test_the_simulator_imports_mujoco_only_through_its_gl_module():
    """MuJoCo reads MUJOCO_GL once, when it loads: `lerobot_env_unidextok.gl` chooses the backend first, so it is
    the one module of the simulator that imports MuJoCo (a headless `lerobot-eval` aborted in GLFW when a hand's
    model loaded MuJoCo before the env chose)."""
    folder = ROOT / "lerobot_env_unidextok"
    direct = [str(p.relative_to(ROOT)) for p in folder.rglob("*.py") if p.name != "gl.py"
              and "mujoco" in {n.split(".")[0] for n in _imported_names("lerobot_env_unidextok.x", p)}]  # fmt: skip
    assert direct == [], direct


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
