"""DQN as the PyTorch tutorial (post 003) runs it, in Keras with one compiled step per env step."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import keras
import numpy as np
import tensorflow as tf

from keras_rl.buffers import Batch, Layout
from keras_rl.envs import EnvSpec
from keras_rl.learners.common import (
    load_variables_state,
    load_weights,
    numpy_weights,
    save_weights,
    soft_update,
    step_function,
    variables_state,
)
from keras_rl.learners.networks import QNetwork, build
from keras_rl.learners.optimizers import TorchAdamW


def huber(x: tf.Tensor, axis=None) -> tf.Tensor:
    """``nn.SmoothL1Loss()`` (beta=1, mean) = Huber with delta 1, averaged (over ``axis``:
    the seed-batched learner averages each seed's batch on its own)."""
    abs_x = tf.abs(x)
    quadratic = tf.minimum(abs_x, 1.0)
    return tf.reduce_mean(0.5 * tf.square(quadratic) + (abs_x - quadratic), axis=axis)


class DQNLearner:
    """The policy and target networks and the compiled ``optimize_model`` + soft update."""

    loss_names = ("loss",)

    def __init__(
        self,
        q_network: keras.Model,
        target_network: keras.Model,
        optimizer: keras.optimizers.Optimizer,
        *,
        gamma: float,
        tau: float,
        grad_clip_value: float,
        layout: Layout,
        xla: bool = True,
    ):
        self.q_network, self.target_network, self.optimizer = q_network, target_network, optimizer
        self.gamma, self.tau, self.grad_clip_value = float(gamma), float(tau), float(grad_clip_value)
        self.layout = layout
        self.xla = xla
        optimizer.build(q_network.trainable_variables)
        self._train: Any = None  # the compiled steps, traced by compile()

    def compile(self) -> None:
        """Trace the compiled steps, once (the loop calls it before its first env step; the
        first call to train or act does it for anyone else)."""
        if self._train is not None:
            return
        rows, obs = self.input_specs()
        self._train = step_function(self.update, self.xla, rows).get_concrete_function()
        self._act = step_function(self._greedy, self.xla, obs).get_concrete_function()
        self._train_and_act = step_function(
            lambda r, s: (self.update(r), self._greedy(s)), self.xla, rows, obs
        ).get_concrete_function()
        self._sync_and_act = step_function(
            lambda s: (self._soft_update(), self._greedy(s))[1], self.xla, obs
        ).get_concrete_function()

    def input_specs(self) -> tuple[tf.TensorSpec, tf.TensorSpec]:
        """Packed rows [B, width] and one state [obs]."""
        return tf.TensorSpec([None, self.layout.width], tf.float32), tf.TensorSpec([self.layout.obs_dim], tf.float32)

    # -- the Learner protocol --------------------------------------------------------------
    def train(self, rows: np.ndarray) -> dict[str, tf.Tensor]:
        """``optimize_model()`` then the soft update, on packed rows [B, width]."""
        self.compile()
        return self._train(tf.constant(rows))

    def act(self, state: np.ndarray) -> int:
        """``policy_net(state).max(1)[1]``: the argmax action for one state."""
        self.compile()
        return int(self._act(tf.constant(state, tf.float32)))

    def train_and_act(self, rows: np.ndarray, state: np.ndarray) -> tuple[dict[str, tf.Tensor], int]:
        self.compile()
        losses, action = self._train_and_act(tf.constant(rows), tf.constant(state, tf.float32))
        return losses, int(action)

    def step_without_batch(self, state: np.ndarray, want_action: bool) -> int | None:
        """Before the first batch: the tutorial's soft update still runs every step."""
        self.compile()
        action = int(self._sync_and_act(tf.constant(state, tf.float32)))
        return action if want_action else None

    def save(self, run_dir: Path) -> None:
        save_weights(self.q_network, Path(run_dir) / "q_network.weights.h5")

    def load_policy(self, run_dir: Path) -> None:
        load_weights(self.q_network, Path(run_dir) / "q_network.weights.h5")

    def weights(self) -> dict[str, list[np.ndarray]]:
        return {"q_network": numpy_weights(self.q_network), "target_network": numpy_weights(self.target_network)}

    def _stateful(self) -> list:
        return [*self.q_network.variables, *self.target_network.variables, *self.optimizer.variables]

    def state_dict(self) -> dict:
        return {"variables": variables_state(self._stateful())}

    def load_state_dict(self, state: dict) -> None:
        load_variables_state(self._stateful(), state["variables"])

    # -- traced ----------------------------------------------------------------------------
    def update(self, batch: Batch | tf.Tensor) -> dict[str, tf.Tensor]:
        """In [None] ``optimize_model``: Q(s,a), V(s') from the target net, Huber, clip, AdamW.
        Shapes are [B, ...]. On a ``Batch``, or on packed rows (``buffers.Layout``), which it splits; rows arrive as
        float32, and the networks may compute in float64 (the parity tests do)."""
        if not isinstance(batch, Batch):
            batch = self.layout.split(tf.cast(batch, self.q_network.compute_dtype))
        states, actions, rewards, next_states, dones = batch
        actions = tf.cast(actions[..., 0], tf.int32)  # [B]
        # next_state_values[non_final_mask] = target_net(non_final_next_states).max(1)[0]
        next_values = tf.reduce_max(self.target_network(next_states), axis=-1) * (1.0 - dones)  # [B]
        expected = next_values * self.gamma + rewards  # [B]
        with tf.GradientTape() as tape:
            q_values = self.q_network(states)  # [B, A]
            state_action_values = tf.gather(q_values, actions[..., None], batch_dims=actions.shape.rank)[..., 0]
            loss = huber(state_action_values - expected, axis=-1)  # a scalar
        grads = tape.gradient(loss, self.q_network.trainable_variables)
        # torch.nn.utils.clip_grad_value_(policy_net.parameters(), 100), before optimizer.step()
        grads = [tf.clip_by_value(g, -self.grad_clip_value, self.grad_clip_value) for g in grads]
        self.optimizer.apply_gradients(zip(grads, self.q_network.trainable_variables))
        self._soft_update()
        return {"loss": loss}

    def _soft_update(self):
        soft_update(self.target_network.variables, self.q_network.variables, self.tau)
        return tf.constant(0)

    def _greedy(self, state):
        state = tf.cast(state, self.q_network.compute_dtype)
        return tf.argmax(self.q_network(state[None, :])[0], output_type=tf.int32)


def post003_networks(config, spec: EnvSpec, dtype: str | None = None) -> tuple[keras.Model, keras.Model]:
    """In [28]: ``policy_net``, then ``target_net`` with ``target_net.load_state_dict(policy_net.state_dict())``."""
    c = config
    if spec.n_actions is None:
        raise ValueError("post 003's Q-network needs a Discrete action space (spec.n_actions)")
    q_network = build(QNetwork(spec.obs_dim, spec.n_actions, c.q_hidden_units, c.init, dtype), spec.obs_dim)
    target_network = build(QNetwork(spec.obs_dim, spec.n_actions, c.q_hidden_units, c.init, dtype), spec.obs_dim)
    soft_update(target_network.variables, q_network.variables, 1.0)  # target_net.load_state_dict(...)
    return q_network, target_network


def post003_optimizer(config) -> TorchAdamW:
    """In [28]: ``optim.AdamW(policy_net.parameters(), lr=LR, amsgrad=True)``, torch's defaults otherwise."""
    c = config
    return TorchAdamW(learning_rate=c.q_lr, epsilon=c.adam_eps, weight_decay=c.weight_decay, amsgrad=c.amsgrad)


def post003_learner(config, spec: EnvSpec, xla: bool = True, dtype: str | None = None) -> DQNLearner:
    """The tutorial's ``policy_net``, ``target_net`` and AdamW."""
    c = config
    return DQNLearner(
        *post003_networks(c, spec, dtype),
        post003_optimizer(c),
        gamma=c.gamma,
        tau=c.tau,
        grad_clip_value=c.grad_clip_value,
        layout=Layout(spec.obs_dim, 1),
        xla=xla,
    )
