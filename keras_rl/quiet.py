"""TensorFlow's start-up lines ("All log messages before absl::InitializeLog()", "Could not find
cuda drivers") are written by its C++ libraries straight to file descriptor 2 while the module
loads, before ``TF_CPP_MIN_LOG_LEVEL`` is read, and they came twice on every command. While
``TF_CPP_MIN_LOG_LEVEL`` is 2 or more (``keras_rl`` sets 3 unless the user chose a level),
the one ``import tensorflow`` of a process runs with descriptor 2 pointed at /dev/null; an
import error is still raised and shown as usual, after the descriptor is restored.
"""

from __future__ import annotations

import contextlib
import importlib.abc
import importlib.util
import os
import sys


@contextlib.contextmanager
def stderr_descriptor_silenced():
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


class _QuietLoader(importlib.abc.Loader):
    def __init__(self, loader):
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        with stderr_descriptor_silenced():
            self._loader.exec_module(module)


class QuietTensorFlowImport(importlib.abc.MetaPathFinder):
    """A finder that hands ``tensorflow``'s own spec back with a loader that silences fd 2."""

    def find_spec(self, name, path=None, target=None):
        if name != "tensorflow":
            return None
        sys.meta_path.remove(self)  # once: find the real spec without us
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _QuietLoader(spec.loader)
        return spec


def install() -> None:
    """Quiet the one TensorFlow import of this process, unless TF's log level asks for its lines."""
    try:
        level = int(os.environ.get("TF_CPP_MIN_LOG_LEVEL", "0"))
    except ValueError:
        level = 0
    if level >= 2 and "tensorflow" not in sys.modules:
        if not any(isinstance(f, QuietTensorFlowImport) for f in sys.meta_path):
            sys.meta_path.insert(0, QuietTensorFlowImport())
