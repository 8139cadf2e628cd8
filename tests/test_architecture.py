"""The package's shape, read from its source: modules import one another without circles, the product imports
nothing of the lab (warp_cloth.lab: bench, study, the Newton comparison) and the kernels nothing outside them.

An import counts wherever it is written (at the top of a module or inside a function: both make the module
depend on the other); one under ``if TYPE_CHECKING:`` does not, as it never runs.
"""

import ast
from pathlib import Path

from conftest import REPO

# Where each package's modules live (the package-dir mapping of pyproject.toml).
PACKAGE_FOLDERS = {"warp_cloth": REPO / "warp_cloth", "warp_cloth.kernels": REPO / "kernels"}
LAB = "warp_cloth.lab"


def module_files() -> dict[str, Path]:
    modules = {}
    for package, folder in PACKAGE_FOLDERS.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join((package, *parts))] = path
    return modules


def _type_checking_only(node: ast.AST) -> bool:
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """Every import statement of a module that runs, at any depth."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif _type_checking_only(node):
            yield from (n for child in node.orelse for n in _imports_in(child))
        else:
            yield from _imports(node)


def _imports_in(node: ast.AST):
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        yield node
    else:
        yield from _imports(node)


def imported_modules(name: str, path: Path, known: set[str]) -> set[str]:
    """The package's modules that module ``name`` imports (``from P import m`` imports module P.m where
    there is one, else P itself)."""

    def known_prefix(dotted: str) -> str | None:
        while dotted and dotted not in known:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in _imports(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {known_prefix(alias.name) for alias in node.names}
            continue
        base = node.module or ""
        if node.level:
            anchor = package.split(".")[:len(package.split(".")) - (node.level - 1)]
            base = ".".join(anchor + ([base] if base else []))
        for alias in node.names:
            found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else known_prefix(base))
    return found - {None, name}


def import_graph() -> dict[str, set[str]]:
    files = module_files()
    return {name: imported_modules(name, path, set(files)) for name, path in files.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_import_graph_is_read_as_python_resolves_it():
    graph = import_graph()
    assert "warp_cloth.kernels.colliders" in graph["warp_cloth.kernels.attachments"]  # from .colliders import ...
    assert "warp_cloth.kernels.motion" in graph["warp_cloth.device_model"]  # from warp_cloth.kernels import motion
    assert "warp_cloth.output" in graph["warp_cloth.writers.usd"]  # from .. import output
    assert "warp_cloth.writers" in graph["warp_cloth.cli"]  # inside a function: from .writers import UsdWriter
    assert "warp_cloth.simulator" not in graph["warp_cloth"]  # under TYPE_CHECKING only
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles():
    assert cycles(import_graph()) == []


def test_nothing_outside_the_lab_imports_it():
    graph = import_graph()
    assert any(name.startswith(f"{LAB}.") for name in graph)
    outside = {name: sorted(m for m in imported if m == LAB or m.startswith(f"{LAB}."))
               for name, imported in graph.items() if not (name == LAB or name.startswith(f"{LAB}."))}
    assert {name: lab for name, lab in outside.items() if lab} == {}


def test_the_command_line_names_the_lab_only_in_its_table_of_lab_commands():
    """The one way from the product to the lab: ``warp-cloth bench`` and ``study`` import their module by its
    name in cli's LAB_COMMANDS when asked for, so that no other command loads any of the lab."""
    from warp_cloth import cli

    files = module_files()
    assert set(cli.LAB_COMMANDS) == {"bench", "study"}
    assert all(module in files and module.startswith(f"{LAB}.") for module in cli.LAB_COMMANDS.values())
    for name, path in files.items():
        if name == LAB or name.startswith(f"{LAB}."):
            continue
        named = [node.value for node in ast.walk(ast.parse(path.read_text()))
                 if isinstance(node, ast.Constant) and isinstance(node.value, str) and LAB in node.value]
        assert sorted(named) == (sorted(cli.LAB_COMMANDS.values()) if name == "warp_cloth.cli" else []), name


def test_kernels_import_nothing_of_the_package_outside_them():
    graph = import_graph()
    kernels = "warp_cloth.kernels"
    outside = {name: sorted(m for m in imported if not (m == kernels or m.startswith(f"{kernels}.")))
               for name, imported in graph.items() if name == kernels or name.startswith(f"{kernels}.")}
    assert {name: others for name, others in outside.items() if others} == {}


def test_an_integrators_name_becomes_an_object_in_one_place():
    """Every integrator a scene may name has its object (warp_cloth/integrators.py), and no other module of
    the product compares a name with one: they ask the object. The scene's own check of its keys and the
    lab's choice of workloads by name are the exceptions."""
    from warp_cloth.integrators import BY_NAME
    from warp_cloth.scene import INTEGRATORS

    assert set(BY_NAME) == set(INTEGRATORS)
    comparing = []
    for name, path in module_files().items():
        if name in ("warp_cloth.integrators", "warp_cloth.scene") or name == LAB or name.startswith(f"{LAB}."):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare) and any(isinstance(c, ast.Constant) and c.value in INTEGRATORS
                                                     for c in [node.left, *node.comparators]):
                comparing.append(f"{name}:{node.lineno}")
    assert comparing == []
