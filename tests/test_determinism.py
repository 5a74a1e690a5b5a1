"""Same seed, identical curve: two separate processes per case."""

import csv
import subprocess
import sys

import pytest


def run(out, experiment, seed, episodes, *extra):
    proc = subprocess.run([sys.executable, "-m", "keras_rl", "reproduce", experiment, "--seeds", str(seed),
                           "--episodes", str(episodes), "--no-progress", "--set", "stop_at_threshold=false",
                           "--out", str(out), *extra], capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stderr
    with open(out / f"seed_{seed}" / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == episodes
    # wall_seconds is the one column that is not a function of the seed
    return [{k: v for k, v in row.items() if k != "wall_seconds"} for row in rows]


def test_pendulum_same_seed_gives_an_identical_episodes_csv(tmp_path):
    first, second = run(tmp_path / "a", "pendulum", 5, 30), run(tmp_path / "b", "pendulum", 5, 30)
    assert first == second
    assert any(row["critic_loss"] for row in first)  # 25 of the 30 episodes trained
    other = run(tmp_path / "c", "pendulum", 6, 30)
    assert [r["score"] for r in other] != [r["score"] for r in first]


@pytest.mark.parametrize("framework", ["keras", "torch"])
def test_cartpole_same_seed_gives_an_identical_episodes_csv(tmp_path, framework):
    if framework == "torch":
        pytest.importorskip("torch", reason="needs the torch extra")
    args = ("--framework", framework)
    first, second = run(tmp_path / "a", "cartpole", 3, 60, *args), run(tmp_path / "b", "cartpole", 3, 60, *args)
    assert first == second
    assert sum(1 for row in first if row["loss"]) > 40  # trained from the first 128 transitions on
    other = run(tmp_path / "c", "cartpole", 4, 60, *args)
    assert [r["score"] for r in other] != [r["score"] for r in first]
