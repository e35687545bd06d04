"""The house rules, read from the source with ast: no import cycle in warp_sim, no module over 600 lines, no
import inside a function (except optional dependencies), and every layer importing only from below it."""
import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "warp_sim"
MAX_LINES = 600
#: imports allowed inside a function: optional dependencies only, imported where they are used
OPTIONAL = {"matplotlib.backends.backend_agg", "matplotlib.figure", "pandas", "distributed"}
#: the layers, bottom first; a module may import its own layer and those listed before it
LAYERS = ["util", "scene", "kernels", "core", "detection", "forces", "solvers", "passes", "assembly", "adjoints",
          "stages", "simulator", "gradients", "cluster", "sweep", "preview", "demo", "studies", "examples", "cli",
          "__main__", "__init__"]


def module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(tree: ast.AST, name: str, is_package: bool, modules) -> list[tuple[str, ast.AST]]:
    """(module, node) for every warp_sim module an ast imports, relative imports resolved."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("warp_sim"):   # "from . import checks" imports the module checks
                found.extend((f"{target}.{alias.name}" if f"{target}.{alias.name}" in modules else target, node)
                             for alias in node.names)
        elif isinstance(node, ast.Import):
            found.extend((alias.name, node) for alias in node.names if alias.name.startswith("warp_sim"))
    return found


def graph() -> dict:
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    edges = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        targets = {t for t, _ in imported(tree, name, path.name == "__init__.py", modules) if t in modules}
        edges[name] = targets - {name}
    return edges


def test_no_import_cycle():
    edges = graph()
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for target in sorted(edges[node]):
            if state.get(target) == "open":
                cycle = stack[stack.index(target):] + [target]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if target not in state:
                visit(target)
        stack.pop()
        state[node] = "done"

    for node in sorted(edges):
        if node not in state:
            visit(node)


def layer(name: str) -> int:
    parts = name.split(".")
    return LAYERS.index(parts[1] if len(parts) > 1 else "__init__")


def test_layers_import_only_from_below():
    edges = graph()
    upward = [f"{a} -> {b}" for a, targets in edges.items() for b in targets
              if b != "warp_sim" and layer(b) > layer(a)]
    assert not upward, "imports from a higher layer: " + ", ".join(sorted(upward))


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_module_is_short_and_imports_at_the_top(path):
    source = path.read_text()
    assert len(source.splitlines()) <= MAX_LINES, f"{path.name} has over {MAX_LINES} lines"
    tree = ast.parse(source)
    for function in (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))):
        for node in ast.walk(function):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [node.module] if isinstance(node, ast.ImportFrom) else [a.name for a in node.names]
                assert all(n in OPTIONAL for n in names), \
                    f"{path.name}:{node.lineno} imports {names} inside {function.name}()"


def test_every_test_file_has_a_basename_of_its_own():
    """pytest imports test files by basename (no __init__.py in tests/): two of one name stop the whole run at
    collection."""
    names = [path.name for path in pathlib.Path(__file__).parent.rglob("test_*.py")]
    assert sorted(name for name in set(names) if names.count(name) > 1) == []
