"""A fourth post in one file (``tests/toy_post.py``), registered with one call, runs end to end:
``reproduce``, ``--resume`` (extending it bit for bit) and ``aggregate``, with no file under
``keras_rl/`` touched (the test checks that too)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import toy_post

from keras_rl import registry
from keras_rl.cli import main
from keras_rl.errors import ConfigError
from keras_rl.learners import table
from keras_rl.runs.files import read_episodes

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.setattr(registry, "EXPERIMENTS", dict(registry.EXPERIMENTS))
    monkeypatch.setattr(table, "IMPLEMENTATIONS", dict(table.IMPLEMENTATIONS))
    registry.register(toy_post.EXPERIMENT, toy_post.LEARNERS)
    return toy_post.EXPERIMENT


def _reproduce(out: Path, *more: str) -> int:
    return main(
        ["reproduce", "toy", "--seeds", "0-1", "--no-progress", "--min-success-rate", "0", "--out", str(out), *more]
    )


@pytest.mark.slow
def test_a_fourth_post_registered_from_outside_runs_reproduce_resume_and_aggregate(toy, tmp_path, capsys):
    before = subprocess.run(["git", "status", "--porcelain", "keras_rl"], cwd=ROOT, capture_output=True, text=True)
    assert _reproduce(tmp_path / "straight", "--episodes", "8") == 0, capsys.readouterr().err
    straight = read_episodes(tmp_path / "straight" / "seed_1" / "episodes.csv")
    assert len(straight) == 8 and any(r["loss"] is not None for r in straight)
    assert _reproduce(tmp_path / "run", "--episodes", "5") == 0
    assert _reproduce(tmp_path / "run", "--episodes", "8", "--resume") == 0  # extended from its final checkpoint
    extended = read_episodes(tmp_path / "run" / "seed_1" / "episodes.csv")
    drop = lambda rows: [{k: v for k, v in r.items() if k != "wall_seconds"} for r in rows]  # noqa: E731
    assert drop(extended) == drop(straight)  # bit for bit
    assert main(["aggregate", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "summary.md").read_text().startswith("# toy (faithful, keras), 2 seeds")
    assert (tmp_path / "run" / "curves.png").is_file()
    after = subprocess.run(["git", "status", "--porcelain", "keras_rl"], cwd=ROOT, capture_output=True, text=True)
    assert after.stdout == before.stdout


def test_a_name_is_registered_once(toy):
    with pytest.raises(ConfigError, match="registered already"):
        registry.register(toy_post.EXPERIMENT, toy_post.LEARNERS)
