"""DQN as the PyTorch tutorial (post 003) runs it, in Keras with one compiled step per env step."""

from __future__ import annotations

import math
from pathlib import Path

import keras
import numpy as np
import tensorflow as tf

from keras_rl.buffers import Batch, Layout, ReplayBuffer
from keras_rl.configs import CartPoleDQNConfig
from keras_rl.ddpg import compile_step
from keras_rl.metrics import accumulate_losses
from keras_rl.networks import QNetwork, build
from keras_rl.optimizers import TorchAdamW
from keras_rl.results import load_weights, save_weights
from keras_rl.targets import soft_update


def epsilon(config: CartPoleDQNConfig, steps_done: int) -> float:
    """In [31]: ``EPS_END + (EPS_START - EPS_END) * exp(-1. * steps_done / EPS_DECAY)``.

    ``steps_done`` counts env steps over the whole run (it is incremented on every
    ``select_action``), so epsilon decays per step, not per episode.
    """
    return config.eps_end + (config.eps_start - config.eps_end) * math.exp(-1.0 * steps_done / config.eps_decay)


def huber(x: tf.Tensor) -> tf.Tensor:
    """``nn.SmoothL1Loss()`` (beta=1, mean) = Huber with delta 1, averaged."""
    abs_x = tf.abs(x)
    quadratic = tf.minimum(abs_x, 1.0)
    return tf.reduce_mean(0.5 * tf.square(quadratic) + (abs_x - quadratic))


class DQNLearner:
    """The policy and target networks and the compiled ``optimize_model`` + soft update."""

    def __init__(self, q_network: keras.Model, target_network: keras.Model, optimizer: keras.optimizers.Optimizer,
                 gamma: float, tau: float, grad_clip_value: float, layout: Layout, xla: bool = True):
        self.q_network, self.target_network, self.optimizer = q_network, target_network, optimizer
        self.gamma, self.tau, self.grad_clip_value = float(gamma), float(tau), float(grad_clip_value)
        self.layout = layout
        optimizer.build(q_network.trainable_variables)
        rows = tf.TensorSpec([None, layout.width], tf.float32)
        obs = tf.TensorSpec([layout.obs_dim], tf.float32)
        self._train = compile_step(self._train_rows, xla, rows)
        self._act = compile_step(self._greedy, xla, obs)
        self._train_and_act = compile_step(lambda r, s: (self._train_rows(r), self._greedy(s)), xla, rows, obs)
        self._sync_and_act = compile_step(lambda s: (self._soft_update(), self._greedy(s))[1], xla, obs)

    # -- host-side entry points ----------------------------------------------------------
    def train(self, rows: np.ndarray) -> dict[str, tf.Tensor]:
        """``optimize_model()`` then the soft update, on packed rows [B, width]."""
        return self._train(tf.constant(rows))

    def greedy(self, state: np.ndarray) -> int:
        """``policy_net(state).max(1)[1]``: the argmax action for one state."""
        return int(self._act(tf.constant(state, tf.float32)))

    def train_and_act(self, rows: np.ndarray, state: np.ndarray) -> tuple[dict[str, tf.Tensor], int]:
        losses, action = self._train_and_act(tf.constant(rows), tf.constant(state, tf.float32))
        return losses, int(action)

    def sync_and_act(self, state: np.ndarray) -> int:
        """Before the first batch: the tutorial's soft update still runs every step."""
        return int(self._sync_and_act(tf.constant(state, tf.float32)))

    # -- traced ----------------------------------------------------------------------------
    def update(self, batch: Batch) -> dict[str, tf.Tensor]:
        """In [None] ``optimize_model``: Q(s,a), V(s') from the target net, Huber, clip, AdamW."""
        states, actions, rewards, next_states, dones = batch
        actions = tf.cast(actions[:, 0], tf.int32)  # [B]
        # next_state_values[non_final_mask] = target_net(non_final_next_states).max(1)[0]
        next_values = tf.reduce_max(self.target_network(next_states), axis=1) * (1.0 - dones)  # [B]
        expected = next_values * self.gamma + rewards  # [B]
        with tf.GradientTape() as tape:
            q_values = self.q_network(states)  # [B, A]
            state_action_values = tf.gather(q_values, actions[:, None], batch_dims=1)[:, 0]  # [B]
            loss = huber(state_action_values - expected)
        grads = tape.gradient(loss, self.q_network.trainable_variables)
        # torch.nn.utils.clip_grad_value_(policy_net.parameters(), 100), before optimizer.step()
        grads = [tf.clip_by_value(g, -self.grad_clip_value, self.grad_clip_value) for g in grads]
        self.optimizer.apply_gradients(zip(grads, self.q_network.trainable_variables))
        self._soft_update()
        return {"loss": loss}

    def _soft_update(self):
        soft_update(self.target_network.variables, self.q_network.variables, self.tau)
        return tf.constant(0)

    def _train_rows(self, rows):
        # rows arrive as float32; the networks may compute in float64 (the parity tests do)
        return self.update(self.layout.split(tf.cast(rows, self.q_network.compute_dtype)))

    def _greedy(self, state):
        state = tf.cast(state, self.q_network.compute_dtype)
        return tf.argmax(self.q_network(state[None, :])[0], output_type=tf.int32)


class DQNAgent:
    """The tutorial's loop body per env step, with Dopamine's verbs.

    ``begin_episode(obs) -> action`` and ``step(reward, obs, terminated, truncated) ->
    action or None`` run, in the tutorial's order: push the transition (``next_state =
    None`` only when terminated), ``optimize_model()``, the soft update, then
    ``select_action`` for the next state.
    """

    loss_names = ("loss",)

    def __init__(self, config: CartPoleDQNConfig, obs_dim: int, n_actions: int, action_space, xla: bool = True,
                 dtype: str | None = None):
        self.config = c = config
        q_network = build(QNetwork(obs_dim, n_actions, c.hidden_units, c.init, dtype), obs_dim)
        target_network = build(QNetwork(obs_dim, n_actions, c.hidden_units, c.init, dtype), obs_dim)
        soft_update(target_network.variables, q_network.variables, 1.0)  # target_net.load_state_dict(...)
        optimizer = TorchAdamW(learning_rate=c.lr, epsilon=c.adam_eps, weight_decay=c.weight_decay, amsgrad=c.amsgrad)
        self.learner = DQNLearner(q_network, target_network, optimizer, c.gamma, c.tau, c.grad_clip_value,
                                  Layout(obs_dim, 1), xla=xla)
        buffer_rng, explore_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(c.seed).spawn(2))
        self.buffer = ReplayBuffer(c.buffer_size, Layout(obs_dim, 1), buffer_rng)
        self.explore_rng = explore_rng
        self.action_space = action_space  # env.action_space.sample() for the random branch
        self.steps_done = 0
        self.updates = 0
        self.episode_losses: dict[str, float] = {}
        self._state: np.ndarray | None = None
        self._action: int | None = None

    def select_action(self, greedy_action: int) -> int:
        """In [31] ``select_action``: one uniform draw per step; explore below epsilon."""
        sample = self.explore_rng.random()
        threshold = epsilon(self.config, self.steps_done)
        self.steps_done += 1
        return greedy_action if sample > threshold else int(self.action_space.sample())

    def begin_episode(self, obs: np.ndarray) -> int:
        self.episode_losses = dict.fromkeys(self.loss_names, 0.0)
        self._state = np.asarray(obs, dtype=np.float32)
        self._action = self.select_action(self.learner.greedy(self._state))
        return self._action

    def step(self, reward: float, obs: np.ndarray, terminated: bool, truncated: bool) -> int | None:
        obs = np.asarray(obs, dtype=np.float32)
        # next_state = None if terminated: only termination zeroes V(s'); truncation bootstraps
        self.buffer.add(self._state, self._action, reward, obs, terminated)
        over = terminated or truncated
        if len(self.buffer) >= self.config.batch_size:
            rows = self.buffer.sample_rows(self.config.batch_size)  # random.sample: without replacement
            if over:
                losses, greedy = self.learner.train(rows), None
            else:
                losses, greedy = self.learner.train_and_act(rows, obs)
            self._record(losses)
        elif over:
            self.learner.sync_and_act(obs)  # the soft update still runs; the action is unused
            greedy = None
        else:
            greedy = self.learner.sync_and_act(obs)
        if over:
            return None
        self._state, self._action = obs, self.select_action(greedy)
        return self._action

    def _record(self, losses: dict[str, tf.Tensor]) -> None:
        self.updates += 1
        accumulate_losses(self.episode_losses, losses, f"update {self.updates} (env step {self.steps_done})")

    def greedy_action(self, obs: np.ndarray) -> int:
        return self.learner.greedy(np.asarray(obs, dtype=np.float32))

    def save(self, run_dir: Path) -> None:
        save_weights(self.learner.q_network, Path(run_dir) / "q_network.weights.h5")

    def load_policy(self, run_dir: Path) -> None:
        load_weights(self.learner.q_network, Path(run_dir) / "q_network.weights.h5")
