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
