"""Post 001 (MountainCarContinuous, Keras 2 graph code): each settled behaviour and switch."""

import random
from collections import deque, namedtuple

import keras
import numpy as np
import pytest
import tensorflow as tf

from keras_rl.buffers import Layout, PoppingBuffer
from keras_rl.envs import EnvSpec
from keras_rl.learners.ddpg import DDPGLearner
from keras_rl.learners.networks import MountainCarActor, build
from keras_rl.posts.mountaincar import MountainCarDDPGConfig, standardised_discounted_returns
from keras_rl.registry import agent_for
from keras_rl.seeding import seed_everything

LOW, HIGH = np.array([-1.2, -0.07], np.float32), np.array([0.6, 0.07], np.float32)
SPEC = EnvSpec(2, 1, 1.0, obs_low=LOW, obs_high=HIGH, max_episode_steps=999)


def make_agent(variant="faithful", **overrides):
    seed_everything(0)
    return agent_for(MountainCarDDPGConfig.for_variant(variant, **overrides), SPEC)


# -- P001-PHASE: the learning phase is never fed --------------------------------------------
def test_P001_PHASE_learning_phase_0_noise_off_and_bn_on_initial_moving_stats():
    seed_everything(0)
    actor = build(MountainCarActor(training=False), 2)
    s = np.random.default_rng(0).random((16, 2)).astype(np.float32)
    np.testing.assert_array_equal(actor(s).numpy(), actor(s).numpy())  # GaussianNoise(1.0) inactive
    bn = actor.norm
    np.testing.assert_array_equal(bn.moving_mean.numpy(), [0, 0])
    np.testing.assert_array_equal(bn.moving_variance.numpy(), [1, 1])
    # BN is then the affine map gamma * x / sqrt(1 + eps) + beta (Keras 2 and 3: eps = 1e-3)
    np.testing.assert_allclose(bn(s, training=False).numpy(), s / np.sqrt(1 + 1e-3), rtol=1e-6)
    noisy = build(MountainCarActor(training=True), 2)
    assert not np.array_equal(noisy(s).numpy(), noisy(s).numpy())


@pytest.mark.slow
def test_P001_PHASE_updates_train_gamma_beta_but_never_move_the_moving_stats():
    agent = make_agent()
    rng = np.random.default_rng(1)
    rows = agent.buffer.layout.pack(
        (rng.random((32, 2)), rng.uniform(-1, 1, (32, 1)), rng.normal(size=32), rng.normal(size=(32, 2)), np.zeros(32))
    )
    actor_bn, critic_bn = agent.learner.actor.norm, agent.learner.critic.norm
    before = [v.numpy().copy() for v in (actor_bn.gamma, critic_bn.gamma, critic_bn.beta)]
    for _ in range(5):
        agent.learner.train(rows)
    for bn in (actor_bn, critic_bn):
        np.testing.assert_array_equal(bn.moving_mean.numpy(), [0, 0])
        np.testing.assert_array_equal(bn.moving_variance.numpy(), [1, 1])
    after = [v.numpy() for v in (actor_bn.gamma, critic_bn.gamma, critic_bn.beta)]
    assert all(not np.array_equal(a, b) for a, b in zip(before, after))


# -- P001-POP: the popping sampler ------------------------------------------------------------
class PostReplayBuffer:
    """The post's ReplayBuffer, verbatim but for an explicit random.Random."""

    def __init__(self, rng, maxlen=20000, batch_size=32):
        self.memory = deque()
        self.batch_size = batch_size
        self.experience = namedtuple("Experience", field_names=["state", "action", "reward", "next_state", "done"])
        self.rng = rng

    def add(self, state, action, reward, next_state, done):
        self.memory.append(self.experience(state, action, reward, next_state, done))

    def sample(self):
        self.rng.shuffle(self.memory)
        return [self.memory.popleft() for x in range(self.batch_size)]

    def __len__(self):
        return len(self.memory)


def test_P001_POP_consumes_exactly_as_the_posts_buffer():
    layout = Layout(2, 1)
    ours, post = PoppingBuffer(3000, layout, random.Random(7)), PostReplayBuffer(random.Random(7))
    rng = np.random.default_rng(0)
    n_batches = 0
    for episode_length in (999, 999, 640, 999, 999):
        rows = rng.normal(size=(episode_length, layout.width)).astype(np.float32)
        rows[:, 0] = np.arange(episode_length) + 10_000 * n_batches  # identity tag
        ours.add_rows(rows)
        for r in rows:
            post.add(r[:2], r[2:3], r[3], r[4:6], r[6])
        if len(post) > 1000:  # the post's trigger, then Agent.train's loop
            while len(post) > 100:
                mine, theirs = ours.sample_rows(32), post.sample()
                np.testing.assert_array_equal(mine[:, 0], [e.state[0] for e in theirs])
                np.testing.assert_array_equal(mine[:, 3], [e.reward for e in theirs])
                n_batches += 1
        assert len(ours) == len(post)
    assert n_batches > 100
    assert len(ours) <= 100  # ended on a burst


@pytest.mark.slow
def test_P001_TRIGGER_trains_in_bursts_down_to_100_after_episode_end():
    agent = make_agent()
    obs = np.array([-0.5, 0.0], np.float32)
    updates_at_episode_end = []
    for _episode in range(3):
        agent.begin_episode(obs)
        for t in range(999):
            assert agent.updates == (updates_at_episode_end[-1] if updates_at_episode_end else 0)
            agent.step(-0.01, obs, terminated=False, truncated=(t == 998))
        updates_at_episode_end.append(agent.updates)
    # episode 1: 999 stored (not > 1000): no training; episode 2: 1998 -> pops to 78 (60 batches);
    # episode 3: 78 + 999 = 1077 -> pops to 85 (31 batches)
    assert updates_at_episode_end == [0, 60, 91]
    assert len(agent.buffer) == 85


# -- P001-RETURNS / NEXTSTATE / DONE ------------------------------------------------------------
def test_discounted_return_normalisation_against_a_hand_computed_example():
    # returns with discount 0.5 of [1, 0, 2]: [1 + 0.5*1, 0 + 0.5*2, 2] = [1.5, 1, 2]
    out = standardised_discounted_returns([1.0, 0.0, 2.0], 0.5)
    expected = (np.array([1.5, 1.0, 2.0]) - 1.5) / np.sqrt(((0**2) + 0.5**2 + 0.5**2) / 3)
    np.testing.assert_allclose(out, expected, rtol=1e-6)
    np.testing.assert_allclose(out, [0.0, -1.2247449, 1.2247449], rtol=1e-6)


@pytest.mark.parametrize("variant", ["faithful", "fixed"])
def test_P001_RETURNS_NEXTSTATE_DONE_what_reaches_the_buffer(variant):
    agent = make_agent(variant, train_start=10_000)
    frames = [np.array([-0.5 + 0.01 * t, 0.001 * t], np.float32) for t in range(6)]
    agent.begin_episode(frames[0])
    rewards = [-0.1, -0.2, -0.3, -0.4, -0.5]
    for t in range(5):
        agent.step(rewards[t], frames[t + 1], terminated=False, truncated=(t == 4))
        if variant == "faithful" and t < 4:
            assert len(agent.buffer) == 0  # stored only at episode end
    rows = agent.buffer.data[agent.buffer.order] if variant == "faithful" else agent.buffer.ordered()
    batch = agent.buffer.layout.split(np.asarray(rows) if variant == "faithful" else agent.buffer.layout.pack(rows))
    np.testing.assert_allclose(batch.states, [agent.transitions.observe(f) for f in frames[:5]], rtol=1e-6)
    if variant == "faithful":
        np.testing.assert_allclose(batch.next_states, frames[1:], rtol=1e-6)  # raw frames
        np.testing.assert_allclose(batch.rewards, standardised_discounted_returns(rewards, 0.999), rtol=1e-5)
        np.testing.assert_array_equal(batch.dones, [0, 0, 0, 0, 1])  # the time limit is done
    else:
        np.testing.assert_allclose(batch.next_states, [agent.transitions.observe(f) for f in frames[1:]], rtol=1e-6)
        np.testing.assert_allclose(batch.rewards, rewards, rtol=1e-6)
        np.testing.assert_array_equal(batch.dones, [0, 0, 0, 0, 0])  # truncation bootstraps


@pytest.mark.slow
def test_P001_NOEXPLORE_faithful_acts_deterministically_fixed_adds_ou_noise():
    obs = np.array([-0.5, 0.0], np.float32)
    faithful, fixed = make_agent("faithful"), make_agent("fixed")
    assert len({float(faithful.begin_episode(obs)[0]) for _ in range(5)}) == 1
    actions = [float(fixed.step(0.0, obs, False, False)[0]) for _ in range(50) if fixed.begin_episode(obs) is not None]
    assert len(set(actions)) > 40


# -- P001-ACTORGRAD and P001-DQDA: a hand-computed two-parameter example ------------------------
class TinyActor(keras.Model):
    """mu(s) = tanh(w * s + b): two parameters."""

    def __init__(self):
        super().__init__()
        self.dense = keras.layers.Dense(1, activation="tanh")

    def call(self, s):
        return self.dense(s)


class LinearCritic(keras.Model):
    """Q(s, a) = a * (s + 1) * k: dQ/da = k (s + 1), independent of a."""

    def __init__(self, k):
        super().__init__()
        self.k = k
        self.dummy = keras.layers.Dense(1, use_bias=False)  # gives the critic a variable to train

    def call(self, s, a):
        return a * (s + 1.0) * self.k + 0.0 * self.dummy(s)


def tiny_learner(mode, w=0.7, b=-0.2, k=1.5, at_buffer=True):
    actor, critic = build(TinyActor(), 1), build(LinearCritic(k), 1, 1)
    actor.set_weights([np.array([[w]], np.float32), np.array([b], np.float32)])
    targets = build(TinyActor(), 1), build(LinearCritic(k), 1, 1)
    return DDPGLearner(
        actor,
        critic,
        targets[0],
        targets[1],
        keras.optimizers.Adam(1e-3),
        keras.optimizers.Adam(1e-3),
        gamma=0.99,
        tau=0.001,
        broadcast_target=False,
        layout=Layout(1, 1),
        xla=False,
        actor_gradient=mode,
        dqda_at_buffer_actions=at_buffer,
    )


S = np.array([[0.2], [-0.5], [1.0]], np.float32)
A = np.array([[0.3], [-0.9], [0.1]], np.float32)


def test_P001_ACTORGRAD_intended_is_the_first_order_dpg():
    w, b, k = 0.7, -0.2, 1.5
    grads, _ = tiny_learner("dpg_intended").actor_gradients(tf.constant(S), tf.constant(A))
    s = S[:, 0]
    mu = np.tanh(w * s + b)
    q = k * (s + 1)  # dQ/da
    # tf.gradients(mu, theta, -dQ/da) = -sum_i q_i * dmu_i/dtheta
    np.testing.assert_allclose(grads[0].numpy()[0, 0], -np.sum(q * (1 - mu**2) * s), rtol=1e-5)
    np.testing.assert_allclose(grads[1].numpy()[0], -np.sum(q * (1 - mu**2)), rtol=1e-5)


def test_P001_ACTORGRAD_literal_differentiates_the_sum_of_the_first_order_gradients():
    w, b, k = 0.7, -0.2, 1.5
    grads, _ = tiny_learner("dpg_literal").actor_gradients(tf.constant(S), tf.constant(A))
    s = S[:, 0]
    mu = np.tanh(w * s + b)
    q = k * (s + 1)
    # F(w, b) = g_w + g_b = -sum_i q_i (1 - mu_i^2)(s_i + 1); d(1 - mu^2)/dz = -2 mu (1 - mu^2)
    inner = 2 * q * mu * (1 - mu**2) * (s + 1)
    np.testing.assert_allclose(grads[0].numpy()[0, 0], np.sum(inner * s), rtol=1e-5)
    np.testing.assert_allclose(grads[1].numpy()[0], np.sum(inner), rtol=1e-5)
    intended, _ = tiny_learner("dpg_intended").actor_gradients(tf.constant(S), tf.constant(A))
    assert not np.allclose(grads[1].numpy(), intended[1].numpy())


def test_P001_DQDA_at_buffer_actions_or_at_the_policy():
    class QuadraticCritic(LinearCritic):
        def call(self, s, a):  # dQ/da = -2 a: depends on where it is evaluated
            return -a * a + 0.0 * self.dummy(s)

    def learner(at_buffer):
        lr = tiny_learner("dpg_intended", at_buffer=at_buffer)
        lr.critic = build(QuadraticCritic(1.0), 1, 1)
        return lr

    g_buffer, _ = learner(True).actor_gradients(tf.constant(S), tf.constant(A))
    g_policy, _ = learner(False).actor_gradients(tf.constant(S), tf.constant(A))
    mu = np.tanh(0.7 * S[:, 0] - 0.2)
    np.testing.assert_allclose(g_buffer[1].numpy()[0], -np.sum(-2 * A[:, 0] * (1 - mu**2)), rtol=1e-5)
    np.testing.assert_allclose(g_policy[1].numpy()[0], -np.sum(-2 * mu * (1 - mu**2)), rtol=1e-5)


def test_fixed_keeps_only_the_learning_phase():
    """FIDELITY says `fixed` turns every quirk off but P001-PHASE: the code must agree."""
    from pathlib import Path

    faithful, fixed = MountainCarDDPGConfig.for_variant("faithful"), MountainCarDDPGConfig.for_variant("fixed")
    quirks = {
        "learning_phase_training",
        "actor_gradient",
        "dqda_at_buffer_actions",
        "store_raw_next_state",
        "episode_returns_as_rewards",
        "done_includes_truncation",
        "popping_buffer",
        "exploration",
    }
    kept = {q for q in quirks if getattr(fixed, q) == getattr(faithful, q)}
    assert kept == {"learning_phase_training"}
    ledger = (Path(__file__).resolve().parents[1] / "reproductions" / "FIDELITY.md").read_text()
    assert "every quirk off but one" in ledger and "The one it keeps is P001-PHASE" in ledger
    results = (Path(__file__).resolve().parents[1] / "results" / "README.md").read_text()
    assert "all quirks off" not in results and "every quirk off but the learning phase" in results
