"""The safety net of every refactor: committed run folders reproduce bit for bit.

Each case reruns a committed seed in a fresh process and asserts that the new
``episodes.csv`` equals the committed one in every column except ``wall_seconds`` (the one
column that is not a function of the seed). A run stopped early (``--episodes N``) must
equal the committed file's first N rows: the budget changes when a run ends, never what
an episode computes.

TensorFlow does not promise bit-exactness across CPU models. Runs record the CPU model
in ``summary.json`` (``provenance.cpu_model``); where the committed run's model is known
and differs from this machine's, the test says so and compares the first 5 episodes only.
Runs committed before the model was recorded were all made on this project's machines
(one kind, see the env notes), so they are compared in full.
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from keras_rl.runs.provenance import cpu_model
from keras_rl.runs.replay import plan_replay, seed_rows

pytestmark = pytest.mark.slow  # every test here trains whole runs

RESULTS = Path(__file__).resolve().parent.parent / "results"

CASES = [
    # (committed seed folder, experiment, extra CLI args, episodes to rerun or None for the whole run)
    pytest.param("pendulum/faithful/seed_0", "pendulum", (), None, id="post000-faithful-seed0"),
    pytest.param("mountaincar/faithful/seed_0", "mountaincar", (), None, id="post001-faithful-seed0"),
    pytest.param(
        "pendulum/faithful-torch/seed_0", "pendulum", ("--framework", "torch"), 12, id="post000-torch-seed0-first12"
    ),
    pytest.param("cartpole/faithful/seed_0", "cartpole", (), 60, id="post003-seed0-first60"),
]


def read_rows(path: Path) -> list[dict[str, str]]:
    return seed_rows(path)


@pytest.mark.parametrize("folder, experiment, extra, episodes", CASES)
def test_committed_run_reproduces_bit_for_bit(tmp_path, folder, experiment, extra, episodes):
    committed = RESULTS / folder
    if "--framework" in extra:
        pytest.importorskip("torch", reason="needs the torch extra")
    summary = json.loads((committed / "summary.json").read_text())
    theirs = summary.get("provenance", {}).get("cpu_model")
    if theirs is not None and theirs != cpu_model():
        warnings.warn(
            f"{folder} was made on {theirs!r}, this is {cpu_model()!r}: TensorFlow does not promise "
            "bit-exactness across CPUs, so only the first 5 episodes are compared",
            stacklevel=2,
        )
        episodes = 5
    replay = plan_replay(committed, experiment, episodes)
    out = tmp_path / "run"
    proc = subprocess.run(replay.command(out, *extra), capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stderr
    got = read_rows(out / f"seed_{replay.seed}" / "episodes.csv")
    assert len(got) == len(replay.expected)
    for want, have in zip(replay.expected, got):
        assert have == want, f"{folder}: first difference at episode {want['episode']}"
    assert replay.divergence(out).identical


BATCH_CASES = [
    # (committed set, experiment, the batch of seeds its command made together, episodes to rerun)
    pytest.param("checks/pendulum/baseline", "pendulum", "0-14", 12, id="post000-batch-of-15-first12"),
    pytest.param("checks/cartpole/baseline", "cartpole", "0-14", 60, id="post003-batch-of-15-first60"),
]


@pytest.mark.parametrize("folder, experiment, seeds, episodes", BATCH_CASES)
def test_committed_seed_batch_reproduces_bit_for_bit(tmp_path, folder, experiment, seeds, episodes):
    """A committed seed-batched set (``--seed-batch 15``): each seed's bits depend on its batch
    mates, so the same batch is rerun and every seed compared."""
    committed = RESULTS / folder
    first, last = (int(x) for x in seeds.split("-"))
    summary = json.loads((committed / f"seed_{first}" / "summary.json").read_text())
    assert f"--seeds 0-29 --workers 2 --seed-batch {last - first + 1}" in summary["command"]  # batches 0-14, 15-29
    theirs = summary.get("provenance", {}).get("cpu_model")
    if theirs is not None and theirs != cpu_model():
        warnings.warn(
            f"{folder} was made on {theirs!r}, this is {cpu_model()!r}: only 5 episodes are compared", stacklevel=2
        )
        episodes = 5
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "keras_rl",
            "reproduce",
            experiment,
            "--seeds",
            seeds,
            "--seed-batch",
            str(last - first + 1),
            "--episodes",
            str(episodes),
            "--no-progress",
            "--min-success-rate",
            "0",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    for seed in range(first, last + 1):
        expected = read_rows(committed / f"seed_{seed}" / "episodes.csv")[:episodes]
        got = read_rows(out / f"seed_{seed}" / "episodes.csv")
        assert len(got) == len(expected), f"seed {seed}"
        for want, have in zip(expected, got):
            assert have == want, f"{folder} seed {seed}: first difference at episode {want['episode']}"
