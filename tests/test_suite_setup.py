"""The suite's own set-up: `make test`'s `--dist loadgroup` really keeps an xdist group in one
process (tests/conftest.py relies on it for shared training fixtures and for Ray's tests).
pytest 9.2 broke it silently with pytest-xdist 3.8, so a version bump is caught here."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytest.importorskip("xdist")

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
