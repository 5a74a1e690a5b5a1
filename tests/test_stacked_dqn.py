"""Post 003's stacked DQN learner: each slice starts from its solo run's weights, and one stacked
update equals each seed's solo update whatever its batch mates do."""

from __future__ import annotations

import numpy as np
import pytest
from weights import max_gap

from keras_rl.buffers import Layout
from keras_rl.learners.stacked import layer_weights
from keras_rl.seeding import seed_everything


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
