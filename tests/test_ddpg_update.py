"""Parity: our compiled update against the post's target built by hand and its eager code."""

import numpy as np
import pytest

from keras_rl.buffers import Batch
from keras_rl.envs import EnvSpec
from keras_rl.learners.networks import Critic, build
from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.registry import agent_for
from keras_rl.seeding import seed_everything
from maintainers.reference.post000_eager import PostActor, PostAgent

B = 4


def make_agent(variant="faithful", xla=True, seed=0):
    seed_everything(seed)
    config = PendulumDDPGConfig.for_variant(variant, batch_size=B, seed=seed)
    return agent_for(config, EnvSpec(3, 1, 2.0), xla=xla)


def train_batch(agent, batch):
    """One update on a given batch; the losses as floats."""
    rows = agent.learner.layout.pack(Batch(*batch))
    return {k: float(v) for k, v in agent.learner.train(rows).items()}


def make_batch(rng, dones):
    theta = rng.uniform(-np.pi, np.pi, size=B)
    states = np.stack([np.cos(theta), np.sin(theta), rng.uniform(-8, 8, B)], 1).astype(np.float32)
    next_states = np.stack([np.cos(theta + 0.1), np.sin(theta + 0.1), rng.uniform(-8, 8, B)], 1).astype(np.float32)
    actions = rng.uniform(-2, 2, size=(B, 1)).astype(np.float32)
    rewards = -rng.uniform(0, 16, size=B)
    return states, actions, rewards, next_states, np.asarray(dones, dtype=bool)


def mlp(x, weights, out_act):
    """Numpy forward pass of Dense-relu-Dense-relu-Dense(out_act)."""
    w1, b1, w2, b2, w3, b3 = weights
    h = np.maximum(x @ w1 + b1, 0)
    h = np.maximum(h @ w2 + b2, 0)
    return out_act(h @ w3 + b3)


def post_mirror(agent, broadcast):
    """The post's eager Agent holding copies of our agent's current weights."""
    nets = {}
    for name, model in [("actor", agent.learner.actor), ("target_actor", agent.learner.target_actor)]:
        nets[name] = build(PostActor(1, 2.0), 3)
        nets[name].set_weights(model.get_weights())
    for name, model in [("critic", agent.learner.critic), ("target_critic", agent.learner.target_critic)]:
        nets[name] = build(Critic(), 3, 1)
        nets[name].set_weights(model.get_weights())
    return PostAgent(
        nets["actor"], nets["critic"], nets["target_actor"], nets["target_critic"], batch_size=B, broadcast=broadcast
    )


def post_minibatch(states, actions, rewards, next_states, dones):
    # the post's memory holds (state (1,3), action (1,), reward (1,), next_state (1,3), done)
    return [
        (states[i : i + 1], actions[i], np.array([rewards[i]]), next_states[i : i + 1], bool(dones[i]))
        for i in range(B)
    ]


def hand_target(agent, rewards, next_states, dones, broadcast):
    next_a = mlp(next_states, agent.learner.target_actor.get_weights(), np.tanh) * 2.0  # [B,1]
    next_q = mlp(
        np.concatenate([next_states, next_a], 1), agent.learner.target_critic.get_weights(), lambda z: z
    )  # [B,1]
    r = rewards.reshape(-1, 1)
    if broadcast:
        return r + 0.99 * next_q * (1 - dones.astype(float))[None, :]  # [B,B]: T[i,j] uses d_j
    return r + 0.99 * next_q * (1 - dones.astype(float))[:, None]  # [B,1]


@pytest.mark.parametrize("variant,broadcast", [("faithful", True), ("fixed", False)])
@pytest.mark.slow  # compiles the learner (with XLA too)
def test_target_and_loss_match_the_hand_built_target(variant, broadcast):
    agent = make_agent(variant)
    states, actions, rewards, next_states, dones = make_batch(np.random.default_rng(1), [0, 1, 0, 0])
    expected = hand_target(agent, rewards, next_states, dones, broadcast)
    assert expected.shape == ((B, B) if broadcast else (B, 1))
    got = agent.learner.td_targets(rewards.astype(np.float32), next_states, dones.astype(np.float32)).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5)

    q = mlp(np.concatenate([states, actions], 1), agent.learner.critic.get_weights(), lambda z: z)  # [B,1]
    expected_loss = np.mean((q - expected) ** 2)  # over B*B entries when broadcasting
    losses = train_batch(agent, (states, actions, rewards, next_states, dones))
    assert losses["critic_loss"] == pytest.approx(expected_loss, rel=1e-5)


@pytest.mark.slow  # compiles the learner (with XLA too)
def test_broadcast_mixes_every_done_into_every_row():
    agent = make_agent("faithful")
    _, _, rewards, next_states, dones = make_batch(np.random.default_rng(2), [0, 1, 0, 0])
    t = agent.learner.td_targets(rewards.astype(np.float32), next_states, dones.astype(np.float32)).numpy()
    # column 1 (the done sample) loses the bootstrap for *every* row; other columns keep it
    np.testing.assert_allclose(t[:, 1], rewards, rtol=1e-6)
    assert not np.allclose(t[:, 0], rewards)
    # with no done in the batch the broadcast target is B identical columns = the fixed target
    zero = np.zeros(B, np.float32)
    t0 = agent.learner.td_targets(rewards.astype(np.float32), next_states, zero).numpy()
    np.testing.assert_allclose(t0, np.repeat(t0[:, :1], B, axis=1))


@pytest.mark.parametrize("variant,broadcast", [("faithful", True), ("fixed", False)])
@pytest.mark.slow  # compiles the learner (with XLA too)
@pytest.mark.parametrize("xla", [True, False])
def test_one_update_matches_the_posts_eager_code(variant, broadcast, xla):
    agent = make_agent(variant, xla=xla)
    post = post_mirror(agent, broadcast)
    batch = make_batch(np.random.default_rng(3), [0, 0, 1, 0])
    ours = train_batch(agent, batch)
    theirs = post.train_model(post_minibatch(*batch))
    assert theirs["targets"].shape == ((B, B) if broadcast else (B, 1))
    assert ours["critic_loss"] == pytest.approx(theirs["critic_loss"], rel=1e-5)
    assert ours["actor_loss"] == pytest.approx(theirs["actor_loss"], rel=1e-5, abs=1e-6)
    pairs = [
        (agent.learner.actor, post.actor),
        (agent.learner.critic, post.critic),
        (agent.learner.target_actor, post.target_actor),
        (agent.learner.target_critic, post.target_critic),
    ]
    for mine, reference in pairs:
        for a, b in zip(mine.get_weights(), reference.get_weights(), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-5)


@pytest.mark.slow
def test_faithful_and_fixed_updates_differ_only_when_a_done_is_sampled():
    batch_done = make_batch(np.random.default_rng(4), [0, 1, 0, 0])
    batch_none = make_batch(np.random.default_rng(4), [0, 0, 0, 0])
    results = {}
    for variant in ("faithful", "fixed"):
        for name, batch in (("done", batch_done), ("none", batch_none)):
            agent = make_agent(variant)
            # same initial targets in both variants, so only the target formula differs
            agent.learner.target_actor.set_weights(agent.learner.actor.get_weights())
            agent.learner.target_critic.set_weights(agent.learner.critic.get_weights())
            results[variant, name] = train_batch(agent, batch)["critic_loss"]
    assert results["faithful", "none"] == pytest.approx(results["fixed", "none"], rel=1e-6)
    assert results["faithful", "done"] != pytest.approx(results["fixed", "done"], rel=1e-3)
