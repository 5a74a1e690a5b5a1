"""Seed-batched learners: S seeds' networks stacked on a leading seed axis, one compiled step.

Each layer holds a kernel ``[S, in, out]`` and a bias ``[S, out]`` and is applied with a
batched matmul (``einsum("sbi,sio->sbo")``), so seed k's slice sees only seed k's data.
The loss is the *sum* over seeds of each seed's own loss: the gradient of seed k's slice is
then exactly its solo gradient, and Adam, torch's AdamW, clip-by-value and the soft update
are elementwise, so each slice steps as its solo run would. The optimizer's step counter is
shared, which is exact because every seed of a batch trains on the same env steps (the
seed-batched loop checks it: post 000's episodes are all 200 steps, and post 003's seeds
reset on their own but train on every env step once their buffers hold one batch). Nothing
global (a norm, a mean across seeds) enters the step.

Seed k's slice starts from the very weights seed k's solo run draws: ``stack_post000`` and
``stack_post003`` seed Keras as a solo run does, build the solo networks, and stack them.
A stack of one seed is the solo learner itself (``SoloAsStack``).

The seed-batched episode loop is ``runs/batched.py``; the equivalence tests are
``tests/test_stacked.py``.
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
from keras_rl.learners.dqn import DQNLearner, post003_networks, post003_optimizer
from keras_rl.seeding import seed_everything


NETWORKS = ("actor", "critic", "target_actor", "target_critic")
"""Post 000's networks, as ``slice_weights`` names them."""
DQN_NETWORKS = ("q_network", "target_network")
"""Post 003's networks."""


def layers_of(model) -> list:
    """A network's Dense (or StackedDense) layers in order: post 000's ``hidden`` + ``out``,
    post 003's ``dense``."""
    return list(model.dense) if hasattr(model, "dense") else [*model.hidden, model.out]


def layer_weights(model) -> list[np.ndarray]:
    """(kernel, bias) of each layer of a network, solo or stacked, in layer order."""
    return [v.numpy() for layer in layers_of(model) for v in (layer.kernel, layer.bias)]


def _check_equal_but_seed(configs: Sequence) -> None:
    first = {k: v for k, v in configs[0].to_dict().items() if k != "seed"}
    if any({k: v for k, v in c.to_dict().items() if k != "seed"} != first for c in configs):
        raise ValueError("seed-batched configs must be equal but for the seed")


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

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, after_episode_end: bool = False):
        """One update of every seed, then each seed's action for ``states``. After an
        episode end the solo run trains, then acts on the new episode's first state in a
        call of its own; so does this (XLA may round a fused call differently)."""
        if after_episode_end:
            return self.train(rows), self.act(states)
        losses, actions = self._train_and_act(tf.constant(rows), tf.constant(states, tf.float32))
        return losses, actions.numpy()

    def act_without_update(self, states: np.ndarray, after_episode_end: bool = False) -> np.ndarray:
        """Before the warm-up ends post 000 only acts."""
        return self.act(states)

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
        # [S, B, obs], [S, B, act], [S, B], [S, B, obs], [S, B]
        states, actions, rewards, next_states, dones = self.layout.split(rows)
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


class StackedQNetwork(keras.Model):
    """Post 003 In [16]'s ``DQN`` for S seeds: Linear 128, relu, Linear 128, relu, Linear n_actions."""

    def __init__(self, solos: Sequence[keras.Model]):
        super().__init__()
        s, n = len(solos), len(solos[0].dense)
        self.dense = [StackedDense(s, d.kernel.shape[0], d.units, "relu" if i < n - 1 else None)
                      for i, d in enumerate(solos[0].dense)]
        for i, layer in enumerate(self.dense):
            layer.set_from([m.dense[i] for m in solos])

    def call(self, state):  # [S, B, obs] -> [S, B, n_actions]
        x = state
        for layer in self.dense:
            x = layer(x)
        return x


class StackedDQNLearner(DQNLearner):
    """Post 003's ``optimize_model`` (Huber, clip-by-value 100, torch's AdamW with amsgrad)
    and its every-step soft update, for S seeds in one call: ``DQNLearner``'s own update on
    [S, B, ...] batches, its gradient taken of the sum of the seeds' losses."""

    def __init__(self, q_network, target_network, optimizer, gamma: float, tau: float, grad_clip_value: float,
                 layout: Layout, seeds: int, xla: bool = True):
        self.seeds = seeds
        self.solo_networks: list[keras.Model] = []  # seed k's solo policy net, for saving
        super().__init__(q_network, target_network, optimizer, gamma, tau, grad_clip_value, layout, xla=xla)

    def input_specs(self) -> tuple[tf.TensorSpec, tf.TensorSpec]:
        return (tf.TensorSpec([self.seeds, None, self.layout.width], tf.float32),
                tf.TensorSpec([self.seeds, self.layout.obs_dim], tf.float32))

    def total_loss(self, loss: tf.Tensor) -> tf.Tensor:
        return tf.reduce_sum(loss)  # each slice gets its solo gradient

    def act(self, states: np.ndarray) -> np.ndarray:
        """Each seed's greedy action ``[S]`` for its state ``[S, obs]``."""
        return self._act(tf.constant(states, tf.float32)).numpy()

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, after_episode_end: bool = False):
        """The update, then the greedy actions for ``states`` (a seed whose episode just
        ended passes its next episode's first state): one call either way, since the
        solo run's separate ``act`` reads the same updated weights."""
        losses, actions = self._train_and_act(tf.constant(rows), tf.constant(states, tf.float32))
        return losses, actions.numpy()

    def act_without_update(self, states: np.ndarray, after_episode_end: bool = False) -> np.ndarray:
        """Before the first batch the tutorial's soft update still runs every step."""
        return self._sync_and_act(tf.constant(states, tf.float32)).numpy()

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        return {name: [w[k] for w in layer_weights(getattr(self, name))] for name in DQN_NETWORKS}

    def save_slice(self, k: int, run_dir) -> None:
        """Seed k's policy net as a solo run saves it (``q_network.weights.h5``)."""
        network = self.solo_networks[k]
        network.set_weights(self.slice_weights(k)["q_network"])
        save_weights(network, Path(run_dir) / "q_network.weights.h5")

    def _greedy(self, states):
        return tf.argmax(self.q_network(states[:, None, :])[:, 0], axis=-1, output_type=tf.int32)  # [S]


class SoloAsStack:
    """A stack of one seed is the solo learner itself, behind the stacked interface: XLA
    rounds a one-row batched matmul differently from Dense's matmul (about 1e-7, measured),
    so S=1 through the stacked layers would not be bit-identical to the solo run; this is,
    call for call (after an episode end: the update, then a separate act, as the solo
    agent does)."""

    def __init__(self, learner, networks: Sequence[str]):
        self.learner, self.networks = learner, tuple(networks)
        self.loss_names = tuple(learner.loss_names)

    @staticmethod
    def _one(losses) -> dict[str, np.ndarray]:
        return {k: np.asarray(v)[None] for k, v in losses.items()}

    def train(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        return self._one(self.learner.train(rows[0]))

    def act(self, states: np.ndarray) -> np.ndarray:
        return np.asarray(self.learner.act(states[0]))[None]

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, after_episode_end: bool = False):
        if after_episode_end:
            return self.train(rows), self.act(states)
        losses, action = self.learner.train_and_act(rows[0], states[0])
        return self._one(losses), np.asarray(action)[None]

    def act_without_update(self, states: np.ndarray, after_episode_end: bool = False) -> np.ndarray:
        action = self.learner.act_without_update(states[0], want_action=not after_episode_end)
        return self.act(states) if after_episode_end else np.asarray(action)[None]

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        return {name: layer_weights(getattr(self.learner, name)) for name in self.networks}

    def save_slice(self, k: int, run_dir) -> None:
        self.learner.save(run_dir)


def _per_seed(configs: Sequence, build) -> list:
    """``build(config)`` for each seed, Keras seeded first as that seed's solo run seeds it."""
    _check_equal_but_seed(configs)
    built = []
    for config in configs:
        seed_everything(config.seed)
        built.append(build(config))
    return built


def stack_post000(configs: Sequence, spec: EnvSpec, xla: bool = True):
    """Post 000's learner for the seeds of ``configs`` (one config per seed, equal but for the
    seed): each slice starts from the weights its solo run draws (``seed_everything(seed)``,
    then the solo builder)."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.ddpg import post000_learner

        seed_everything(c.seed)
        return SoloAsStack(post000_learner(c, spec, xla=xla), NETWORKS)
    solos = _per_seed(configs, lambda config: post000_networks(config, spec))
    obs_dim, act_dim = spec.obs_dim, spec.action_dim
    nets = [StackedActor([s[0] for s in solos], obs_dim), StackedCritic([s[1] for s in solos], obs_dim + act_dim),
            StackedActor([s[2] for s in solos], obs_dim), StackedCritic([s[3] for s in solos], obs_dim + act_dim)]
    learner = StackedDDPGLearner(*nets, c.actor_lr, c.critic_lr, c.gamma, c.tau, c.broadcast_target,
                                 Layout(obs_dim, act_dim), seeds=len(configs), xla=xla)
    learner.solo_policies = [(s[0], s[1]) for s in solos]
    return learner


def stack_post003(configs: Sequence, spec: EnvSpec, xla: bool = True):
    """Post 003's learner for the seeds of ``configs``, each slice from its solo run's weights."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.dqn import post003_learner

        seed_everything(c.seed)
        return SoloAsStack(post003_learner(c, spec, xla=xla), DQN_NETWORKS)
    solos = _per_seed(configs, lambda config: post003_networks(config, spec))
    learner = StackedDQNLearner(StackedQNetwork([q for q, _ in solos]), StackedQNetwork([t for _, t in solos]),
                                post003_optimizer(c), c.gamma, c.tau, c.grad_clip_value, Layout(spec.obs_dim, 1),
                                seeds=len(configs), xla=xla)
    learner.solo_networks = [q for q, _ in solos]
    return learner
