"""docs/figures.py (the figures the pages state, and their sources) as a module for the tests that compare them:
``from docs_figures import figures``."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

FILE = Path(__file__).resolve().parents[1] / "docs" / "figures.py"


def load():
    """docs/figures.py, loaded once per process (it is a script beside the pages, not a package module)."""
    if "docs_figures_module" not in sys.modules:
        spec = importlib.util.spec_from_file_location("docs_figures_module", FILE)
        module = sys.modules[spec.name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    return sys.modules["docs_figures_module"]


figures = load()
