"""The ``mast`` package's layers import only downwards (README, the orchestration/ row):
core <- data <- analyses <- diagnosis, batch, hosts <- cli. A module that reaches up a layer
(or across, between the three top layers) fails here with its name and the import."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "orchestration"
# what each layer may import from the package (besides itself)
ALLOWED = {
    "core": set(),
    "data": {"core"},
    "analyses": {"core", "data"},
    "diagnosis": {"core", "data", "analyses"},
    "batch": {"core", "data", "analyses"},
    "hosts": {"core"},
    "cli": {"core", "data", "analyses", "diagnosis", "batch", "hosts"},
}


def _imported_layers(path: Path) -> list[tuple[str, str]]:
    """(layer, the import as written) for every import of the package inside ``path``."""
    own = list(path.relative_to(PACKAGE).with_suffix("").parts)
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the module's own package
                base = own[:-1][: len(own) - node.level] if node.level > 1 else own[:-1]
                target = base + (node.module.split(".") if node.module else [])
                if not target:  # from . import x (the package root)
                    target = [alias.name for alias in node.names][:1]
            elif node.module and node.module.split(".")[0] == "mast":
                target = node.module.split(".")[1:] or [alias.name for alias in node.names][:1]
            else:
                continue
            found.append((target[0], ast.unparse(node)))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "mast" and len(parts) > 1:
                    found.append((parts[1], ast.unparse(node)))
    return found


def test_every_module_belongs_to_a_layer():
    loose = [p.name for p in PACKAGE.glob("*.py") if p.stem not in ALLOWED and p.name != "__init__.py"]
    assert not loose, f"modules outside the layers: {loose}"


def test_imports_go_only_downwards():
    wrong = []
    for path in sorted(PACKAGE.rglob("*.py")):
        layer = path.relative_to(PACKAGE).parts[0].removesuffix(".py")
        if layer == "__init__":
            continue
        for target, statement in _imported_layers(path):
            if target != layer and target in ALLOWED and target not in ALLOWED[layer]:
                wrong.append(f"{path.relative_to(PACKAGE)}: {statement}")
    assert not wrong, "imports that reach up or across a layer:\n" + "\n".join(wrong)


# --------------------------------------------------------------------------- private names stay in their module
ROOT = PACKAGE.parent


def _project_modules() -> dict[str, Path]:
    """{dotted name: file} of every module in fmus/ and orchestration/ (imported as ``mast``)."""
    modules = {}
    for top in ("fmus", "orchestration"):
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            parts[0] = "mast" if parts[0] == "orchestration" else parts[0]
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def _absolute(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The module an ``ImportFrom`` in ``module`` (file ``path``) reads from, relative imports resolved."""
    if not node.level:
        return node.module or ""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    package = package[: len(package) - node.level + 1]
    return ".".join(package + ([node.module] if node.module else []))


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_reaches(modules: dict[str, Path], root: Path = ROOT) -> list[str]:
    """Every ``from m import _x`` and ``m._x`` (m a project module bound by an import) across modules."""
    wrong = []
    for module, path in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        aliases = {}  # local name -> the project module it is
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                source = _absolute(module, path, node)
                for alias in node.names:
                    if f"{source}.{alias.name}" in modules:
                        aliases[alias.asname or alias.name] = f"{source}.{alias.name}"
                    elif source in modules and source != module and _private(alias.name):
                        wrong.append(f"{path.relative_to(root)}:{node.lineno}: {ast.unparse(node)}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in modules:
                        aliases[alias.asname or alias.name] = alias.name
        for node in ast.walk(tree):
            if not isinstance(node, ast.Attribute) or not _private(node.attr):
                continue
            target = ast.unparse(node.value)  # a.b._x after "import a.b", or m._x after "... as m"
            target = aliases.get(target, target if target in modules and "." in target else None)
            if target is not None and target != module:
                wrong.append(f"{path.relative_to(root)}:{node.lineno}: {ast.unparse(node)} ({target})")
    return wrong


def test_no_private_name_is_imported_across_modules():
    """A name with a leading underscore (not a dunder) is its module's own: no other module of fmus/ or
    orchestration/ imports it (``from m import _x``) or reads it (``m._x``). What another module needs gets
    a public name and a docstring."""
    wrong = _private_reaches(_project_modules())
    assert not wrong, "private names used across modules:\n" + "\n".join(wrong)


def test_the_private_name_check_sees_both_forms(tmp_path):
    """The check above on a made-up pair of modules: both forms found, a dunder and the module itself not."""
    (tmp_path / "a.py").write_text("_x = 1\n__version__ = '1'\nprint(_x)\n")
    (tmp_path / "b.py").write_text("from .a import _x, __version__\nfrom . import a as m\nprint(m._x, m.__version__)\n")
    (tmp_path / "__init__.py").write_text("")
    modules = {"p": tmp_path / "__init__.py", "p.a": tmp_path / "a.py", "p.b": tmp_path / "b.py"}
    found = _private_reaches(modules, tmp_path)
    assert [line.split(": ", 1)[1] for line in found] == ["from .a import _x, __version__", "m._x (p.a)"]


# --------------------------------------------------------------------------- no import circles
def _imports(modules: dict[str, Path]) -> dict[str, dict[str, int]]:
    """{module: {project module it imports: line}}: every import statement, wherever it stands (in a function,
    under ``if TYPE_CHECKING``), packages' ``__init__`` left out as targets (importing a submodule runs its
    package first; that order is Python's, not a dependency of the package's own code)."""
    graph: dict[str, dict[str, int]] = {}
    for module, path in modules.items():
        edges = graph.setdefault(module, {})
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                source = _absolute(module, path, node)
                names = [f"{source}.{alias.name}" for alias in node.names]
                targets = [n for n in names if n in modules]
                if any(n not in modules for n in names):  # a name defined in the module ``source``
                    targets.append(source)
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:  # a name inside a module: that module
                    target = target.rpartition(".")[0]
                if target and target != module and modules[target].name != "__init__.py":
                    edges.setdefault(target, node.lineno)
    return graph


def _circles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Every circle of ``graph`` as one path m0 -> m1 -> ... -> m0 through a strongly connected component of
    more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                elif child in on_stack:
                    low[v] = min(low[v], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    components.append(set(component))
    circles = []
    for component in components:  # one shortest way back to the start inside the component
        start = min(component)
        paths = {start: [start]}
        frontier = [start]
        found = None
        while frontier and found is None:
            nxt = []
            for v in frontier:
                for w in sorted(graph[v]):
                    if w == start:
                        found = paths[v] + [start]
                        break
                    if w in component and w not in paths:
                        paths[w] = paths[v] + [w]
                        nxt.append(w)
                if found:
                    break
            frontier = nxt
        circles.append(found)
    return circles


def test_no_import_circles():
    """No module of fmus/ or orchestration/ imports, at any depth, a module that imports it back: not across
    packages, not inside one, not through a function-level or a TYPE_CHECKING import."""
    graph = _imports(_project_modules())
    circles = _circles(graph)
    shown = [" -> ".join(f"{a} (line {graph[a][b]})" for a, b in zip(c, c[1:])) + f" -> {c[-1]}" for c in circles]
    assert not circles, "import circles:\n" + "\n".join(shown)


def test_the_circle_check_names_a_circle():
    graph = {"p.a": {"p.b": 3}, "p.b": {"p.c": 5}, "p.c": {"p.a": 7, "p.d": 8}, "p.d": {}, "p.e": {"p.d": 1}}
    assert _circles(graph) == [["p.a", "p.b", "p.c", "p.a"]]
    assert _circles({"p.a": {"p.b": 1}, "p.b": {}}) == []
