"""Load a script of ``reproductions/`` as a module, the one way the tests do it."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

REPRODUCTIONS = Path(__file__).resolve().parents[1] / "reproductions"


def load_reproduction(name: str) -> ModuleType:
    """``reproductions/<name>.py``, executed as a module of that name."""
    spec = importlib.util.spec_from_file_location(name, REPRODUCTIONS / f"{name}.py")
    assert spec is not None and spec.loader is not None, name
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
