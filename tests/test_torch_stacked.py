"""The PyTorch ports batched (``keras_rl/torch/stacked.py``): seed k inside a stack computes
what seed k's solo PyTorch learner computes, for posts 000 and 001 and every actor update,
and a seed masked out of an update keeps its weights, Adam moments and step count bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from weights import max_gap

pytest.importorskip("torch", reason="needs the torch extra")

from keras_rl.buffers import Layout  # noqa: E402
from keras_rl.envs import EnvSpec  # noqa: E402
from keras_rl.posts.mountaincar import MountainCarDDPGConfig  # noqa: E402
from keras_rl.posts.pendulum import PendulumDDPGConfig  # noqa: E402
from keras_rl.torch import ddpg as solo_learners  # noqa: E402
from keras_rl.torch import stacked  # noqa: E402

B = 32
POSTS = {  # post: (config class, spec, solo builder, stacked builder)
    "000": (PendulumDDPGConfig, EnvSpec(3, 1, 2.0), solo_learners.post000_learner, stacked.stack_post000),
    "001": (MountainCarDDPGConfig, EnvSpec(2, 1, 1.0), solo_learners.post001_learner, stacked.stack_post001),
}
CASES = [
    pytest.param("000", {}, id="post000-faithful"),
    pytest.param("000", {"broadcast_target": False}, id="post000-no-broadcast"),
    pytest.param("001", {}, id="post001-dpg_literal"),
    pytest.param("001", {"actor_gradient": "dpg_intended"}, id="post001-dpg_intended"),
]


def rows_for(post: str, seed: int, salt: int = 0) -> np.ndarray:
    spec = POSTS[post][1]
    rng = np.random.default_rng(3000 + 31 * seed + salt)
    states = rng.uniform(-1, 1, (B, spec.obs_dim))
    return Layout(spec.obs_dim, 1).pack(
        (
            states,
            rng.uniform(-1, 1, (B, 1)),
            rng.normal(size=B),
            states + rng.normal(0, 0.05, states.shape),
            rng.uniform(size=B) < 0.05,
        )
    )


def configs(post: str, seeds, **changes):
    cls = POSTS[post][0]
    return [cls.for_variant("faithful", seed=s).replace(framework="torch", **changes) for s in seeds]


def solo(post: str, seed: int, **changes):
    _, spec, build, _ = POSTS[post]
    return build(configs(post, [seed], **changes)[0], spec)


def stack(post: str, seeds, **changes):
    _, spec, _, build = POSTS[post]
    return build(configs(post, seeds, **changes), spec)


@pytest.mark.parametrize("post", ["000", "001"])
def test_each_slice_starts_from_its_solo_runs_weights_and_seeds_differ(post):
    learner = stack(post, [0, 1, 2])
    for k in range(3):
        assert max_gap(learner.slice_weights(k), solo(post, k).weights()) == 0.0
    assert max_gap(learner.slice_weights(0), learner.slice_weights(1)) > 0.05


@pytest.mark.parametrize("post, changes", CASES)
def test_one_stacked_update_equals_each_seeds_solo_update(post, changes):
    seeds = [0, 1, 2]
    learner = stack(post, seeds, **changes)
    rows = np.stack([rows_for(post, s) for s in seeds])
    losses = learner.train(rows)
    for k, seed in enumerate(seeds):
        alone = solo(post, seed, **changes)
        before = alone.weights()
        solo_losses = alone.train(rows[k])
        moved = max_gap(alone.weights(), before)
        gap = max_gap(learner.slice_weights(k), alone.weights())
        assert gap <= 1e-6 and gap < 0.05 * moved, (seed, gap, moved)
        for name in ("critic_loss", "actor_loss"):
            assert float(losses[name][k]) == pytest.approx(float(solo_losses[name]), rel=1e-5, abs=1e-6)


def test_a_masked_seed_keeps_weights_moments_and_its_own_adam_step_count_bit_for_bit():
    seeds = [0, 1, 2]
    learner = stack("001", seeds)
    before = learner.slice_state(1)["tensors"]
    first, second = (np.stack([rows_for("001", s, salt) for s in seeds]) for salt in (0, 1))
    learner.train(first, mask=np.array([True, False, True]))
    assert all(bool((a == b).all()) for a, b in zip(before, learner.slice_state(1)["tensors"], strict=True))
    learner.train(second)
    assert learner.actor_optimizer.steps.tolist() == [2, 1, 2]
    for k, seed in enumerate(seeds):
        alone = solo("001", seed)
        if k != 1:
            alone.train(first[k])
        alone.train(second[k])
        assert max_gap(learner.slice_weights(k), alone.weights()) <= 1e-6, seed


def test_a_seeds_result_does_not_depend_on_which_seeds_share_its_batch():
    first, second = stack("000", [2, 3]), stack("000", [3, 4, 5])
    first.train(np.stack([rows_for("000", s) for s in (2, 3)]))
    second.train(np.stack([rows_for("000", s) for s in (3, 4, 5)]))
    assert max_gap(first.slice_weights(1), second.slice_weights(0)) <= 1e-6


def test_acting_gives_each_seed_its_own_action():
    learner = stack("000", [0, 1])
    states = np.random.default_rng(0).normal(size=(2, 3)).astype(np.float32)
    actions = learner.act(states)
    for k in range(2):
        np.testing.assert_allclose(actions[k], solo("000", k).act(states[k]), atol=1e-6)


@pytest.mark.slow
def test_a_torch_batch_runs_through_the_loop_and_resumes_to_the_same_files(tmp_path):
    """Post 000's PyTorch port, 2 seeds batched: Ctrl-C after episode 3 leaves checkpoints,
    and resuming gives every seed the episodes an uninterrupted batch gives."""
    import signal

    from wrappers import SigintAt

    from keras_rl.registry import get_experiment
    from keras_rl.runs.files import read_episodes
    from keras_rl.train.loop import run_seeds
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    cs = [c.replace(episodes=6, train_start=200) for c in configs("000", [0, 1])]
    straight = run_seeds(exp, cs, [tmp_path / "straight" / f"seed_{c.seed}" for c in cs], TrainSettings(progress=False))
    assert [s.status for s in straight] == ["completed"] * 2
    dirs = [tmp_path / "cut" / f"seed_{c.seed}" for c in cs]
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        envs = [SigintAt(exp.make_env(c), at=650) for c in cs]
        cut = run_seeds(exp, cs, dirs, TrainSettings(progress=False), envs=envs)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert [s.status for s in cut] == ["interrupted"] * 2 and cut[0].episodes_run == 3
    envs = [SigintAt(exp.make_env(c), at=650) for c in cs]  # their counters come back past 650 from the checkpoint
    resumed = run_seeds(exp, cs, dirs, TrainSettings(progress=False, resume=True), envs=envs)
    assert [s.status for s in resumed] == ["completed"] * 2
    for c in cs:
        got = read_episodes(tmp_path / "cut" / f"seed_{c.seed}" / "episodes.csv")
        want = read_episodes(tmp_path / "straight" / f"seed_{c.seed}" / "episodes.csv")
        assert [{k: v for k, v in r.items() if k != "wall_seconds"} for r in got] == [
            {k: v for k, v in r.items() if k != "wall_seconds"} for r in want
        ]
        assert (tmp_path / "cut" / f"seed_{c.seed}" / "actor.pt").is_file()
