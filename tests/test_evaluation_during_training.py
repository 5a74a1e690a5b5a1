"""``reproduce --eval-every N --eval-episodes K`` (issue #23, item 14): greedy evaluations during
training on an env of their own, in ``evaluations.csv``, TensorBoard and ``best/``; the training
run is the same, bit for bit, with them as without."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

CLI = [sys.executable, "-m", "keras_rl", "reproduce"]


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


CASES = [  # experiment, extra options, seeds, episodes
    ("pendulum", ["--set", "train_start=200"], "3", 6),  # solo, trains from episode 2
    # a seed batch: each seed evaluated through its slice (post 000's PyTorch port, which still batches)
    ("pendulum", ["--framework", "torch", "--seed-batch", "2", "--set", "train_start=200"], "3-4", 6),
    ("cartpole", ["--framework", "torch"], "3", 14),  # the tutorial's own agent
]


@pytest.mark.slow
@pytest.mark.parametrize(
    "experiment, extra, seeds, episodes", CASES, ids=["pendulum", "pendulum-torch-batch", "cartpole-torch"]
)
def test_evaluations_leave_the_training_run_as_it_is(tmp_path, experiment, extra, seeds, episodes):
    if "torch" in extra:
        pytest.importorskip("torch", reason="needs the torch extra")
    common = [*CLI, experiment, "--seeds", seeds, "--episodes", str(episodes), "--no-progress", *extra]
    plain = subprocess.run([*common, "--out", str(tmp_path / "plain")], capture_output=True, text=True, timeout=600)
    assert plain.returncode in (0, 1), plain.stderr
    evaluated = subprocess.run(
        [
            *common,
            "--out",
            str(tmp_path / "evaluated"),
            "--eval-every",
            "2",
            "--eval-episodes",
            "2",
            "--tensorboard",
            str(tmp_path / "tb"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert evaluated.returncode in (0, 1), evaluated.stderr
    first, _, last = seeds.partition("-")
    for seed in range(int(first), int(last or first) + 1):
        mine, theirs = tmp_path / "evaluated" / f"seed_{seed}", tmp_path / "plain" / f"seed_{seed}"
        assert rows(mine / "episodes.csv") == rows(theirs / "episodes.csv")
        assert not (theirs / "evaluations.csv").exists()
        evals = rows(mine / "evaluations.csv")
        assert [int(r["episode"]) for r in evals] == list(range(2, episodes + 1, 2))
        means = [float(r["mean"]) for r in evals]
        best = json.loads((mine / "best" / "best.json").read_text())
        assert best["mean"] == max(means) and best["episode"] == int(evals[means.index(max(means))]["episode"])
        assert len(best["scores"]) == 2
        if experiment == "pendulum":  # it trains from episode 2: each evaluation sees another policy
            assert len(set(means)) == len(means)
        assert [int(r["best"]) for r in evals][0] == 1
        assert any(p.suffix in (".h5", ".pt") for p in (mine / "best").iterdir())
        assert not [p for p in mine.iterdir() if p.name.startswith(".tmp-")]
    events = list((tmp_path / "tb").rglob("events.out.tfevents.*"))
    assert events and all(b"eval_mean" in e.read_bytes() for e in events)


@pytest.mark.slow
def test_bad_evaluation_options_exit_2_before_anything_runs(tmp_path):
    for extra, message in (
        (["--eval-every", "-1"], "--eval-every must be zero"),
        (["--eval-every", "2", "--eval-episodes", "0"], "--eval-episodes must be at least 1"),
        (["--eval-every", "2", "--set", "learning_phase_training=true"], "does not cover learning_phase_training"),
    ):
        experiment = "mountaincar" if "learning_phase_training=true" in extra else "pendulum"
        proc = subprocess.run(
            [
                *CLI,
                experiment,
                "--seeds",
                "0",
                "--episodes",
                "2",
                "--no-progress",
                "--out",
                str(tmp_path / "x"),
                *extra,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 2 and message in proc.stderr, (extra, proc.stderr)
        assert not (tmp_path / "x").exists()


def test_a_resumed_run_keeps_the_evaluations_its_checkpoint_holds(tmp_path):
    """Evaluations after the checkpoint are played again on resume, so they leave the file, and
    ``best/`` goes with them if it was one of them."""
    from keras_rl.registry import get_experiment
    from keras_rl.runs.evaluate import BEST, EVALUATIONS, EvalSchedule, TrainingEvaluator

    experiment = get_experiment("pendulum")
    config = experiment.config_cls.for_variant("faithful", seed=5)
    evaluator = TrainingEvaluator(experiment, config, tmp_path, EvalSchedule(2, 1))
    assert evaluator.seed == 10_005
    for episode, mean in ((2, -900.0), (4, -700.0), (6, -500.0)):
        evaluator.evaluate(episode, lambda obs: [0.0], lambda folder: (folder / "actor.weights.h5").write_text("w"))
        evaluator.rows[-1].update(mean=mean)  # stand-ins for three policies of rising quality
        evaluator._write_rows()
    (tmp_path / BEST / "best.json").write_text(json.dumps({"episode": 6, "mean": -500.0}))
    again = TrainingEvaluator(experiment, config, tmp_path, EvalSchedule(2, 1))
    again.resume(4)
    assert [r["episode"] for r in again.rows] == [2, 4] and [r["best"] for r in again.rows] == [1, 1]
    assert [int(r["episode"]) for r in rows(tmp_path / EVALUATIONS)] == [2, 4]
    assert not (tmp_path / BEST).exists() and again.best_mean == -700.0
    evaluator.close()
    again.close()
