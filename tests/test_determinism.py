"""Same seed, identical curve: two separate processes per case."""

import csv
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow  # every test here trains whole runs


def run(out, experiment, seed, episodes, *extra):
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "keras_rl",
            "reproduce",
            experiment,
            "--seeds",
            str(seed),
            "--episodes",
            str(episodes),
            "--no-progress",
            "--set",
            "stop_at_threshold=false",
            "--out",
            str(out),
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode in (0, 1), proc.stderr
    with open(out / f"seed_{seed}" / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == episodes
    # wall_seconds is the one column that is not a function of the seed
    return [{k: v for k, v in row.items() if k != "wall_seconds"} for row in rows]


CASES = [  # experiment, framework, seed, episodes, loss column, least episodes with training
    ("pendulum", "keras", 5, 12, "critic_loss", 7),
    ("pendulum", "torch", 5, 12, "critic_loss", 7),
    ("cartpole", "keras", 3, 60, "loss", 41),
    ("cartpole", "torch", 3, 60, "loss", 41),
    ("mountaincar", "keras", 3, 4, "critic_loss", 2),  # bursts after episodes 2 and up
    ("mountaincar", "torch", 3, 4, "critic_loss", 2),
]


@pytest.mark.parametrize(
    "experiment, framework, seed, episodes, loss, trained", CASES, ids=[f"{c[0]}-{c[1]}" for c in CASES]
)
def test_same_seed_gives_an_identical_episodes_csv(tmp_path, experiment, framework, seed, episodes, loss, trained):
    if framework == "torch":
        pytest.importorskip("torch", reason="needs the torch extra")
    args = ("--framework", framework)
    first = run(tmp_path / "a", experiment, seed, episodes, *args)
    assert first == run(tmp_path / "b", experiment, seed, episodes, *args)
    assert sum(1 for row in first if row[loss]) >= trained  # the runs trained, so the update is covered
    # another seed parts from the first at once: a quarter of the episodes shows it
    shown = max(1, episodes // 4)
    other = run(tmp_path / "c", experiment, seed + 1, shown, *args)
    assert [r["score"] for r in other] != [r["score"] for r in first[:shown]]
