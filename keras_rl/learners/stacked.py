"""Seed-batched learners: S seeds' networks stacked on a leading seed axis, one compiled step.

Each layer holds a kernel ``[S, in, out]`` and a bias ``[S, out]`` and is applied with a
batched matmul (``einsum("sbi,sio->sbo")``), so seed k's slice sees only seed k's data.
The loss is the *sum* over seeds of each seed's own loss: the gradient of seed k's slice is
then exactly its solo gradient, and Adam and the soft update are elementwise, so each slice
steps as its solo run would (the step counter is shared, which is exact while the seeds
train in lockstep, as post 000's fixed 200-step episodes make them). Nothing global (a norm,
a mean across seeds) enters the step.

Seed k's slice starts from the very weights seed k's solo run draws: ``stack_post000`` seeds
Keras as a solo run does, builds the solo networks, and stacks them.

This module has the learner and its equivalence tests (``tests/test_stacked.py``); the
seed-batched episode loop and ``--seed-batch`` are not built yet (issue #11).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import keras
import numpy as np
import tensorflow as tf

from keras_rl.buffers import Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.common import compile_step, save_weights, soft_update
from keras_rl.learners.ddpg import post000_networks
from keras_rl.seeding import seed_everything


NETWORKS = ("actor", "critic", "target_actor", "target_critic")


def layer_weights(model) -> list[np.ndarray]:
    """(kernel, bias) of each layer of a post-000 network, solo or stacked, in layer order."""
    return [v.numpy() for layer in [*model.hidden, model.out] for v in (layer.kernel, layer.bias)]


class StackedDense(keras.layers.Layer):
    """``Dense`` for S seeds at once: ``[S, B, in] -> [S, B, out]``."""

    def __init__(self, seeds: int, units_in: int, units: int, activation: str | None = None):
        super().__init__()
        self.kernel = self.add_weight(shape=(seeds, units_in, units), initializer="zeros", name="kernel")
        self.bias = self.add_weight(shape=(seeds, units), initializer="zeros", name="bias")
        self.activation = keras.activations.get(activation)

    def call(self, x: tf.Tensor) -> tf.Tensor:
        return self.activation(tf.einsum("sbi,sio->sbo", x, self.kernel) + self.bias[:, None, :])

    def set_from(self, denses: Sequence[keras.layers.Dense]) -> None:
        """Seed k's slice := the k-th solo layer's weights."""
        self.kernel.assign(np.stack([d.kernel.numpy() for d in denses]))
        self.bias.assign(np.stack([d.bias.numpy() for d in denses]))


class StackedActor(keras.Model):
    """Post 000 §2.2's actor for S seeds: Dense 64 relu x2, Dense(act, tanh), times the bound."""

    def __init__(self, solos: Sequence[keras.Model], obs_dim: int):
        super().__init__()
        s, widths = len(solos), [obs_dim, *(d.units for d in solos[0].hidden), solos[0].out.units]
        self.action_bound = solos[0].action_bound
        self.hidden = [StackedDense(s, a, b, "relu") for a, b in zip(widths[:-2], widths[1:-1])]
        self.out = StackedDense(s, widths[-2], widths[-1], "tanh")
        for i, layer in enumerate(self.hidden):
            layer.set_from([m.hidden[i] for m in solos])
        self.out.set_from([m.out for m in solos])

    def call(self, state):  # [S, B, obs] -> [S, B, act]
        x = state
        for layer in self.hidden:
            x = layer(x)
        return self.out(x) * self.action_bound


class StackedCritic(keras.Model):
    """Post 000 §2.2's critic for S seeds: concat(state, action), Dense 64 relu x2, Dense 1."""

    def __init__(self, solos: Sequence[keras.Model], in_dim: int):
        super().__init__()
        s, widths = len(solos), [in_dim, *(d.units for d in solos[0].hidden), 1]
        self.hidden = [StackedDense(s, a, b, "relu") for a, b in zip(widths[:-2], widths[1:-1])]
        self.out = StackedDense(s, widths[-2], 1)
        for i, layer in enumerate(self.hidden):
            layer.set_from([m.hidden[i] for m in solos])
        self.out.set_from([m.out for m in solos])

    def call(self, state, action):  # -> [S, B, 1]
        x = tf.concat([state, action], axis=-1)
        for layer in self.hidden:
            x = layer(x)
        return self.out(x)


class StackedDDPGLearner:
    """Post 000's update (critic tape, actor tape, soft updates) for S seeds in one call."""

    loss_names = ("critic_loss", "actor_loss")

    def __init__(self, actor, critic, target_actor, target_critic, actor_lr: float, critic_lr: float, gamma: float,
                 tau: float, broadcast_target: bool, layout: Layout, seeds: int, xla: bool = True):
        self.actor, self.critic, self.target_actor, self.target_critic = actor, critic, target_actor, target_critic
        self.solo_policies: list[tuple[keras.Model, keras.Model]] = []  # (actor, critic) per seed, for saving
        self.actor_optimizer = keras.optimizers.Adam(learning_rate=actor_lr)
        self.critic_optimizer = keras.optimizers.Adam(learning_rate=critic_lr)
        self.actor_optimizer.build(actor.trainable_variables)
        self.critic_optimizer.build(critic.trainable_variables)
        self.gamma, self.tau, self.broadcast_target, self.layout = float(gamma), float(tau), bool(broadcast_target), layout
        rows = tf.TensorSpec([seeds, None, layout.width], tf.float32)  # [S, B, width]
        obs = tf.TensorSpec([seeds, layout.obs_dim], tf.float32)  # [S, obs]
        self._train = compile_step(self._train_rows, xla, rows)
        self._act = compile_step(self._act_all, xla, obs)
        self._train_and_act = compile_step(lambda r, s: (self._train_rows(r), self._act_all(s)), xla, rows, obs)

    def train(self, rows: np.ndarray) -> dict[str, tf.Tensor]:
        """One update of every seed on its own rows ``[S, B, width]``; losses ``[S]``."""
        return self._train(tf.constant(rows))

    def act(self, states: np.ndarray) -> np.ndarray:
        """Each seed's action for its state: ``[S, obs] -> [S, act]``."""
        return self._act(tf.constant(states, tf.float32)).numpy()

    def train_and_act(self, rows: np.ndarray, states: np.ndarray):
        losses, actions = self._train_and_act(tf.constant(rows), tf.constant(states, tf.float32))
        return losses, actions.numpy()

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        """Seed k's weights: (kernel, bias) per layer of each network, as a solo model holds them."""
        return {name: [w[k] for w in layer_weights(getattr(self, name))] for name in NETWORKS}

    def save_slice(self, k: int, run_dir) -> None:
        """Seed k's actor and critic as a solo run saves them (``actor.weights.h5``, ``critic.weights.h5``)."""
        weights = self.slice_weights(k)
        actor, critic = self.solo_policies[k]
        actor.set_weights(weights["actor"])
        critic.set_weights(weights["critic"])
        save_weights(actor, Path(run_dir) / "actor.weights.h5")
        save_weights(critic, Path(run_dir) / "critic.weights.h5")

    def _train_rows(self, rows):
        o, a = self.layout.obs_dim, self.layout.action_dim
        states, actions = rows[:, :, :o], rows[:, :, o:o + a]  # [S, B, obs], [S, B, act]
        rewards, next_states, dones = rows[:, :, o + a], rows[:, :, o + a + 1:2 * o + a + 1], rows[:, :, 2 * o + a + 1]
        next_q = self.target_critic(next_states, self.target_actor(next_states))  # [S, B, 1]
        if self.broadcast_target:  # P000-BROADCAST per seed: [S, B, B]
            targets = rewards[:, :, None] + self.gamma * next_q * (1.0 - dones[:, None, :])
        else:
            targets = rewards[:, :, None] + self.gamma * next_q * (1.0 - dones[:, :, None])  # [S, B, 1]
        with tf.GradientTape() as tape:
            q = self.critic(states, actions)  # [S, B, 1]
            critic_losses = tf.reduce_mean(tf.square(q - targets), axis=[1, 2])  # [S]: each seed's own loss
            critic_loss = tf.reduce_sum(critic_losses)  # the sum: each slice gets its solo gradient
        grads = tape.gradient(critic_loss, self.critic.trainable_variables)
        self.critic_optimizer.apply_gradients(zip(grads, self.critic.trainable_variables))
        with tf.GradientTape() as tape:
            actor_losses = -tf.reduce_mean(self.critic(states, self.actor(states)), axis=[1, 2])  # [S]
            actor_loss = tf.reduce_sum(actor_losses)
        grads = tape.gradient(actor_loss, self.actor.trainable_variables)
        self.actor_optimizer.apply_gradients(zip(grads, self.actor.trainable_variables))
        soft_update(self.target_actor.variables, self.actor.variables, self.tau)
        soft_update(self.target_critic.variables, self.critic.variables, self.tau)
        return {"critic_loss": critic_losses, "actor_loss": actor_losses}

    def _act_all(self, states):
        return self.actor(states[:, None, :])[:, 0]  # [S, act]


class SoloAsStack:
    """A stack of one seed is the solo learner itself, behind the stacked interface: XLA
    rounds a one-row batched matmul differently from Dense's matmul (about 1e-7, measured),
    so S=1 through the stacked layers would not be bit-identical to the solo run; this is."""

    loss_names = ("critic_loss", "actor_loss")

    def __init__(self, learner):
        self.learner = learner

    def train(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        return {k: np.asarray(v)[None] for k, v in self.learner.train(rows[0]).items()}

    def act(self, states: np.ndarray) -> np.ndarray:
        return self.learner.act(states[0])[None]

    def train_and_act(self, rows: np.ndarray, states: np.ndarray):
        losses, action = self.learner.train_and_act(rows[0], states[0])
        return {k: np.asarray(v)[None] for k, v in losses.items()}, action[None]

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        return {name: layer_weights(getattr(self.learner, name)) for name in NETWORKS}

    def save_slice(self, k: int, run_dir) -> None:
        self.learner.save(run_dir)


def stack_post000(configs: Sequence, spec: EnvSpec, xla: bool = True):
    """Post 000's learner for the seeds of ``configs`` (one config per seed, equal but for the
    seed): each slice starts from the weights its solo run draws (``seed_everything(seed)``,
    then the solo builder)."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.ddpg import post000_learner

        seed_everything(c.seed)
        return SoloAsStack(post000_learner(c, spec, xla=xla))
    if any({k: v for k, v in x.to_dict().items() if k != "seed"} != {k: v for k, v in c.to_dict().items()
                                                                     if k != "seed"} for x in configs):
        raise ValueError("seed-batched configs must be equal but for the seed")
    solos = []
    for config in configs:
        seed_everything(config.seed)
        solos.append(post000_networks(config, spec))
    obs_dim, act_dim = spec.obs_dim, spec.action_dim
    nets = [StackedActor([s[0] for s in solos], obs_dim), StackedCritic([s[1] for s in solos], obs_dim + act_dim),
            StackedActor([s[2] for s in solos], obs_dim), StackedCritic([s[3] for s in solos], obs_dim + act_dim)]
    learner = StackedDDPGLearner(*nets, c.actor_lr, c.critic_lr, c.gamma, c.tau, c.broadcast_target,
                                 Layout(obs_dim, act_dim), seeds=len(configs), xla=xla)
    learner.solo_policies = [(s[0], s[1]) for s in solos]
    return learner
