"""Helpers for tests that drive the command line in a subprocess, as a user would."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

CLI = [sys.executable, "-m", "keras_rl"]


def run_cli(*args, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=600, **kwargs)


def strict_json(path: Path):
    """JSON as the standard has it: NaN and Infinity are refused."""

    def refuse(name):
        raise ValueError(f"{path} holds {name}, which is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


def default_signals() -> None:
    """``preexec_fn`` for a child that is sent SIGINT or SIGTERM: the default handlers, whatever
    the test process (pytest, xdist) installed."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def wait_for_rows(proc: subprocess.Popen, csv_path: Path, rows: int, seconds: float = 300, poll: float = 0.05) -> None:
    """Wait until ``csv_path`` holds ``rows`` data rows, ``proc`` ends, or ``seconds`` pass."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        if csv_path.is_file() and len(csv_path.read_text().splitlines()) - 1 >= rows:
            return
        time.sleep(poll)


def start_cli(*args, **kwargs) -> subprocess.Popen:
    """The CLI started in a subprocess that a test will signal: text pipes, default handlers."""
    return subprocess.Popen(
        [*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_signals, **kwargs
    )


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (from /proc)."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            parents[int(stat.parent.name)] = int(fields[1])
        except (OSError, IndexError, ValueError):
            continue
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def reproduction(name: str):
    """The script ``reproductions/<name>.py`` as a module (the folder is scripts, not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        name, Path(__file__).resolve().parents[1] / "reproductions" / f"{name}.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # a dataclass finds its module by name
    spec.loader.exec_module(module)
    return module
