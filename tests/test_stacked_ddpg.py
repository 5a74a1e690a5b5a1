"""Post 000's stacked DDPG learner (keras_rl/learners/stacked.py): S seeds in one set of
tensors, each slice bit for bit its solo learner, independent of its batch mates."""

from __future__ import annotations

import numpy as np
import pytest
from weights import max_gap

from keras_rl.buffers import Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.ddpg import post000_learner
from keras_rl.learners.stacked import NETWORKS, layer_weights, stack_post000
from keras_rl.posts.pendulum import PendulumDDPGConfig
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
