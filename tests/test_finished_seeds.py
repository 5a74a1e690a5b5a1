"""A seed that finishes before its batch mates: masked in the stack, or the stack shrunk.

``train/loop.PartsAxis`` either keeps a finished seed's slice in the stacked update on rows
of zeros (``mask``) or rebuilds the learner from the running seeds' slices (``shrink``).
The choice is one of speed only (``learners/table.FINISHED_SEEDS``), because a slice's
arithmetic does not depend on how many slices the stack holds: these tests hold both
policies to the same ``episodes.csv`` for every seed, bit for bit, through real shrinks,
and a batch stopped after a shrink to resume from its shrunk stack.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from keras_rl.registry import get_experiment
from keras_rl.runs.files import read_episodes
from keras_rl.train.loop import PartsAxis, run_seeds
from keras_rl.train.settings import TrainSettings

pytestmark = pytest.mark.slow  # whole batches, twice each


def episodes(folder: Path) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in read_episodes(folder / "episodes.csv")]


def configs(experiment: str, seeds, **changes):
    exp = get_experiment(experiment)
    return exp, [exp.config_cls.for_variant("faithful", **changes).replace(seed=s) for s in seeds]


@pytest.fixture
def stacks(monkeypatch):
    """The stack sizes each shrink left (every ``shrink_to`` that rebuilt)."""
    sizes: list[int] = []
    original = PartsAxis.shrink_to

    def recording(self, keep):
        if keep != self.live:
            sizes.append(len(keep))
        original(self, keep)

    monkeypatch.setattr(PartsAxis, "shrink_to", recording)
    return sizes


CASES = [
    # post 003: episodes of different lengths, so 4 seeds end their 50 episodes at different steps
    pytest.param("cartpole", "keras", {"episodes": 50}, id="post003-keras"),
    # post 000 stops each seed at a threshold it reaches at its own episode (seeds 1 and 3 by the
    # 4th); its PyTorch port, since its Keras learner no longer batches (issue 34 retired it)
    pytest.param("pendulum", "torch", {"episodes": 24, "threshold": -1320.0}, id="post000-torch"),
]


@pytest.mark.parametrize("experiment, framework, changes", CASES)
def test_shrinking_the_stack_gives_every_seed_the_bits_masking_gives(tmp_path, stacks, experiment, framework, changes):
    exp, cs = configs(experiment, [1, 2, 3, 4], framework=framework, **changes)
    for policy in ("mask", "shrink"):
        run_seeds(
            exp,
            cs,
            [tmp_path / policy / f"seed_{c.seed}" for c in cs],
            TrainSettings(progress=False, finished_seeds=policy),
        )
    assert stacks == [3, 2], "the seeds did not finish one by one, so nothing was shrunk"
    for c in cs:
        masked, shrunk = (
            episodes(tmp_path / "mask" / f"seed_{c.seed}"),
            episodes(tmp_path / "shrink" / f"seed_{c.seed}"),
        )
        assert len(masked) == len(shrunk) > 0
        assert shrunk == masked, f"seed {c.seed}"


def test_a_batch_stopped_after_a_shrink_resumes_from_its_shrunk_stack(tmp_path, stacks):
    """Post 003, 4 seeds: stopped as soon as the first seed has finished (and left the stack),
    the batch's checkpoints record the 3 seeds still stacked; the resumed batch rebuilds
    that stack and ends as an uninterrupted one, every seed bit for bit."""
    exp, cs = configs("cartpole", [1, 2, 3, 4], episodes=50)
    shrink = TrainSettings(progress=False, finished_seeds="shrink")
    straight = run_seeds(exp, cs, [tmp_path / "straight" / f"seed_{c.seed}" for c in cs], shrink)
    assert stacks == [3, 2]
    first = min(straight, key=lambda s: s.total_steps).seed
    dirs = [tmp_path / "cut" / f"seed_{c.seed}" for c in cs]

    def first_has_finished() -> bool:
        summary = dirs[[c.seed for c in cs].index(first)] / "summary.json"
        return json.loads(summary.read_text())["status"] == "completed"

    cut = run_seeds(exp, cs, dirs, shrink, should_stop=first_has_finished)
    assert sorted(s.status for s in cut) == ["completed", "interrupted", "interrupted", "interrupted"]
    from keras_rl.runs.checkpoint import read_checkpoint

    saved = read_checkpoint(dirs[0])
    assert saved["live"] == [c.seed for c in cs if c.seed != first]
    del stacks[:]
    resumed = run_seeds(exp, cs, dirs, replace(shrink, resume=True))
    assert stacks[0] == 3, "the resumed batch did not rebuild the shrunk stack"
    assert [s.status for s in resumed] == ["completed"] * 4
    for c in cs:
        assert episodes(tmp_path / "cut" / f"seed_{c.seed}") == episodes(tmp_path / "straight" / f"seed_{c.seed}")


def test_reproduce_resume_takes_the_finished_seeds_of_a_stopped_batch_back_into_it(tmp_path, capsys):
    """The same stop, resumed by ``reproduce --resume``: the seeds that had finished before the
    stop rejoin their batch (it was refused as "resume them together" when they were kept as
    completed runs), and every seed ends as in an uninterrupted batch, bit for bit."""
    from keras_rl.cli import main

    exp, cs = configs("cartpole", [1, 2, 3], episodes=30)
    straight = run_seeds(exp, cs, [tmp_path / "straight" / f"seed_{c.seed}" for c in cs], TrainSettings(progress=False))
    first = min(straight, key=lambda s: s.total_steps).seed
    dirs = [tmp_path / "cut" / f"seed_{c.seed}" for c in cs]

    def first_has_finished() -> bool:
        return json.loads((tmp_path / "cut" / f"seed_{first}" / "summary.json").read_text())["status"] == "completed"

    run_seeds(exp, cs, dirs, TrainSettings(progress=False), should_stop=first_has_finished)
    assert (dirs[0] / "checkpoint.pkl").is_file() and (tmp_path / "cut" / f"seed_{first}" / "checkpoint.pkl").is_file()
    args = ["reproduce", "cartpole", "--seeds", "1-3", "--episodes", "30", "--seed-batch", "3"]
    args += ["--out", str(tmp_path / "cut"), "--resume", "--no-progress", "--min-success-rate", "0", "--workers", "1"]
    assert main(args) == 0, capsys.readouterr().err
    for c in cs:
        assert episodes(tmp_path / "cut" / f"seed_{c.seed}") == episodes(tmp_path / "straight" / f"seed_{c.seed}")
        assert json.loads((tmp_path / "cut" / f"seed_{c.seed}" / "summary.json").read_text())["status"] == "completed"
        assert not (tmp_path / "cut" / f"seed_{c.seed}" / "checkpoint.pkl").exists()  # the batch ended
