"""DDPG in Keras: one compiled learner for posts 000 and 001, and their network builders.

The learner owns one compiled update (Acme's ``_step``): critic first, then actor, then
the soft update of both targets. It never leaves the graph: no ``get_weights``/
``set_weights``, no ``.predict``. How the actor's gradient is formed is a switch:

- ``mean_q`` (post 000 §2.3.3): minimise ``-mean(Q(s, mu(s)))`` with a GradientTape;
- ``dpg_intended`` (post 001, as its formula means): ``tape.gradient(mu(s), theta,
  output_gradients=-dQ/da)``, the first-order deterministic policy gradient, summed;
- ``dpg_literal`` (post 001, as its Keras 2 code computes): that list of gradients is
  handed to ``optimizer.get_updates(loss=...)``, which differentiates it *again*: the
  step follows ``d/dtheta sum_k sum(g_k)``, a second-order quantity (FIDELITY P001-ACTORGRAD).
"""

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
from keras_rl.learners.networks import Actor, Critic, MountainCarActor, MountainCarCritic, build
from keras_rl.learners.protocol import ActorGradient, check_actor_gradient, four_networks


class DDPGLearner:
    """Networks, optimizers and the compiled update of post 000 §2.3.3 (and post 001's)."""

    loss_names = ("critic_loss", "actor_loss")

    def __init__(
        self,
        actor: keras.Model,
        critic: keras.Model,
        target_actor: keras.Model,
        target_critic: keras.Model,
        actor_optimizer: keras.optimizers.Optimizer,
        critic_optimizer: keras.optimizers.Optimizer,
        *,
        gamma: float,
        tau: float,
        broadcast_target: bool,
        layout: Layout,
        xla: bool = True,
        actor_gradient: ActorGradient = "mean_q",
        dqda_at_buffer_actions: bool = False,
    ):
        self.actor_gradient = check_actor_gradient(actor_gradient)
        self.dqda_at_buffer_actions = bool(dqda_at_buffer_actions)
        self.actor, self.critic = actor, critic
        self.target_actor, self.target_critic = target_actor, target_critic
        self.actor_optimizer, self.critic_optimizer = actor_optimizer, critic_optimizer
        self.gamma, self.tau = float(gamma), float(tau)
        self.broadcast_target = bool(broadcast_target)
        self.layout = layout
        self.xla = xla
        self.build_optimizers()
        self._train: Any = None  # the compiled steps, traced by compile()

    def compile(self) -> None:
        """Trace the compiled steps, once (the loop calls it before its first env step; the
        first call to train or act does it for anyone else): the update, the act, and both
        fused into one call per env step (the post trains at the end of step t and picks
        step t+1's action with the updated actor; so do we)."""
        if self._train is not None:
            return
        rows, obs = self.input_specs()
        self._train = step_function(self.update, self.xla, rows).get_concrete_function()
        self._act = step_function(self._act_one, self.xla, obs).get_concrete_function()
        self._train_and_act = step_function(self._train_rows_and_act, self.xla, rows, obs).get_concrete_function()

    # -- hooks: a stacked learner (``stacked.py``) runs this same update over a seed axis -----
    def build_optimizers(self) -> None:
        self.actor_optimizer.build(self.actor.trainable_variables)
        self.critic_optimizer.build(self.critic.trainable_variables)

    def input_specs(self) -> tuple[tf.TensorSpec, tf.TensorSpec]:
        """Packed transitions ``[B, width]`` (buffers.py) and one state ``[obs]``."""
        return tf.TensorSpec([None, self.layout.width], tf.float32), tf.TensorSpec([self.layout.obs_dim], tf.float32)

    def seed_mean(self, x: tf.Tensor) -> tf.Tensor:
        """A loss's mean over the batch (per seed, stacked)."""
        return tf.reduce_mean(x)

    def total(self, loss: tf.Tensor) -> tf.Tensor:
        """What the gradient is taken of (stacked: the sum of the seeds' losses)."""
        return loss

    def apply_gradients(self, optimizer, grads, variables) -> None:
        optimizer.apply_gradients(zip(grads, variables))

    def seeds_that_train(self) -> tf.Tensor | None:
        """The seeds whose targets the soft update moves (stacked: a mask); None: all."""
        return None

    @classmethod
    def with_adam(
        cls,
        networks: tuple[keras.Model, keras.Model, keras.Model, keras.Model],
        actor_lr: float,
        critic_lr: float,
        **kwargs,
    ) -> DDPGLearner:
        """The posts' set-up: (actor, critic, target actor, target critic), each network with
        its own Keras Adam (Keras 2's Adam of post 001 has the same epsilon and update rule)."""
        return cls(
            *networks,
            keras.optimizers.Adam(learning_rate=actor_lr),
            keras.optimizers.Adam(learning_rate=critic_lr),
            **kwargs,
        )

    # -- the Learner protocol --------------------------------------------------------------
    def train(self, rows: np.ndarray) -> dict[str, tf.Tensor]:
        """One update on packed transition rows [B, width]; returns the losses."""
        self.compile()
        return self._train(tf.constant(rows))

    def act(self, state: np.ndarray) -> np.ndarray:
        """The actor's action for one state [obs] -> [act], without noise."""
        self.compile()
        return self._act(tf.constant(state, tf.float32)).numpy()

    def train_and_act(self, rows: np.ndarray, state: np.ndarray) -> tuple[dict[str, tf.Tensor], np.ndarray]:
        self.compile()
        losses, action = self._train_and_act(tf.constant(rows), tf.constant(state, tf.float32))
        return losses, action.numpy()

    def step_without_batch(self, state: np.ndarray, want_action: bool) -> np.ndarray | None:
        return self.act(state) if want_action else None

    def save(self, run_dir: Path) -> None:
        """``actor.weights.h5`` and ``critic.weights.h5`` (post 000 §2.4 saves the actor)."""
        save_weights(self.actor, Path(run_dir) / "actor.weights.h5")
        save_weights(self.critic, Path(run_dir) / "critic.weights.h5")

    def load_policy(self, run_dir: Path) -> None:
        """Post 000 §3: ``agent.actor.load_weights(...)``: only the actor is needed to play."""
        load_weights(self.actor, Path(run_dir) / "actor.weights.h5")

    def weights(self) -> dict[str, list[np.ndarray]]:
        return {
            name: numpy_weights(getattr(self, name)) for name in ("actor", "critic", "target_actor", "target_critic")
        }

    def _stateful(self) -> list:
        return [
            *(v for m in (self.actor, self.critic, self.target_actor, self.target_critic) for v in m.variables),
            *self.actor_optimizer.variables,
            *self.critic_optimizer.variables,
        ]

    def state_dict(self) -> dict:
        return {"variables": variables_state(self._stateful())}

    def load_state_dict(self, state: dict) -> None:
        load_variables_state(self._stateful(), state["variables"])

    # -- traced -----------------------------------------------------------------------------
    def td_targets(self, rewards: tf.Tensor, next_states: tf.Tensor, dones: tf.Tensor) -> tf.Tensor:
        """The critic's regression targets, [B,B] under P000-BROADCAST, else [B,1]."""
        next_q = self.target_critic(next_states, self.target_actor(next_states))  # [B, 1]
        rewards = rewards[..., None]  # [B, 1]: the post's rewards came back from env.step as (1,)
        if self.broadcast_target:
            # P000-BROADCAST: the post's dones are [B], so (1 - dones) broadcasts along the
            # *columns*: targets[i, j] = r_i + gamma * Q'_i * (1 - d_j)            # [B, B]
            return rewards + self.gamma * next_q * (1.0 - dones[..., None, :])
        return rewards + self.gamma * next_q * (1.0 - dones[..., :, None])  # [B, 1]

    def update(self, batch: Batch | tf.Tensor) -> dict[str, tf.Tensor]:
        """Post 000 §2.3.3, traceable: critic tape, actor tape, soft updates; on a ``Batch``, or
        on packed transition rows (``buffers.Layout``), which it splits."""
        if not isinstance(batch, Batch):
            batch = self.layout.split(batch)
        states, actions, rewards, next_states, dones = batch
        targets = self.td_targets(rewards, next_states, dones)  # computed before the tape, as in §2.3.3

        with tf.GradientTape() as tape:
            q_values = self.critic(states, actions)  # [B, 1]
            # Under P000-BROADCAST q_values [B,1] - targets [B,B] averages over B*B terms.
            critic_loss = self.seed_mean(tf.square(q_values - targets))
            critic_total = self.total(critic_loss)
        critic_grads = tape.gradient(critic_total, self.critic.trainable_variables)
        self.apply_gradients(self.critic_optimizer, critic_grads, self.critic.trainable_variables)

        actor_grads, actor_loss = self.actor_gradients(states, actions)
        self.apply_gradients(self.actor_optimizer, actor_grads, self.actor.trainable_variables)

        soft_update(
            [*self.target_actor.variables, *self.target_critic.variables],
            [*self.actor.variables, *self.critic.variables],
            self.tau,
            self.seeds_that_train(),
        )
        return {"critic_loss": critic_loss, "actor_loss": actor_loss}

    def actor_gradients(self, states, actions):
        """The actor's gradients (see the module docstring) and a loss to report, -mean Q."""
        variables = self.actor.trainable_variables
        if self.actor_gradient == "mean_q":
            with tf.GradientTape() as tape:
                q_values = self.critic(states, self.actor(states))  # the freshly updated critic
                actor_loss = -self.seed_mean(q_values)
                actor_total = self.total(actor_loss)
            return tape.gradient(actor_total, variables), actor_loss
        # post 001: dQ/da from the updated critic, at the buffer's actions (as the post feeds
        # `actions`) or at mu(s); a constant for the actor's update (a placeholder in Keras 2)
        policy_actions = self.actor(states)
        at = actions if self.dqda_at_buffer_actions else policy_actions
        with tf.GradientTape() as tape:
            tape.watch(at)
            q_values = self.critic(states, at)
        dq_da = tf.stop_gradient(tape.gradient(q_values, at))  # [B, act]
        actor_loss = -self.seed_mean(q_values)
        if self.actor_gradient == "dpg_intended":
            with tf.GradientTape() as tape:
                mu = self.actor(states)
            return tape.gradient(mu, variables, output_gradients=-dq_da), actor_loss
        # dpg_literal: Keras 2's get_updates(loss=[g_1..g_k]) calls K.gradients(loss, params),
        # i.e. tf.gradients of a list, which differentiates the sum of all its entries.
        with tf.GradientTape() as outer:
            with tf.GradientTape() as inner:
                mu = self.actor(states)
            first = inner.gradient(mu, variables, output_gradients=-dq_da)
            total = tf.add_n([tf.reduce_sum(g) for g in first])
        return outer.gradient(total, variables, unconnected_gradients=tf.UnconnectedGradients.ZERO), actor_loss

    def _act_one(self, state):
        return self.actor(state[None, :])[0]  # [act]

    def _train_rows_and_act(self, rows, state):
        losses = self.update(rows)
        return losses, self._act_one(state)


def _hard_copy(target: keras.Model, source: keras.Model) -> None:
    soft_update(target.variables, source.variables, 1.0)


def post000_networks(config, spec: EnvSpec):
    """Post 000's four Keras networks (``four_networks``'s order). The fixed variant does
    what §2.4's ``update_target_networks(1.0)`` meant to do: a real hard copy (P000-TARGETINIT)."""
    c = config
    return four_networks(
        lambda: build(Actor(spec.action_dim, spec.action_bound, c.actor_hidden_units), spec.obs_dim),
        lambda: build(Critic(c.critic_hidden_units), spec.obs_dim, spec.action_dim),
        None if c.target_copy_is_noop else _hard_copy,
    )


def post000_learner(config, spec: EnvSpec, xla: bool = True) -> DDPGLearner:
    c = config
    return DDPGLearner.with_adam(
        post000_networks(c, spec),
        c.actor_lr,
        c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=c.broadcast_target,
        layout=Layout(spec.obs_dim, spec.action_dim),
        xla=xla,
    )


def post001_networks(config, spec: EnvSpec):
    """Post 001's four Keras networks in the order ``Agent.__init__`` makes them. Its
    ``target.model.set_weights(main.model.get_weights())`` copies built functional models,
    so unlike post 000's this copy is real."""
    c = config
    return four_networks(
        lambda: build(
            MountainCarActor(spec.action_dim, c.actor_hidden_units, c.actor_input_noise, c.learning_phase_training),
            spec.obs_dim,
        ),
        lambda: build(
            MountainCarCritic(c.critic_hidden_units, c.learning_phase_training), spec.obs_dim, spec.action_dim
        ),
        _hard_copy,
    )


def post001_learner(config, spec: EnvSpec, xla: bool = True) -> DDPGLearner:
    c = config
    return DDPGLearner.with_adam(
        post001_networks(c, spec),
        c.actor_lr,
        c.critic_lr,
        gamma=c.gamma,
        tau=c.tau,
        broadcast_target=False,
        layout=Layout(spec.obs_dim, spec.action_dim),
        xla=xla,
        actor_gradient=c.actor_gradient,
        dqda_at_buffer_actions=c.dqda_at_buffer_actions,
    )
