"""The kernel's modules import each other without a circle, counting every import statement
(those for type checking alone and those inside functions too), and import no room above them."""

import ast
from pathlib import Path

import ata.core

CORE = Path(ata.core.__file__).resolve().parent


def _imports(path: Path) -> set[str]:
    """The ``ata`` modules a file's import statements name, wherever they stand."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names |= {node.module} | {f"{node.module}.{a.name}" for a in node.names
                                      if not a.name.startswith("__")}    # not ata.__version__
    return {n for n in names if n == "ata" or n.startswith("ata.")}


def _graph() -> dict[str, set[str]]:
    modules = {f"ata.core.{p.stem}": p for p in CORE.glob("*.py") if p.stem != "__init__"}
    return {m: {n for n in _imports(p) if n in modules and n != m} for m, p in modules.items()}


def test_the_kernel_imports_no_room_above_it():
    for path in CORE.glob("*.py"):
        above = {n for n in _imports(path) if n != "ata" and not n.startswith("ata.core")}
        assert not above, f"{path.name} imports {sorted(above)}"


def test_the_kernel_modules_import_each_other_without_a_circle():
    graph, done, path = _graph(), set(), []

    def visit(module: str) -> None:
        if module in path:
            raise AssertionError("import circle: " + " -> ".join(
                path[path.index(module):] + [module]))
        if module in done:
            return
        path.append(module)
        for other in sorted(graph[module]):
            visit(other)
        path.pop()
        done.add(module)

    for module in sorted(graph):
        visit(module)
    # the circle this guards against: the hook specs name the Mission their hooks receive
    assert "ata.core.mission" in graph["ata.core.hookspecs"]
