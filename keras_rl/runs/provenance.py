"""Where a run came from: library versions, the command, the code version and the machine."""

from __future__ import annotations

import functools
import os
import platform
import subprocess
import sys
from pathlib import Path


@functools.lru_cache(maxsize=1)
def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or ``platform.processor()`` elsewhere."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


@functools.lru_cache(maxsize=1)
def git_state() -> dict[str, object]:
    """``{"commit": sha, "dirty": bool}`` of the checkout this package runs from, or nulls
    when it is not run from a git checkout (an installed wheel)."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10)
        if commit.returncode != 0:
            return {"commit": None, "dirty": None}
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=10)
        return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def library_versions(framework: str = "keras") -> dict[str, str]:
    import gymnasium
    import keras
    import numpy
    import tensorflow

    from keras_rl import __version__

    versions = {"keras_rl": __version__, "python": platform.python_version(),
                "tensorflow": tensorflow.__version__, "keras": keras.__version__,
                "keras_backend": keras.backend.backend(), "gymnasium": gymnasium.__version__,
                "numpy": numpy.__version__}
    if framework == "torch":
        versions["torch"] = sys.modules["torch"].__version__ if "torch" in sys.modules else "not imported"
    return versions


def command_line() -> str:
    """The command that produced this run, as a user would type it."""
    prog = Path(sys.argv[0]).name
    if prog in ("__main__.py", "keras-rl", "cli.py"):
        prog = "keras-rl"
    elif prog.endswith(".py"):
        prog = f"python {sys.argv[0]}"
    return " ".join([prog, *sys.argv[1:]])


def provenance() -> dict[str, object]:
    """The machine and code version a run was made with (``summary.json``'s ``provenance``)."""
    return {"cpu_model": cpu_model(), **git_state(), "cwd": os.getcwd()}
