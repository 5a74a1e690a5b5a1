"""The suite's own set-up: `make test`'s `--dist loadgroup` really keeps an xdist group in one
process (tests/conftest.py relies on it for shared training fixtures and for Ray's tests).
pytest 9.2 broke it silently with pytest-xdist 3.8, so a version bump is caught here. And the CI
entry point `.ci/run` names a disk shortfall before pip runs into it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run_ci_with(tmp_path: Path, free_mib: int) -> subprocess.CompletedProcess[str]:
    """`.ci/run`, copied into a scratch tree, with `df` reporting `free_mib` and `make` a stand-in."""
    (tmp_path / ".ci").mkdir()
    shutil.copy(ROOT / ".ci" / "run", tmp_path / ".ci" / "run")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "df").write_text(
        f"#!/bin/sh\necho 'Filesystem 1M-blocks Used Available Capacity Mounted'\necho 'x 9 9 {free_mib} 1% /'\n"
    )
    (bin_dir / "make").write_text('#!/bin/sh\necho "make $*"\n')
    for tool in ("df", "make"):
        (bin_dir / tool).chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "TMPDIR": str(tmp_path)}
    return subprocess.run(
        ["bash", str(tmp_path / ".ci" / "run")], capture_output=True, text=True, env=env, timeout=60, check=False
    )


def test_ci_run_names_a_disk_shortfall_before_installing(tmp_path):
    proc = _run_ci_with(tmp_path, free_mib=900)
    assert proc.returncode == 2
    assert "error: .ci/run needs about 5120 MiB free" in proc.stderr and "it has 900 MiB" in proc.stderr
    assert "make" not in proc.stdout  # nothing installed


def test_ci_run_goes_on_to_make_test_with_room(tmp_path):
    proc = _run_ci_with(tmp_path, free_mib=50_000)
    assert proc.returncode == 0, proc.stderr
    assert "make test" in proc.stdout


GROUPED = """
import os
import pytest

@pytest.mark.xdist_group("one")
@pytest.mark.parametrize("i", range(6))
def test_grouped(i):
    with open(os.environ["WORKERS_FILE"], "a") as f:
        f.write(os.environ["PYTEST_XDIST_WORKER"] + "\\n")
"""


@pytest.mark.slow  # two pytest processes start (about 3 s)
def test_an_xdist_group_runs_in_one_process(tmp_path):
    pytest.importorskip("xdist")
    (tmp_path / "test_grouped.py").write_text(GROUPED)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-n",
            "2",
            "--dist",
            "loadgroup",
            "test_grouped.py",
        ],
        cwd=tmp_path,
        env={**os.environ, "WORKERS_FILE": str(tmp_path / "workers.txt")},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    workers = (tmp_path / "workers.txt").read_text().split()
    assert len(workers) == 6 and len(set(workers)) == 1, workers
