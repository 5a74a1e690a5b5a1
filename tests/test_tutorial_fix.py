"""``reproductions/tutorial_fix.py``: the tutorial's community fix against the tutorial as
published, read from run folders; its numbers checked against the folders by hand."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "results" / "engines" / "cartpole" / "compiled"


def arm(tmp_path: Path, name: str, seeds: range) -> Path:
    folder = tmp_path / name
    for seed in seeds:
        shutil.copytree(PUBLISHED / f"seed_{seed}", folder / f"seed_{seed}")
    return folder


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / "reproductions" / "tutorial_fix.py"), *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )


def test_the_report_counts_what_the_folders_hold(tmp_path):
    a, b = arm(tmp_path, "a", range(0, 10)), arm(tmp_path, "b", range(10, 20))
    out = tmp_path / "report.md"
    proc = run(str(a), str(b), "--labels", "published,issue-3080", "--write", str(out))
    assert proc.returncode == 0, proc.stderr
    text = out.read_text()
    for folder, seeds in ((a, range(0, 10)), (b, range(10, 20))):
        summaries = [json.loads((folder / f"seed_{s}" / "summary.json").read_text()) for s in seeds]
        wins = sum(s["success"] for s in summaries)
        means = []
        for s in seeds:
            with open(folder / f"seed_{s}" / "episodes.csv", newline="") as fh:
                steps = [int(r["steps"]) for r in csv.DictReader(fh)][:50]
            means.append(np.mean(steps))
        row = next(line for line in text.splitlines() if f"`{folder}`" in line)
        assert f"| {wins}/10 (" in row and f"| {np.median(means):.1f} (" in row
    assert "issue-3080 minus published" in text and "success rate difference: **" in text
    assert "tutorial_fix.py" in text  # the command that made it


def test_an_empty_arm_or_a_missing_folder_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    proc = run(str(PUBLISHED), str(tmp_path / "empty"))
    assert proc.returncode == 2 and "holds no finished seed" in proc.stderr
    proc = run(str(PUBLISHED), str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "is not a folder" in proc.stderr


@pytest.mark.parametrize("labels", ["one", "a,b,c", ",b"])
def test_labels_are_two_names(labels):
    proc = run(str(PUBLISHED), str(PUBLISHED), "--labels", labels)
    assert proc.returncode == 2 and "--labels" in proc.stderr
