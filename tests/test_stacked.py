"""Seed-batched learner (issue #11): seed k inside a stack computes what seed k computes alone."""

from __future__ import annotations

import numpy as np
import pytest
from wrappers import NaNRewardAfter, SigintAt

from keras_rl.buffers import Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.ddpg import post000_learner
from keras_rl.learners.stacked import NETWORKS, layer_weights, stack_post000
from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.runs.files import read_episodes
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import seed_everything

SPEC = EnvSpec(3, 1, 2.0)
LAYOUT = Layout(3, 1)
B = 64


def rows_for(seed: int, dones_share: float = 0.05) -> np.ndarray:
    """A plausible Pendulum batch [B, width] of seed ``seed``'s own."""
    rng = np.random.default_rng(1000 + seed)
    theta = rng.uniform(-np.pi, np.pi, B)
    states = np.stack([np.cos(theta), np.sin(theta), rng.uniform(-8, 8, B)], 1)
    next_states = np.stack([np.cos(theta + 0.05), np.sin(theta + 0.05), rng.uniform(-8, 8, B)], 1)
    return LAYOUT.pack(
        (states, rng.uniform(-2, 2, (B, 1)), -rng.uniform(0, 16, B), next_states, rng.uniform(size=B) < dones_share)
    )


def solo(seed: int, variant: str = "faithful"):
    config = PendulumDDPGConfig.for_variant(variant, seed=seed)
    seed_everything(seed)  # as run_seed does before the agent is built
    return post000_learner(config, SPEC)


def stacked(seeds, variant: str = "faithful"):
    return stack_post000([PendulumDDPGConfig.for_variant(variant, seed=s) for s in seeds], SPEC)


def max_gap(a: dict, b: dict) -> float:
    return max(float(np.max(np.abs(x - y))) for name in a for x, y in zip(a[name], b[name]))


def solo_weights(learner) -> dict:
    """A solo learner's networks as (kernel, bias) per layer, like ``slice_weights``."""
    return {name: layer_weights(getattr(learner, name)) for name in NETWORKS}


@pytest.mark.slow
def test_each_slice_starts_from_its_solo_runs_initial_weights_and_seeds_differ():
    stack = stacked(range(4))
    for k in range(4):
        assert max_gap(stack.slice_weights(k), solo_weights(solo(k))) == 0.0
    assert max_gap(stack.slice_weights(0), stack.slice_weights(1)) > 0.1  # not one RNG stream for all


@pytest.mark.parametrize("variant", ["faithful", "fixed"])
@pytest.mark.slow
def test_one_stacked_update_equals_each_seeds_solo_update(variant):
    seeds = list(range(8))
    stack = stacked(seeds, variant)
    rows = np.stack([rows_for(s) for s in seeds])  # [S, B, width]
    losses = stack.train(rows)
    worst = 0.0
    for k, seed in enumerate(seeds):
        alone = solo(seed, variant)
        solo_losses = alone.train(rows[k])
        moved = max_gap(solo_weights(alone), solo_weights(solo(seed, variant)))
        gap = max_gap(stack.slice_weights(k), solo_weights(alone))
        worst = max(worst, gap)
        assert gap <= 1e-6 and gap < 0.05 * moved, (seed, gap, moved)
        for name in ("critic_loss", "actor_loss"):
            assert float(losses[name][k]) == pytest.approx(float(solo_losses[name]), rel=1e-6, abs=1e-6)
    print(f"max |stacked - solo| after one update, 8 seeds, {variant}: {worst:.3g}")


@pytest.mark.slow
def test_a_seeds_result_does_not_depend_on_which_seeds_share_its_batch():
    first, second = stacked(range(0, 8)), stacked(range(3, 11))
    first.train(np.stack([rows_for(s) for s in range(0, 8)]))
    second.train(np.stack([rows_for(s) for s in range(3, 11)]))
    assert max_gap(first.slice_weights(3), second.slice_weights(0)) <= 1e-6


@pytest.mark.slow
def test_acting_gives_each_seed_its_own_action():
    seeds = list(range(4))
    stack = stacked(seeds)
    states = np.random.default_rng(0).normal(size=(4, 3)).astype(np.float32)
    actions = stack.act(states)
    for k, seed in enumerate(seeds):
        np.testing.assert_allclose(actions[k], solo(seed).act(states[k]), atol=1e-6)


@pytest.mark.slow
def test_one_seed_through_the_stacked_learner_is_bit_identical_to_the_solo_learner():
    alone, stack = solo(0), stacked([0])
    rows = rows_for(0)
    for _ in range(3):
        alone_losses, stacked_losses = alone.train(rows), stack.train(rows[None])
        assert float(stacked_losses["critic_loss"][0]) == float(alone_losses["critic_loss"])
    assert max_gap(stack.slice_weights(0), solo_weights(alone)) == 0.0


# -- the seed-batched episode loop ------------------------------------------------------------------
def _csv(path):
    import csv

    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


def _batch(tmp_path, name, seeds, **overrides):
    from keras_rl.registry import get_experiment
    from keras_rl.runs.loop import run_seeds as run_seed_batch

    exp = get_experiment("pendulum")
    configs = [exp.config_cls.for_variant("faithful", seed=s, **overrides) for s in seeds]
    return run_seed_batch(exp, configs, [tmp_path / name / f"seed_{s}" for s in seeds], progress=False)


@pytest.mark.slow
def test_one_seed_through_the_batched_loop_writes_the_solo_runs_episodes_csv(tmp_path):
    import subprocess
    import sys

    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "keras_rl",
            "reproduce",
            "pendulum",
            "--seeds",
            "3",
            "--episodes",
            "12",
            "--no-progress",
            "--out",
            str(tmp_path / "solo"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 1, proc.stderr
    summaries = _batch(tmp_path, "batch", [3], episodes=12)
    assert summaries[0].status == "completed"
    assert _csv(tmp_path / "batch" / "seed_3" / "episodes.csv") == _csv(tmp_path / "solo" / "seed_3" / "episodes.csv")


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
    for name in ("config.json", "summary.json", "actor.weights.h5", "critic.weights.h5"):
        assert (tmp_path / "a" / "seed_0" / name).is_file()
    # each summary names the seeds it was trained with, since its bits depend on them
    assert RunSummary.read(tmp_path / "b" / "seed_3").provenance["seed_batch"] == [3, 4, 5, 6]


@pytest.mark.slow
def test_a_seed_that_reaches_the_threshold_stops_while_the_others_go_on(tmp_path):
    summaries = _batch(tmp_path, "t", [0, 1, 2, 3], episodes=6, threshold=-1450.0)
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
    from keras_rl.runs.loop import run_seeds as run_seed_batch

    exp = get_experiment("pendulum")
    seeds = [0, 1, 2]
    configs = [exp.config_cls.for_variant("faithful", seed=s, episodes=5, train_start=64, batch_size=16) for s in seeds]
    envs = _envs(seeds, wrap=lambda e: NaNRewardAfter(e, after_steps=450))
    summaries = run_seed_batch(exp, configs, [tmp_path / f"seed_{s}" for s in seeds], progress=False, envs=envs)
    by_seed = {s.seed: s for s in summaries}
    assert by_seed[1].status == "non_finite_loss" and "critic_loss became nan" in by_seed[1].message
    assert by_seed[1].episodes_run == 2  # the episode that hit NaN is not recorded
    assert by_seed[0].status == by_seed[2].status == "completed"
    assert by_seed[0].episodes_run == by_seed[2].episodes_run == 5


@pytest.mark.slow
def test_ctrl_c_stops_every_seed_of_a_batch_and_keeps_their_episodes(tmp_path):
    import signal

    from keras_rl.registry import get_experiment
    from keras_rl.runs.loop import run_seeds as run_seed_batch

    exp = get_experiment("pendulum")
    seeds = [0, 1]
    configs = [exp.config_cls.for_variant("faithful", seed=s, episodes=10, train_start=64) for s in seeds]
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        summaries = run_seed_batch(
            exp,
            configs,
            [tmp_path / f"seed_{s}" for s in seeds],
            progress=False,
            envs=_envs(seeds, wrap=lambda e: SigintAt(e, at=450)),
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    for s in summaries:
        assert s.status == "interrupted" and s.episodes_run == 2  # episode 3 was cut short
        assert len(read_episodes(tmp_path / f"seed_{s.seed}" / "episodes.csv")) == 2
        assert (tmp_path / f"seed_{s.seed}" / "actor.weights.h5").is_file()


# -- post 003: the stacked DQN and episodes of any length -----------------------------------------
def _cartpole_spec():
    from keras_rl.registry import get_experiment

    exp = get_experiment("cartpole")
    env = exp.make_env(exp.config_cls())
    try:
        return exp.env_spec(env)
    finally:
        env.close()


def _dqn_solo(seed: int, spec):
    from keras_rl.learners.dqn import post003_learner
    from keras_rl.posts.cartpole import CartPoleDQNConfig

    seed_everything(seed)  # as run_seed does before the agent is built
    return post003_learner(CartPoleDQNConfig(seed=seed), spec)


def _dqn_stack(seeds, spec):
    from keras_rl.learners.stacked import stack_post003
    from keras_rl.posts.cartpole import CartPoleDQNConfig

    return stack_post003([CartPoleDQNConfig(seed=s) for s in seeds], spec)


def _dqn_weights(learner) -> dict:
    from keras_rl.learners.stacked import DQN_NETWORKS

    return {name: layer_weights(getattr(learner, name)) for name in DQN_NETWORKS}


def _cartpole_rows(seed: int) -> np.ndarray:
    """A plausible CartPole batch [128, width] of seed ``seed``'s own (actions 0/1, some terminal)."""
    rng = np.random.default_rng(2000 + seed)
    n = 128
    states = rng.normal(0, [1.0, 1.0, 0.1, 1.0], (n, 4))
    return Layout(4, 1).pack(
        (
            states,
            rng.integers(0, 2, (n, 1)),
            np.ones(n),
            states + rng.normal(0, 0.05, (n, 4)),
            rng.uniform(size=n) < 0.1,
        )
    )


@pytest.mark.slow
def test_dqn_slices_start_from_their_solo_runs_weights_and_seeds_differ():
    spec = _cartpole_spec()
    stack = _dqn_stack(range(3), spec)
    for k in range(3):
        assert max_gap(stack.slice_weights(k), _dqn_weights(_dqn_solo(k, spec))) == 0.0
    assert max_gap(stack.slice_weights(0), stack.slice_weights(1)) > 0.05  # not one RNG stream for all


@pytest.mark.slow
def test_one_stacked_dqn_update_equals_each_seeds_solo_update_and_ignores_its_batch_mates():
    spec = _cartpole_spec()
    seeds = list(range(8))
    stack = _dqn_stack(seeds, spec)
    rows = np.stack([_cartpole_rows(s) for s in seeds])
    states = rows[:, 0, :4]
    for _ in range(3):  # three steps, so that AdamW's moments and amsgrad's max are exercised
        losses, actions = stack.train_and_act(rows, states)
    worst = 0.0
    for k, seed in enumerate(seeds):
        alone = _dqn_solo(seed, spec)
        for _ in range(3):
            solo_losses, solo_action = alone.train_and_act(rows[k], states[k])
        moved = max_gap(_dqn_weights(alone), _dqn_weights(_dqn_solo(seed, spec)))
        gap = max_gap(stack.slice_weights(k), _dqn_weights(alone))
        worst = max(worst, gap)
        assert gap <= 1e-6 and gap < 0.05 * moved, (seed, gap, moved)
        assert float(losses["loss"][k]) == pytest.approx(float(solo_losses["loss"]), rel=1e-6)
        assert actions[k] == solo_action
    print(f"max |stacked - solo| after three DQN updates, 8 seeds: {worst:.3g}")
    other = _dqn_stack(range(3, 11), spec)  # seed 3 in {3..10} as in {0..7}
    for _ in range(3):
        other.train(np.stack([_cartpole_rows(s) for s in range(3, 11)]))
    assert max_gap(other.slice_weights(0), stack.slice_weights(3)) <= 1e-6


def _cartpole_runs(tmp_path, name, seeds, episodes, batch: bool):
    from keras_rl.registry import get_experiment
    from keras_rl.runs.loop import run_seed
    from keras_rl.runs.loop import run_seeds as run_seed_batch

    exp = get_experiment("cartpole")
    configs = [exp.config_cls.for_variant("faithful", seed=s, episodes=episodes) for s in seeds]
    dirs = [tmp_path / name / f"seed_{s}" for s in seeds]
    if batch:
        return run_seed_batch(exp, configs, dirs, progress=False)
    return [run_seed(exp, c, d, progress=False) for c, d in zip(configs, dirs)]


@pytest.mark.slow
def test_cartpole_seeds_batched_play_their_solo_episodes(tmp_path):
    """S=1 writes the solo episodes.csv bit for bit; in a batch of 4 (episodes of different
    lengths, seeds finishing at different env steps) every seed plays the same episodes as
    alone, and its losses agree to 1e-6."""
    seeds, episodes = [0, 1, 2, 3], 20
    _cartpole_runs(tmp_path, "solo", seeds, episodes, batch=False)
    _cartpole_runs(tmp_path, "one", [2], episodes, batch=True)
    assert _csv(tmp_path / "one" / "seed_2" / "episodes.csv") == _csv(tmp_path / "solo" / "seed_2" / "episodes.csv")
    summaries = _cartpole_runs(tmp_path, "four", seeds, episodes, batch=True)
    assert all(s.status == "completed" and s.episodes_run == episodes for s in summaries)
    assert len({s.total_steps for s in summaries}) > 1  # the seeds really finished at different env steps
    for s in seeds:
        batched = _csv(tmp_path / "four" / f"seed_{s}" / "episodes.csv")
        alone = _csv(tmp_path / "solo" / f"seed_{s}" / "episodes.csv")
        assert [(r["steps"], r["score"], r["total_steps"]) for r in batched] == [
            (r["steps"], r["score"], r["total_steps"]) for r in alone
        ]
        for b, a in zip(batched, alone):
            if a["loss"]:
                assert float(b["loss"]) == pytest.approx(float(a["loss"]), rel=1e-6)
        assert (tmp_path / "four" / f"seed_{s}" / "q_network.weights.h5").is_file()
    neighbours = _cartpole_runs(tmp_path, "other", [3, 4, 5, 6], episodes, batch=True)
    assert neighbours[0].status == "completed"
    assert _csv(tmp_path / "other" / "seed_3" / "episodes.csv") == _csv(tmp_path / "four" / "seed_3" / "episodes.csv")


# -- --seed-batch on reproduce, compare and sweep -----------------------------------------------------
def test_only_jobs_that_differ_in_the_seed_share_a_batch(tmp_path):
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.runs.jobs import SeedBatchJob, SeedJob, batched

    def job(seed, framework="keras", gamma=0.99, start="new"):
        config = CartPoleDQNConfig(seed=seed, framework=framework, gamma=gamma)
        return SeedJob.of(config, tmp_path / f"{framework}-{gamma}" / f"seed_{seed}", start=start, command="x")

    jobs = [job(s, gamma=g) for g in (0.99, 0.9) for s in range(3)] + [job(0, "torch"), job(7, start="resume")]
    packed = batched(jobs, 2)
    batches = [[j.config["seed"] for j in b.jobs] for b in packed if isinstance(b, SeedBatchJob)]
    assert batches == [[0, 1], [0, 1]]  # one per grid point; seed 2 of each point alone
    alone = [
        (j.config["framework"], j.config["gamma"], j.config["seed"]) for j in packed if not isinstance(j, SeedBatchJob)
    ]
    assert sorted(alone) == [("keras", 0.9, 2), ("keras", 0.99, 2), ("keras", 0.99, 7), ("torch", 0.99, 0)]
    assert batched(jobs, 1) == jobs


@pytest.mark.parametrize(
    "seeds, workers, cap, size",
    [(30, 2, 10, 8), (30, 2, 16, 15), (10, 1, 10, 10), (10, 2, 10, 5), (11, 1, 10, 6), (1, 2, 10, 1), (40, 2, 10, 10)],
)
def test_auto_batches_are_as_even_as_the_cap_and_the_workers_allow(seeds, workers, cap, size):
    import math

    from keras_rl.runs.jobs import auto_batch_size

    got = auto_batch_size(seeds, workers, cap)
    assert got == size and got <= cap
    jobs = math.ceil(seeds / got)
    assert math.ceil(jobs / workers) == math.ceil(seeds / (workers * cap))  # no more rounds than the cap forces


def test_seed_batch_auto_packs_each_post_by_its_cap(tmp_path):
    from keras_rl.learners.table import SEED_BATCH_CAP, seed_batch_cap
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.runs.jobs import SeedBatchJob, SeedJob, batched

    jobs = [SeedJob.of(CartPoleDQNConfig(seed=s), tmp_path / f"seed_{s}", command="x") for s in range(30)]
    packed = batched(jobs, "auto", workers=2)
    assert [len(b.jobs) for b in packed if isinstance(b, SeedBatchJob)] == [8, 8, 8, 6]
    assert seed_batch_cap("cartpole", "keras") == SEED_BATCH_CAP[("cartpole", "keras")] == 10
    assert seed_batch_cap("cartpole", "torch") == 1  # the tutorial's code: one seed per run
    torch = [SeedJob.of(CartPoleDQNConfig(seed=s, framework="torch"), tmp_path / f"t{s}", command="x") for s in (0, 1)]
    assert batched(torch, "auto", workers=2) == torch


def test_a_config_no_stacked_learner_covers_runs_alone_under_auto_and_is_refused_under_a_fixed_size(tmp_path):
    """Post 001 with its learning phase on has no stacked learner. ``sweep --ablate --seed-batch
    auto`` once sent its seeds to the stacked learner, which refused each batch at run time;
    now ``auto`` runs them alone beside the other grid points' batches, and a fixed size
    refuses them before anything runs."""
    from keras_rl.errors import ConfigError
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig
    from keras_rl.runs.jobs import SeedBatchJob, SeedJob, batched

    def jobs(point, **overrides):
        config = MountainCarDDPGConfig.for_variant("faithful", **overrides)
        return [SeedJob.of(config.replace(seed=s), tmp_path / point / f"seed_{s}", command="x") for s in range(4)]

    phase, base = jobs("learning_phase_training=true", learning_phase_training=True), jobs("base")
    packed = batched(phase + base, "auto")
    assert [j for j in packed if not isinstance(j, SeedBatchJob)] == phase  # each alone
    assert [[m.config["seed"] for m in j.jobs] for j in packed if isinstance(j, SeedBatchJob)] == [[0, 1, 2, 3]]
    with pytest.raises(ConfigError, match="--seed-batch 2 does not cover .*learning_phase_training=true"):
        batched(base + phase, 2)
    assert batched(phase, 1) == phase


@pytest.mark.slow
def test_seed_batch_on_sweep_runs_each_grid_point_as_a_batch_and_refuses_what_it_cannot_do(tmp_path):
    import json
    import subprocess
    import sys

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "keras_rl", *args], capture_output=True, text=True, timeout=600)

    bad = cli(
        "reproduce",
        "cartpole",
        "--framework",
        "torch",
        "--seeds",
        "0-1",
        "--seed-batch",
        "2",
        "--dry-run",
        "--out",
        str(tmp_path / "tutorial"),
    )
    assert bad.returncode == 2 and "--seed-batch has no torch learner for cartpole" in bad.stderr, bad.stderr
    tutorial = cli(  # auto: where nothing batches, each seed runs alone
        "reproduce", "cartpole", "--framework", "torch", "--seeds", "0-1", "--seed-batch", "auto", "--dry-run",
        "--out", str(tmp_path / "tutorial"),
    )  # fmt: skip
    assert tutorial.returncode == 0, tutorial.stderr
    out = tmp_path / "sweep"
    proc = cli(
        "sweep",
        "cartpole",
        "--grid",
        "gamma=0.99,0.9",
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--seed-batch",
        "auto",  # two seeds, one worker: one batch of both per grid point
        "--no-progress",
        "--out",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for point in ("gamma=0.99", "gamma=0.9"):
        for seed in (0, 1):
            summary = json.loads((out / point / f"seed_{seed}" / "summary.json").read_text())
            assert summary["status"] == "completed" and summary["episodes_run"] == 3
            assert summary["provenance"]["seed_batch"] == [0, 1]
    again = cli(
        "sweep",
        "cartpole",
        "--grid",
        "gamma=0.99,0.9",
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--seed-batch",
        "2",
        "--no-progress",
        "--out",
        str(out),
    )
    assert again.returncode == 0 and "4 already done, 0 to run" in again.stderr, again.stderr[-2000:]
