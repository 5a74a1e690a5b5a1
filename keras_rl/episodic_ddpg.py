"""Post 001's DDPG agent: what reaches the buffer, when, and when it trains.

The learner (networks, the compiled update) is ``keras_rl.ddpg.DDPGLearner``, shared with
post 000; this agent is the part post 001 does differently. Every difference is a switch
in ``MountainCarDDPGConfig`` (FIDELITY P001-*); with all of them off (the ``fixed``
variant) it is an ordinary DDPG agent with OU exploration and a ring buffer.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import tensorflow as tf

from keras_rl.buffers import Layout, PoppingBuffer, ReplayBuffer
from keras_rl.configs import MountainCarDDPGConfig
from keras_rl.ddpg import DDPGLearner
from keras_rl.metrics import accumulate_losses
from keras_rl.networks import MountainCarActor, MountainCarCritic, build
from keras_rl.noise import OUNoise
from keras_rl.targets import soft_update


def standardised_discounted_returns(rewards, discount: float = 0.999) -> np.ndarray:
    """Post 001 ``_compute_discounted_R``: discounted returns of one episode, then
    ``-= mean`` and ``/= std`` in float32, as the post computes them."""
    discounted = np.zeros(len(rewards), dtype=np.float32)
    running_add = 0.0
    for t in reversed(range(len(rewards))):
        running_add = running_add * discount + rewards[t]
        discounted[t] = running_add
    discounted -= discounted.mean()
    discounted /= discounted.std()
    return discounted


def post001_networks(config: MountainCarDDPGConfig, obs_dim: int, action_dim: int):
    """Post 001's four Keras networks in the order ``Agent.__init__`` makes them (actor,
    target actor, critic, target critic), targets hard-copied; returned as actor, critic, targets."""
    c = config
    actor, target_actor = (build(MountainCarActor(action_dim, c.actor_hidden, c.actor_input_noise,
                                                  c.learning_phase_training), obs_dim) for _ in range(2))
    critic, target_critic = (build(MountainCarCritic(c.critic_hidden, c.learning_phase_training), obs_dim, action_dim)
                             for _ in range(2))
    # Agent.__init__: target.model.set_weights(main.model.get_weights()): functional models
    # are built, so unlike post 000 this copy is real.
    soft_update(target_actor.variables, actor.variables, 1.0)
    soft_update(target_critic.variables, critic.variables, 1.0)
    return actor, critic, target_actor, target_critic


class EpisodicDDPGAgent:
    """Post 001's ``Agent`` and main loop body, with Dopamine's verbs."""

    loss_names = ("critic_loss", "actor_loss")

    def __init__(self, config: MountainCarDDPGConfig, obs_low: np.ndarray, obs_high: np.ndarray,
                 action_dim: int, max_episode_steps: int, xla: bool = True):
        self.config = c = config
        obs_dim = len(obs_low)
        self.obs_low = np.asarray(obs_low, np.float32)
        self.obs_span = np.asarray(obs_high, np.float32) - self.obs_low

        layout = Layout(obs_dim, action_dim)
        if c.framework == "torch":
            from keras_rl.torch.ddpg import post001_learner

            self.learner = post001_learner(c, obs_dim, action_dim)
        else:
            self.learner = DDPGLearner.with_adam(
                post001_networks(c, obs_dim, action_dim), c.actor_lr, c.critic_lr,
                gamma=c.gamma, tau=c.tau, broadcast_target=False, layout=layout, xla=xla,
                actor_update=c.actor_gradient, dqda_at_buffer_actions=c.dqda_at_buffer_actions)
        seeds = np.random.SeedSequence(c.seed).spawn(2)
        if c.popping_buffer:
            capacity = c.train_above + max_episode_steps + 1  # the most it can ever hold
            self.buffer = PoppingBuffer(capacity, layout, random.Random(int(seeds[0].generate_state(1)[0])))
        else:
            self.buffer = ReplayBuffer(c.buffer_size, layout, np.random.default_rng(seeds[0]))
        self.noise = (OUNoise(action_dim, np.random.default_rng(seeds[1]), theta=c.ou_theta, dt=c.ou_dt,
                              sigma=c.ou_sigma) if c.exploration == "ou" else None)
        self.layout = layout
        self.updates = 0
        self.total_steps = 0
        self.episode_losses: dict[str, float] = {}
        self._record: list[np.ndarray] = []
        self._state: np.ndarray | None = None
        self._action: np.ndarray | None = None

    def normalise(self, frame: np.ndarray) -> np.ndarray:
        """``(state - env.observation_space.low) / (high - low)``."""
        return (np.asarray(frame, np.float32) - self.obs_low) / self.obs_span

    def _act(self, state: np.ndarray) -> np.ndarray:
        action = self.learner.act(state).numpy()  # agent.get_action: model.predict, learning phase 0
        if self.noise is not None:
            action = np.clip(action + self.noise().astype(np.float32), -1.0, 1.0)
        return action

    def begin_episode(self, obs: np.ndarray) -> np.ndarray:
        self.episode_losses = dict.fromkeys(self.loss_names, 0.0)
        self._record = []
        if self.noise is not None:
            self.noise.reset()
        self._state = self.normalise(obs)
        self._action = self._act(self._state)
        return self._action

    def step(self, reward: float, obs: np.ndarray, terminated: bool, truncated: bool) -> np.ndarray | None:
        c = self.config
        self.total_steps += 1
        over = terminated or truncated
        done = over if c.done_includes_truncation else terminated  # P001-DONE
        next_state = np.asarray(obs, np.float32) if c.store_raw_next_state else self.normalise(obs)  # P001-NEXTSTATE
        row = np.concatenate([self._state, self._action, [reward], next_state, [float(done)]]).astype(np.float32)
        if c.episode_returns_as_rewards:  # P001-RETURNS: record, and store only when the episode ends
            self._record.append(row)
            if over:
                rows = np.stack(self._record)
                rows[:, self.layout.obs_dim + self.layout.action_dim] = standardised_discounted_returns(
                    rows[:, self.layout.obs_dim + self.layout.action_dim].astype(np.float64).tolist(),
                    c.return_discount)
                self.buffer.add_rows(rows)
        else:
            self.buffer.add_rows(row[None, :])
        self._train()
        if over:
            return None
        self._state = self.normalise(obs)
        self._action = self._act(self._state)
        return self._action

    def _train(self) -> None:
        c = self.config
        if c.popping_buffer:
            # P001-TRIGGER: `if len(agent.memory) > 1000: agent.train()`, every env step; train()
            # pops batch after batch `while len(self.memory) > 100`, soft-updating after each.
            if len(self.buffer) > c.train_above:
                while len(self.buffer) > c.train_down_to:
                    self._record_losses(self.learner.train(self.buffer.sample_rows(c.batch_size)))
        elif len(self.buffer) >= c.train_start:
            self._record_losses(self.learner.train(self.buffer.sample_rows(c.batch_size)))

    def _record_losses(self, losses: dict[str, tf.Tensor]) -> None:
        self.updates += 1
        accumulate_losses(self.episode_losses, losses, f"update {self.updates} (env step {self.total_steps})")

    def greedy_action(self, obs: np.ndarray) -> np.ndarray:
        return self.learner.act(self.normalise(obs)).numpy()

    def save(self, run_dir: Path) -> None:
        self.learner.save(run_dir)

    def load_policy(self, run_dir: Path) -> None:
        self.learner.load_policy(run_dir)
