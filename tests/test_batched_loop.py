"""The seed-batched episode loop (keras_rl/train/loop.py over a seed axis): each seed writes its
solo run's episodes.csv and stops on its own threshold, NaN or Ctrl-C. The cases batch post
000's PyTorch port: posts 000 and 003's Keras learners no longer batch (issue 34 retired them
for the compiled engine), and the loop is the same for every stacked learner. Post 001's
batch, whose seeds train in bursts of their own sizes, is ``tests/test_stacked_post001.py``'s.
A solo run is this loop with one seed (``run_seed``): that it plays the same episodes in
another process is tests/test_resume.py's life of a seed, and that they are the committed
ones is tests/test_committed_runs_replay.py's."""

from __future__ import annotations

import pytest
from wrappers import NaNRewardAfter, SigintAt

from keras_rl.runs.files import read_episodes
from keras_rl.runs.summary import RunSummary


def _csv(path):
    import csv

    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


def _batch(tmp_path, name, seeds, **overrides):
    from keras_rl.registry import get_experiment
    from keras_rl.train.loop import run_seeds as run_seed_batch
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    configs = [exp.config_cls.for_variant("faithful", seed=s, framework="torch", **overrides) for s in seeds]
    return run_seed_batch(exp, configs, [tmp_path / name / f"seed_{s}" for s in seeds], TrainSettings(progress=False))


@pytest.mark.slow
def test_batched_seeds_are_independent_of_their_neighbours_and_of_each_other(tmp_path):
    first = _batch(tmp_path, "a", [0, 1, 2, 3], episodes=7)
    second = _batch(tmp_path, "b", [3, 4, 5, 6], episodes=7)
    assert all(s.status == "completed" for s in first + second)
    seed3_a, seed3_b = (
        _csv(tmp_path / "a" / "seed_3" / "episodes.csv"),
        _csv(tmp_path / "b" / "seed_3" / "episodes.csv"),
    )
    assert seed3_a == seed3_b  # the same seed in another batch of the same size: the same run
    scores = {s: [r["score"] for r in _csv(tmp_path / "a" / f"seed_{s}" / "episodes.csv")] for s in range(4)}
    assert len({tuple(v) for v in scores.values()}) == 4  # every seed its own env, noise and weights
    for name in ("config.json", "summary.json", "actor.pt", "critic.pt"):
        assert (tmp_path / "a" / "seed_0" / name).is_file()
    # each summary names the seeds it was trained with, since its bits depend on them
    assert RunSummary.read(tmp_path / "b" / "seed_3").provenance["seed_batch"] == [3, 4, 5, 6]


@pytest.mark.slow
def test_a_seed_that_reaches_the_threshold_stops_while_the_others_go_on(tmp_path):
    summaries = _batch(tmp_path, "t", [0, 1, 2, 3], episodes=6, threshold=-1320.0)  # seeds 1, 3 reach it
    by_seed = {s.seed: s for s in summaries}
    stopped = [s for s in summaries if s.reached_at_episode is not None and s.reached_at_episode < 6]
    assert stopped and len(stopped) < 4, {s.seed: s.reached_at_episode for s in summaries}
    for s in stopped:
        rows = _csv(tmp_path / "t" / f"seed_{s.seed}" / "episodes.csv")
        assert len(rows) == s.reached_at_episode == s.episodes_run and s.success and s.status == "completed"
    assert max(s.episodes_run for s in by_seed.values()) == 6 or all(s.reached_at_episode for s in summaries)
    longest = max(summaries, key=lambda s: s.episodes_run)
    for s in stopped:  # its summary was final when it stopped: its wall time ends there
        assert s.wall_seconds < longest.wall_seconds
        assert RunSummary.read(tmp_path / "t" / f"seed_{s.seed}").wall_seconds == s.wall_seconds


def _envs(seeds, wrap=None):
    from keras_rl.registry import get_experiment

    exp = get_experiment("pendulum")
    envs = [exp.make_env(exp.config_cls()) for _ in seeds]
    return [wrap(e) if wrap is not None and i == 1 else e for i, e in enumerate(envs)]


@pytest.mark.slow
def test_a_nan_in_one_seed_stops_that_seed_only(tmp_path):
    from keras_rl.registry import get_experiment
    from keras_rl.train.loop import run_seeds as run_seed_batch
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    seeds = [0, 1, 2]
    configs = [
        exp.config_cls.for_variant("faithful", seed=s, framework="torch", episodes=5, train_start=64, batch_size=16)
        for s in seeds
    ]
    envs = _envs(seeds, wrap=lambda e: NaNRewardAfter(e, after_steps=450))
    summaries = run_seed_batch(
        exp, configs, [tmp_path / f"seed_{s}" for s in seeds], TrainSettings(progress=False), envs=envs
    )
    by_seed = {s.seed: s for s in summaries}
    assert by_seed[1].status == "non_finite_loss" and "critic_loss became nan" in by_seed[1].message
    assert by_seed[1].episodes_run == 2  # the episode that hit NaN is not recorded
    assert by_seed[0].status == by_seed[2].status == "completed"
    assert by_seed[0].episodes_run == by_seed[2].episodes_run == 5


@pytest.mark.slow
def test_ctrl_c_stops_every_seed_of_a_batch_and_keeps_their_episodes(tmp_path):
    import signal

    from keras_rl.registry import get_experiment
    from keras_rl.train.loop import run_seeds as run_seed_batch
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    seeds = [0, 1]
    configs = [
        exp.config_cls.for_variant("faithful", seed=s, framework="torch", episodes=10, train_start=64) for s in seeds
    ]
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        summaries = run_seed_batch(
            exp,
            configs,
            [tmp_path / f"seed_{s}" for s in seeds],
            TrainSettings(progress=False),
            envs=_envs(seeds, wrap=lambda e: SigintAt(e, at=450)),
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    for s in summaries:
        assert s.status == "interrupted" and s.episodes_run == 2  # episode 3 was cut short
        assert len(read_episodes(tmp_path / f"seed_{s.seed}" / "episodes.csv")) == 2
        assert (tmp_path / f"seed_{s.seed}" / "actor.pt").is_file()
