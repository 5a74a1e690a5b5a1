"""Same seed, identical curve: two separate processes, 30 episodes of post 000."""

import csv
import subprocess
import sys


def run(out, seed):
    proc = subprocess.run([sys.executable, "-m", "keras_rl", "reproduce", "pendulum", "--seeds", str(seed),
                           "--episodes", "30", "--no-progress", "--set", "stop_at_threshold=false",
                           "--out", str(out)], capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stderr
    with open(out / f"seed_{seed}" / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 30
    # wall_seconds is the one column that is not a function of the seed
    return [{k: v for k, v in row.items() if k != "wall_seconds"} for row in rows]


def test_same_seed_gives_an_identical_episodes_csv(tmp_path):
    first, second = run(tmp_path / "a", 5), run(tmp_path / "b", 5)
    assert first == second
    assert any(row["critic_loss"] for row in first)  # 25 of the 30 episodes trained
    other = run(tmp_path / "c", 6)
    assert [r["score"] for r in other] != [r["score"] for r in first]
