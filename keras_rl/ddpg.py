"""DDPG: one compiled learner for posts 000 and 001, and post 000's agent.

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

import keras
import numpy as np
import tensorflow as tf

from keras_rl.buffers import Batch, Layout, ReplayBuffer
from keras_rl.configs import PendulumDDPGConfig
from keras_rl.metrics import accumulate_losses
from keras_rl.networks import Actor, Critic, build
from keras_rl.noise import OUNoise
from keras_rl.results import load_weights, save_weights
from keras_rl.targets import soft_update


class DDPGLearner:
    """Networks, optimizers and the compiled update of post 000 §2.3.3."""

    def __init__(self, actor: keras.Model, critic: keras.Model, target_actor: keras.Model,
                 target_critic: keras.Model, actor_optimizer: keras.optimizers.Optimizer,
                 critic_optimizer: keras.optimizers.Optimizer, gamma: float, tau: float,
                 broadcast_target: bool, layout: Layout, xla: bool = True, actor_update: str = "mean_q",
                 dqda_at_buffer_actions: bool = False):
        if actor_update not in ("mean_q", "dpg_intended", "dpg_literal"):
            raise ValueError(f"actor_update must be mean_q, dpg_intended or dpg_literal, got {actor_update!r}")
        self.actor_update, self.dqda_at_buffer_actions = actor_update, bool(dqda_at_buffer_actions)
        self.actor, self.critic = actor, critic
        self.target_actor, self.target_critic = target_actor, target_critic
        self.actor_optimizer, self.critic_optimizer = actor_optimizer, critic_optimizer
        self.gamma, self.tau = float(gamma), float(tau)
        self.broadcast_target = bool(broadcast_target)
        self.layout = layout
        actor_optimizer.build(actor.trainable_variables)
        critic_optimizer.build(critic.trainable_variables)
        rows = tf.TensorSpec([None, layout.width], tf.float32)  # packed transitions, see buffers.py
        obs = tf.TensorSpec([layout.obs_dim], tf.float32)
        # Concrete functions: calling them skips tf.function's per-call signature dispatch,
        # which costs as much as the update itself at these network sizes (benchmarks/).
        self._train = compile_step(self._train_rows, xla, rows)
        self._act = compile_step(self._act_one, xla, obs)
        # Acting and training fused into one call per env step: the post trains at the
        # end of step t and picks step t+1's action with the updated actor; so do we.
        self._train_and_act = compile_step(self._train_rows_and_act, xla, rows, obs)

    @classmethod
    def with_adam(cls, networks: tuple[keras.Model, keras.Model, keras.Model, keras.Model], actor_lr: float,
                  critic_lr: float, **kwargs) -> "DDPGLearner":
        """The posts' set-up: (actor, critic, target actor, target critic), each network with
        its own Keras Adam (Keras 2's Adam of post 001 has the same epsilon and update rule)."""
        return cls(*networks, keras.optimizers.Adam(learning_rate=actor_lr),
                   keras.optimizers.Adam(learning_rate=critic_lr), **kwargs)

    def train(self, rows: np.ndarray) -> dict[str, tf.Tensor]:
        """One update on packed transition rows [B, width]; returns the losses."""
        return self._train(tf.constant(rows))

    def act(self, state: np.ndarray) -> tf.Tensor:
        """The actor's action for one state [obs] -> [act], without noise."""
        return self._act(tf.constant(state, tf.float32))

    def train_and_act(self, rows: np.ndarray, state: np.ndarray) -> tuple[dict[str, tf.Tensor], tf.Tensor]:
        return self._train_and_act(tf.constant(rows), tf.constant(state, tf.float32))

    def targets(self, rewards: tf.Tensor, next_states: tf.Tensor, dones: tf.Tensor) -> tf.Tensor:
        """The critic's regression targets, [B,B] under P000-BROADCAST, else [B,1]."""
        next_q = self.target_critic(next_states, self.target_actor(next_states))  # [B, 1]
        rewards = rewards[:, None]  # [B, 1]: the post's rewards came back from env.step as (1,)
        if self.broadcast_target:
            # P000-BROADCAST: the post's dones are [B], so (1 - dones) broadcasts along the
            # *columns*: targets[i, j] = r_i + gamma * Q'_i * (1 - d_j)            # [B, B]
            return rewards + self.gamma * next_q * (1.0 - dones[None, :])
        return rewards + self.gamma * next_q * (1.0 - dones[:, None])  # [B, 1]

    def update(self, batch: Batch) -> dict[str, tf.Tensor]:
        """Post 000 §2.3.3, traceable: critic tape, actor tape, soft updates."""
        states, actions, rewards, next_states, dones = batch
        targets = self.targets(rewards, next_states, dones)  # computed before the tape, as in §2.3.3

        with tf.GradientTape() as tape:
            q_values = self.critic(states, actions)  # [B, 1]
            # Under P000-BROADCAST q_values [B,1] - targets [B,B] averages over B*B terms.
            critic_loss = tf.reduce_mean(tf.square(q_values - targets))
        critic_grads = tape.gradient(critic_loss, self.critic.trainable_variables)
        self.critic_optimizer.apply_gradients(zip(critic_grads, self.critic.trainable_variables))

        actor_grads, actor_loss = self.actor_gradients(states, actions)
        self.actor_optimizer.apply_gradients(zip(actor_grads, self.actor.trainable_variables))

        soft_update(self.target_actor.variables, self.actor.variables, self.tau)
        soft_update(self.target_critic.variables, self.critic.variables, self.tau)
        return {"critic_loss": critic_loss, "actor_loss": actor_loss}

    def actor_gradients(self, states, actions):
        """The actor's gradients (see the module docstring) and a loss to report, -mean Q."""
        variables = self.actor.trainable_variables
        if self.actor_update == "mean_q":
            with tf.GradientTape() as tape:
                q_values = self.critic(states, self.actor(states))  # the freshly updated critic
                actor_loss = -tf.reduce_mean(q_values)
            return tape.gradient(actor_loss, variables), actor_loss
        # post 001: dQ/da from the updated critic, at the buffer's actions (as the post feeds
        # `actions`) or at mu(s); a constant for the actor's update (a placeholder in Keras 2)
        policy_actions = self.actor(states)
        at = actions if self.dqda_at_buffer_actions else policy_actions
        with tf.GradientTape() as tape:
            tape.watch(at)
            q_values = self.critic(states, at)
        dq_da = tf.stop_gradient(tape.gradient(q_values, at))  # [B, act]
        actor_loss = -tf.reduce_mean(q_values)
        if self.actor_update == "dpg_intended":
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

    def _train_rows(self, rows):
        return self.update(self.layout.split(rows))

    def save(self, run_dir: Path) -> None:
        """``actor.weights.h5`` and ``critic.weights.h5`` (post 000 §2.4 saves the actor)."""
        save_weights(self.actor, Path(run_dir) / "actor.weights.h5")
        save_weights(self.critic, Path(run_dir) / "critic.weights.h5")

    def load_policy(self, run_dir: Path) -> None:
        """Post 000 §3: ``agent.actor.load_weights(...)``: only the actor is needed to play."""
        load_weights(self.actor, Path(run_dir) / "actor.weights.h5")

    def _act_one(self, state):
        return self.actor(state[None, :])[0]  # [act]

    def _train_rows_and_act(self, rows, state):
        losses = self._train_rows(rows)
        return losses, self._act_one(state)


def compile_step(fn, xla: bool, *specs: tf.TensorSpec):
    """``tf.function`` (XLA-compiled when ``xla``) traced once for ``specs``."""
    return tf.function(fn, jit_compile=xla, input_signature=list(specs)).get_concrete_function()


def post000_networks(config: PendulumDDPGConfig, obs_dim: int, action_dim: int,
                     action_bound: float) -> tuple[keras.Model, keras.Model, keras.Model, keras.Model]:
    """Post 000's four Keras networks, in the order the agent draws their initial weights:
    actor, target actor, critic, target critic (returned as actor, critic, targets)."""
    c = config
    actor = build(Actor(action_dim, action_bound, c.hidden_units), obs_dim)
    target_actor = build(Actor(action_dim, action_bound, c.hidden_units), obs_dim)
    critic = build(Critic(c.hidden_units), obs_dim, action_dim)
    target_critic = build(Critic(c.hidden_units), obs_dim, action_dim)
    if not c.target_copy_is_noop:
        # The fixed variant does what §2.4's update_target_networks(1.0) meant to do.
        soft_update(target_actor.variables, actor.variables, 1.0)
        soft_update(target_critic.variables, critic.variables, 1.0)
    return actor, critic, target_actor, target_critic


class DDPGAgent:
    """Post 000's agent: noisy actions, a FIFO buffer, one update per env step.

    Public face (Dopamine): ``begin_episode(obs) -> action``,
    ``step(reward, obs, terminated, truncated) -> action or None`` and ``greedy_action``.
    """

    def __init__(self, config: PendulumDDPGConfig, obs_dim: int, action_dim: int,
                 action_bound: float, xla: bool = True):
        self.config = c = config
        self.action_bound = float(action_bound)
        if c.framework == "torch":
            from keras_rl.torch.ddpg import post000_learner

            self.learner = post000_learner(c, obs_dim, action_dim, action_bound)
        else:
            self.learner = DDPGLearner.with_adam(
                post000_networks(c, obs_dim, action_dim, action_bound), c.actor_lr, c.critic_lr,
                gamma=c.gamma, tau=c.tau, broadcast_target=c.broadcast_target,
                layout=Layout(obs_dim, action_dim), xla=xla)
        buffer_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(c.seed).spawn(2))
        self.buffer = ReplayBuffer(c.buffer_size, Layout(obs_dim, action_dim), buffer_rng)
        self.noise = OUNoise(action_dim, noise_rng, theta=c.noise_theta, mu=c.noise_mu, dt=c.noise_dt,
                             sigma=c.noise_sigma, carry_state=not c.noise_restarts_from_zero)
        self.total_steps = 0
        self.updates = 0
        self.episode_losses: dict[str, float] = {}
        self._state: np.ndarray | None = None
        self._action: np.ndarray | None = None

    @property
    def actor(self) -> keras.Model:
        return self.learner.actor

    @property
    def critic(self) -> keras.Model:
        return self.learner.critic

    def _explore(self, raw_action: tf.Tensor) -> np.ndarray:
        # §2.4: np.clip(action + noise, -2, 2); the post adds float64 noise to a float32
        # tensor, which TensorFlow casts to float32 first.
        noisy = raw_action.numpy() + self.noise().astype(np.float32)
        return np.clip(noisy, -self.config.action_clip, self.config.action_clip)

    def begin_episode(self, obs: np.ndarray) -> np.ndarray:
        self.noise.reset()  # §2.4: pre_noise = np.zeros(action_size)
        self.episode_losses = dict.fromkeys(self.loss_names, 0.0)
        self._state = np.asarray(obs, dtype=np.float32)
        self._action = self._explore(self.learner.act(self._state))
        return self._action

    def step(self, reward: float, obs: np.ndarray, terminated: bool, truncated: bool) -> np.ndarray | None:
        """Store the transition, train, and return the next action (None once the episode is over)."""
        c = self.config
        obs = np.asarray(obs, dtype=np.float32)
        # P000-DONE: the post stores env.step's 4th value, `truncated`, as `done`.
        done = truncated if c.done_from_truncated else terminated
        self.buffer.add(self._state, self._action, reward, obs, done)
        self.total_steps += 1
        episode_over = terminated or truncated
        raw = None
        if len(self.buffer) >= c.train_start and self.total_steps % c.train_every == 0:
            rows = self.buffer.sample_rows(c.batch_size)  # random.sample: without replacement
            if episode_over:
                losses = self.learner.train(rows)
            else:
                losses, raw = self.learner.train_and_act(rows, obs)
            self._record(losses)
        if episode_over:
            return None
        if raw is None:
            raw = self.learner.act(obs)
        self._state, self._action = obs, self._explore(raw)
        return self._action

    def _record(self, losses: dict[str, tf.Tensor]) -> None:
        self.updates += 1
        accumulate_losses(self.episode_losses, losses, f"env step {self.total_steps} (update {self.updates})")

    def greedy_action(self, obs: np.ndarray) -> np.ndarray:
        """§3 test: ``agent.get_action(state)`` with no noise."""
        return self.learner.act(np.asarray(obs, dtype=np.float32)).numpy()

    def train_batch(self, batch: Batch) -> dict[str, float]:
        """One update on a given batch (for tests and benchmarks)."""
        rows = self.learner.layout.pack(Batch(*batch))
        return {k: float(v) for k, v in self.learner.train(rows).items()}

    loss_names = ("critic_loss", "actor_loss")

    def save(self, run_dir: Path) -> None:
        """The learner's weight files: ``actor``/``critic`` ``.weights.h5`` (Keras) or ``.pt`` (torch)."""
        self.learner.save(run_dir)

    def load_policy(self, run_dir: Path) -> None:
        self.learner.load_policy(run_dir)
