"""Post 001's seed-batched learner: seed k inside a stack computes what seed k computes
alone, for every actor update, and a seed masked out of an update keeps its weights, its
Adam moments and its own Adam step count bit for bit (its bursts differ from its batch
mates', P001-POP)."""

from __future__ import annotations

import numpy as np
import pytest
from weights import max_gap

from keras_rl.buffers import Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.ddpg import post001_learner
from keras_rl.learners.stacked import NETWORKS, model_variables, stack_post001
from keras_rl.posts.mountaincar import MountainCarDDPGConfig
from keras_rl.seeding import seed_everything

SPEC = EnvSpec(
    2,
    1,
    1.0,
    obs_low=np.array([-1.2, -0.07], np.float32),
    obs_high=np.array([0.6, 0.07], np.float32),
    max_episode_steps=999,
)
LAYOUT = Layout(2, 1)
B = 32
ACTOR_UPDATES = [
    pytest.param({}, id="faithful-dpg_literal"),
    pytest.param({"actor_gradient": "dpg_intended"}, id="dpg_intended"),
    pytest.param({"dqda_at_buffer_actions": False}, id="dqda-at-policy-actions"),
]


def rows_for(seed: int, salt: int = 0) -> np.ndarray:
    """A batch [B, width] of post 001's kind: normalised states, standardised returns."""
    rng = np.random.default_rng(2000 + 17 * seed + salt)
    states = rng.uniform(0, 1, (B, 2))
    return LAYOUT.pack(
        (
            states,
            rng.uniform(-1, 1, (B, 1)),
            rng.normal(size=B),
            states + rng.normal(0, 0.01, (B, 2)),
            rng.uniform(size=B) < 0.01,
        )
    )


def config(seed: int, **changes) -> MountainCarDDPGConfig:
    return MountainCarDDPGConfig.for_variant("faithful", seed=seed).replace(**changes)


XLA = False
"""The update's arithmetic is compared here, not the compiler's rounding: plain tf.function
graphs compile in a fraction of XLA's time. The runs through the loop (last test) use XLA,
as every run does."""


def solo(seed: int, **changes):
    seed_everything(seed)  # as the loop does before a solo learner is built
    return post001_learner(config(seed, **changes), SPEC, xla=XLA)


def stacked(seeds, **changes):
    return stack_post001([config(s, **changes) for s in seeds], SPEC, xla=XLA)


def weights(learner) -> dict:
    """A solo learner's networks in ``slice_weights``' form (each model's variables, in order)."""
    return {name: [v.numpy() for v in model_variables(getattr(learner, name))] for name in NETWORKS}


@pytest.mark.slow
def test_each_slice_starts_from_its_solo_runs_weights_batchnorm_included_and_seeds_differ():
    stack = stacked(range(3))
    for k in range(3):
        assert max_gap(stack.slice_weights(k), weights(solo(k))) == 0.0
    assert len(stack.slice_weights(0)["actor"]) == 4 + 2 * 4  # BatchNorm's four, then four Dense layers
    assert max_gap(stack.slice_weights(0), stack.slice_weights(1)) > 0.1  # not one RNG stream for all


@pytest.mark.parametrize("changes", ACTOR_UPDATES)
@pytest.mark.slow
def test_one_stacked_update_equals_each_seeds_solo_update(changes):
    seeds = [0, 1, 2]
    stack = stacked(seeds, **changes)
    rows = np.stack([rows_for(s) for s in seeds])
    losses = stack.train(rows)
    for k, seed in enumerate(seeds):
        alone = solo(seed, **changes)
        before = weights(alone)
        solo_losses = alone.train(rows[k])
        moved = max_gap(weights(alone), before)
        gap = max_gap(stack.slice_weights(k), weights(alone))
        assert gap <= 1e-6 and gap < 0.05 * moved, (seed, gap, moved)
        for name in ("critic_loss", "actor_loss"):
            assert float(losses[name][k]) == pytest.approx(float(solo_losses[name]), rel=1e-5, abs=1e-6)


@pytest.mark.slow
def test_a_masked_seed_keeps_weights_moments_and_its_own_adam_step_count_bit_for_bit():
    seeds = [0, 1, 2]
    stack = stacked(seeds)
    before = [stack.slice_state(k) for k in range(3)]
    first, second = (np.stack([rows_for(s, salt) for s in seeds]) for salt in (0, 1))
    stack.train(first, mask=np.array([True, False, True]))
    for k in (1,):  # masked: every variable of its slice, the step count among them, as it was
        after = stack.slice_state(k)["variables"]
        assert all(np.array_equal(a, b) for a, b in zip(before[k]["variables"], after, strict=True))
    stack.train(second)  # everyone trains: seed 1 takes its first Adam step, 0 and 2 their second
    assert stack.actor_optimizer.steps.numpy().tolist() == [2, 1, 2]
    for k, seed in enumerate(seeds):
        alone = solo(seed)
        if k in (0, 2):
            alone.train(first[k])
        alone.train(second[k])
        assert max_gap(stack.slice_weights(k), weights(alone)) <= 1e-6, seed


@pytest.mark.slow
def test_a_seeds_result_does_not_depend_on_which_seeds_share_its_batch():
    first, second = stacked([2, 3]), stacked([3, 4, 5])
    first.train(np.stack([rows_for(s) for s in (2, 3)]))
    second.train(np.stack([rows_for(s) for s in (3, 4, 5)]))
    assert max_gap(first.slice_weights(1), second.slice_weights(0)) <= 1e-6


@pytest.mark.slow
def test_acting_gives_each_seed_its_own_action():
    stack = stacked([0, 1, 2])
    states = np.random.default_rng(0).uniform(0, 1, (3, 2)).astype(np.float32)
    actions = stack.act(states)
    for k in range(3):
        np.testing.assert_allclose(actions[k], solo(k).act(states[k]), atol=1e-6)


def test_the_learning_phase_on_does_not_batch():
    from keras_rl.errors import ConfigError

    with pytest.raises(ConfigError, match="learning_phase_training"):
        stacked([0, 1], learning_phase_training=True)


@pytest.mark.slow
def test_post001_seeds_batched_burst_by_burst_play_their_solo_episodes(tmp_path):
    """Three seeds through the one loop with their bursts masked per seed; each seed's
    episodes match its solo run's (to the rounding of stacked matmuls: 1e-7 per update)."""
    from keras_rl.registry import get_experiment
    from keras_rl.runs.files import read_episodes
    from keras_rl.train.loop import run_seed, run_seeds
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("mountaincar")
    seeds = [0, 1, 2]
    configs = [config(s, episodes=3) for s in seeds]
    batch = run_seeds(exp, configs, [tmp_path / "batch" / f"seed_{s}" for s in seeds], TrainSettings(progress=False))
    assert [s.status for s in batch] == ["completed"] * 3
    for c in configs:
        alone = run_seed(exp, c, tmp_path / "solo" / f"seed_{c.seed}", TrainSettings(progress=False))
        got = read_episodes(tmp_path / "batch" / f"seed_{c.seed}" / "episodes.csv")
        want = read_episodes(tmp_path / "solo" / f"seed_{c.seed}" / "episodes.csv")
        assert alone.episodes_run == len(got) == len(want) == 3
        for g, w in zip(got, want):
            assert g["steps"] == w["steps"]
            assert g["score"] == pytest.approx(w["score"], abs=1e-3)
            if w["actor_loss"] is not None:  # the bursts (episode 2 on) trained
                assert g["actor_loss"] == pytest.approx(w["actor_loss"], rel=1e-3, abs=1e-4)
