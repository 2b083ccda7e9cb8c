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
            if node.level:                      # relative: from the module's own package
                base = own[:-1][: len(own) - node.level] if node.level > 1 else own[:-1]
                target = base + (node.module.split(".") if node.module else [])
                if not target:                  # from . import x (the package root)
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
        aliases = {}                                      # local name -> the project module it is
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
            target = ast.unparse(node.value)              # a.b._x after "import a.b", or m._x after "... as m"
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
