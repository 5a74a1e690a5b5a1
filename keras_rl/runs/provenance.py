"""Where a run came from: library versions, the command, the code version and the machine."""

from __future__ import annotations

import functools
import hashlib
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


SIMD_FLAGS = (
    "sse4_2",
    "avx",
    "avx2",
    "fma",
    "avx512f",
    "avx512bw",
    "avx512vl",
    "avx512_vnni",
    "avx512_bf16",
    "amx_tile",
)
"""The instruction-set flags that choose TensorFlow's and oneDNN's kernels (and so how a sum
rounds): two CPUs of one model name can differ here, and then in the last bits of a run."""


def cpu_isa() -> list[str]:
    """The ``SIMD_FLAGS`` this CPU has (``/proc/cpuinfo``); empty where it cannot be read."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                have = set(line.split(":", 1)[1].split())
                return [f for f in SIMD_FLAGS if f in have]
    except OSError:
        pass
    return []


@functools.lru_cache(maxsize=1)
def git_state() -> dict[str, object]:
    """``{"commit": sha, "code_tree": git's hash of keras_rl/ at that commit, "dirty": bool,
    "diff_sha256": hash of the uncommitted diff of keras_rl/ or None}`` of the checkout this
    package runs from; nulls when it is not a git checkout (a wheel)."""
    root = Path(__file__).resolve().parents[1]
    unknown: dict[str, object] = {"commit": None, "code_tree": None, "dirty": None, "diff_sha256": None}
    if not (root.parent / ".git").exists():
        return unknown
    try:
        git = ["git", "-C", str(root.parent)]
        commit = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
        if commit.returncode != 0:
            return unknown
        tree = subprocess.run([*git, "rev-parse", "HEAD:keras_rl"], capture_output=True, text=True, timeout=10)
        diff = subprocess.run([*git, "diff", "HEAD", "--", "keras_rl"], capture_output=True, timeout=30).stdout
        return {
            "commit": commit.stdout.strip(),
            "code_tree": tree.stdout.strip() or None,
            "dirty": bool(diff.strip()),
            "diff_sha256": hashlib.sha256(diff).hexdigest() if diff.strip() else None,
        }
    except (OSError, subprocess.SubprocessError):
        return unknown


def code_version() -> str:
    """What "the same code" means when runs are reused: the package's own files at the run's
    commit (git's hash of ``keras_rl/``, so a commit that changes only docs or results does
    not invalidate runs), plus a hash of any uncommitted change to them; the package version
    where there is no checkout."""
    return code_version_of(git_state(), None)


def code_version_of(provenance: dict, package_version: str | None) -> str:
    """The code version a run recorded (``summary.json``'s provenance)."""
    commit = provenance.get("code_tree") or (f"commit {provenance['commit']}" if provenance.get("commit") else None)
    if commit is None:
        from keras_rl import __version__

        return f"keras_rl {package_version or __version__} (no commit recorded)"
    return commit + (f"+dirty.{provenance['diff_sha256'][:12]}" if provenance.get("dirty") else "")


def library_versions(framework: str = "keras") -> dict[str, str]:
    import gymnasium
    import keras
    import numpy
    import tensorflow

    from keras_rl import __version__

    versions = {
        "keras_rl": __version__,
        "python": platform.python_version(),
        "tensorflow": tensorflow.__version__,
        "keras": keras.__version__,
        "keras_backend": keras.backend.backend(),
        "gymnasium": gymnasium.__version__,
        "numpy": numpy.__version__,
    }
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


ARITHMETIC_ENVIRONMENT = ("XLA_FLAGS", "TF_XLA_FLAGS", "TF_ENABLE_ONEDNN_OPTS")
"""Environment variables that change a run's arithmetic without changing its code or config (XLA's
fast math, oneDNN's kernels): recorded where set, so that a set made under one can be told apart
from the code's own bits (issue 70's real changes). PyTorch's MKL and ATen switches are recorded as
``portable_torch``, which sets them."""


def arithmetic_environment() -> dict[str, str]:
    """Those of ``ARITHMETIC_ENVIRONMENT`` that are set, as set."""
    return {name: os.environ[name] for name in ARITHMETIC_ENVIRONMENT if name in os.environ}


def provenance() -> dict[str, object]:
    """The machine and code version a run was made with (``summary.json``'s ``provenance``); the
    arithmetic's environment only where some of it is set (a run made without any records none)."""
    environment = arithmetic_environment()
    return {
        "cpu_model": cpu_model(),
        "cpu_isa": cpu_isa(),
        **git_state(),
        **({"environment": environment} if environment else {}),
    }  # no working folder: it tells a reader nothing and leaks a path
