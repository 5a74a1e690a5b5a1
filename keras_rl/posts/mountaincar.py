"""Post 001: DDPG on ``MountainCarContinuous-v0``, written in Keras 2 / TF1 graph style.

Quotes are from ``../shared/seeds/001_98f9c3d244106c52.txt``. Every quirk (FIDELITY P001-*)
is a switch at the end of the config. Where each takes effect:

- what reaches the buffer, and when (P001-RETURNS, P001-NEXTSTATE, P001-DONE): ``assemble``'s
  ``TransitionRule`` and ``standardised_discounted_returns`` below;
- when it trains (P001-POP, P001-TRIGGER): ``assemble``'s ``Bursts`` schedule and
  ``buffers.PoppingBuffer``;
- how it explores (P001-NOEXPLORE): ``assemble``'s explorer;
- the actor's gradient and the critic's dQ/da (P001-ACTORGRAD, P001-DQDA): the learner
  (``learners/ddpg.py``, ``torch/ddpg.py``);
- the learning phase (P001-PHASE): the networks (``learners/networks.py``).

With every switch off (the ``fixed`` variant) it is an ordinary DDPG agent with OU
exploration and a ring buffer.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from keras_rl.agents.explorers import AdditiveNoise, NoExploration, OUNoise
from keras_rl.agents.schedules import Bursts, EveryStep
from keras_rl.agents.skeleton import Agent
from keras_rl.agents.transitions import TransitionRule
from keras_rl.buffers import Layout, PoppingBuffer, ReplayBuffer
from keras_rl.config import ExperimentConfig, named_fields, non_negative, positive, unit, widths
from keras_rl.envs import EnvSpec, box_spec, make_env
from keras_rl.errors import ConfigError
from keras_rl.experiment import Experiment
from keras_rl.learners.protocol import ActorGradient
from keras_rl.metrics import GoalShare, ReturnSpread


@named_fields
@dataclass(frozen=True, kw_only=True)
class MountainCarDDPGConfig(ExperimentConfig):
    """Post 001's hyperparameters and quirk switches."""

    experiment: ClassVar[str] = "mountaincar"
    post: ClassVar[str] = "001_98f9c3d244106c52"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "faithful": {},
        "faithful-intended": {"actor_gradient": "dpg_intended"},
        "fixed": {
            "actor_gradient": "dpg_intended",
            "dqda_at_buffer_actions": False,
            "store_raw_next_state": False,
            "episode_returns_as_rewards": False,
            "done_includes_truncation": False,
            "popping_buffer": False,
            "exploration": "ou",
            "criterion": "goal",
            "threshold": 0.5,
        },
    }
    QUIRKS: ClassVar = {
        "learning_phase_training": ("P001-PHASE", True),
        "actor_gradient": ("P001-ACTORGRAD", "dpg_intended"),
        "dqda_at_buffer_actions": ("P001-DQDA", False),
        "store_raw_next_state": ("P001-NEXTSTATE", False),
        "episode_returns_as_rewards": ("P001-RETURNS", False),
        "done_includes_truncation": ("P001-DONE", False),
        "popping_buffer": ("P001-POP", False),
        "exploration": ("P001-NOEXPLORE", "ou"),
    }
    RENAMED: ClassVar = {
        "critic_hidden": lambda v: {"critic_hidden_units": (int(v), int(v))},
        "actor_hidden": lambda v: {"actor_hidden_units": v},
        "train_above": lambda v: {"train_start": v},
        "ou_sigma": lambda v: {"noise_sigma": v},
        "ou_theta": lambda v: {"noise_theta": v},
        "ou_dt": lambda v: {"noise_dt": v},
    }

    env_id: str = "MountainCarContinuous-v0"
    """``env = gym.make("MountainCarContinuous-v0")``: 999-step time limit."""
    critic_hidden_units: tuple[int, ...] = widths((32, 32))
    """Critic: BatchNormalization, ``Dense(32, selu)``, concat action, ``Dense(32, selu)``, ``Dense(1)``."""
    actor_hidden_units: tuple[int, ...] = widths((32, 32, 32))
    """Actor: ``GaussianNoise(1.0)``, BatchNormalization, 3 x ``Dense(32, selu)``, ``Dense(1, tanh)``."""
    actor_input_noise: float = non_negative(1.0)
    """``layers.GaussianNoise(1.0)`` on the actor's input (inactive at learning phase 0)."""
    critic_lr: float = positive(5e-4)
    """``optimizers.Adam(lr = 0.0005)`` in ``Critic.__build_loss_function``."""
    actor_lr: float = positive(5e-5)
    """``optimizers.Adam(lr=0.00005)`` in ``Actor.__make_loss_function``."""
    tau: float = unit(0.001)
    """``Agent(..., tau = 0.001, ...)``."""
    gamma: float = unit(0.999)
    """``Agent(..., gamma =0.999)``: the bootstrap discount."""
    return_discount: float = unit(0.999)
    """``_compute_discounted_R(R, discount_rate=.999)``: the per-episode returns."""
    batch_size: int = positive(32)
    """``ReplayBuffer(maxlen=20000, batch_size=32)``."""
    train_start: int = positive(1000)
    """``if len(agent.memory)> 1000: agent.train()``, checked every env step: with the popping
    buffer a burst starts once it holds *more than* this many (P001-TRIGGER); with the ring
    buffer (fixed) one update per env step from this many on."""
    train_down_to: int = non_negative(100)
    """``while (len(self.memory)) > 100:`` pop and train batch after batch."""
    buffer_size: int = positive(100_000)
    """Only for ``popping_buffer=False`` (the fixed variant's ring buffer)."""
    episodes: int = positive(100)
    """``for iterate in range(100):``."""
    criterion: Literal["converged", "goal"] = "converged"
    """``converged`` (faithful): the post claims only that it "roughly converged within 100
    trials", so success is the returns of the last ``converge_window`` episodes lying within
    ``threshold`` of each other after all episodes (derived in FIDELITY.md from 10+ seeds).
    ``goal`` (fixed): the share of the last ``goal_window`` episodes that reached the goal
    is at least ``threshold``."""
    converge_window: int = positive(10)
    """``criterion="converged"``: how many final episodes must agree."""
    goal_window: int = positive(50)
    """``criterion="goal"``: the window whose goal share is judged."""
    threshold: float = 2.0
    """``converged``: the largest allowed return spread; ``goal``: the least goal share."""
    stop_at_threshold: bool = False
    """The post runs all 100 iterations."""
    noise_sigma: float = non_negative(0.5)
    """``exploration="ou"`` only: rl-zoo3's OU noise sigma for DDPG on this task."""
    noise_theta: float = non_negative(0.15)
    """``exploration="ou"`` only: OU mean reversion (rl-zoo3's default)."""
    noise_dt: float = positive(1e-2)
    """``exploration="ou"`` only: OU time step (rl-zoo3's default)."""
    noise_mu: float = 0.0
    """``exploration="ou"`` only: OU mean."""

    # -- quirk switches; see reproductions/FIDELITY.md ---------------------------------
    learning_phase_training: bool = False
    """P001-PHASE: Keras 2's learning phase is never fed, so it stays 0: GaussianNoise off,
    BatchNormalization on its never-updated moving statistics (an affine layer with
    trainable gamma and beta). True would call every network in training mode."""
    actor_gradient: ActorGradient = "dpg_literal"
    """P001-ACTORGRAD: ``dpg_literal`` (what ``get_updates(loss=tf.gradients(...))`` computes:
    the gradient of the sum of the first-order gradients) or ``dpg_intended``."""
    dqda_at_buffer_actions: bool = True
    """P001-DQDA: ``get_gradient(states, actions)`` evaluates dQ/da at the *stored* actions,
    after the critic's update. False: at mu(s)."""
    store_raw_next_state: bool = True
    """P001-NEXTSTATE: the state is normalised to [0,1] but ``next_frame`` is stored raw."""
    episode_returns_as_rewards: bool = True
    """P001-RETURNS: transitions enter the buffer at episode end with their rewards replaced
    by the episode's standardised discounted returns. False: raw rewards, stored each step."""
    done_includes_truncation: bool = True
    """P001-DONE: the old 4-tuple ``done`` is true at the 999-step limit too."""
    popping_buffer: bool = True
    """P001-POP: shuffle-and-pop sampling that consumes the buffer, trained in bursts
    (P001-TRIGGER). False: a ring buffer and one update per env step."""
    exploration: Literal["none", "ou"] = "none"
    """P001-NOEXPLORE: the actor acts with no added noise (``none``); ``ou`` adds OU noise."""

    def uses_ring_buffer(self) -> bool:
        return not self.popping_buffer

    def validate(self) -> None:
        super().validate()
        if self.actor_gradient == "mean_q":
            raise ConfigError("post 001's actor_gradient is dpg_literal or dpg_intended, not mean_q")
        if self.train_down_to >= self.train_start:
            raise ConfigError("train_down_to must be below train_start")
        if self.popping_buffer and self.batch_size > self.train_down_to + 1:
            raise ConfigError(
                f"batch_size {self.batch_size} is larger than train_down_to + 1 = "
                f"{self.train_down_to + 1}: a burst pops batches while more than train_down_to "
                "transitions remain, so the last pop would come up short"
            )
        if self.actor_input_noise > 1:
            # Keras 3's GaussianNoise refuses a stddev above 1 when the actor is built: say so
            # before any seed starts, not once per seed at run time
            raise ConfigError(
                f"actor_input_noise must be at most 1 (Keras 3's GaussianNoise takes a stddev in [0, 1]), "
                f"got {self.actor_input_noise}"
            )
        if len(self.critic_hidden_units) != 2:
            raise ConfigError(
                "critic_hidden_units takes two widths (before and after the action joins), "
                f"got {self.critic_hidden_units}"
            )


def standardised_discounted_returns(rewards, discount: float = 0.999) -> np.ndarray:
    """Post 001 ``_compute_discounted_R``: discounted returns of one episode, then
    ``-= mean`` and ``/= std`` in float32, as the post computes them (P001-RETURNS)."""
    discounted = np.zeros(len(rewards), dtype=np.float32)
    running_add = 0.0
    for t in reversed(range(len(rewards))):
        running_add = running_add * discount + rewards[t]
        discounted[t] = running_add
    discounted -= discounted.mean()
    discounted /= discounted.std()
    return discounted


def assemble(config: MountainCarDDPGConfig, spec: EnvSpec, learner, action_space=None) -> Agent:
    """Post 001's ``Agent`` and main-loop body, from the shared parts."""
    c = config
    layout = Layout(spec.obs_dim, spec.action_dim)
    seeds = np.random.SeedSequence(c.seed).spawn(2)
    obs_low = np.asarray(spec.obs_low, np.float32)
    transitions = TransitionRule(
        layout,
        done_flag="either" if c.done_includes_truncation else "terminated",  # P001-DONE
        obs_low=obs_low,
        obs_span=np.asarray(spec.obs_high, np.float32) - obs_low,  # (s - low) / (high - low)
        store_raw_next_state=c.store_raw_next_state,  # P001-NEXTSTATE
        episode_rewards=(
            (lambda rewards: standardised_discounted_returns(rewards, c.return_discount))
            if c.episode_returns_as_rewards
            else None
        ),
    )  # P001-RETURNS
    buffer: PoppingBuffer | ReplayBuffer
    schedule: Bursts | EveryStep
    explorer: AdditiveNoise | NoExploration
    if c.popping_buffer:  # P001-POP, P001-TRIGGER
        capacity = c.train_start + (spec.max_episode_steps or 999) + 1  # the most it can ever hold
        buffer = PoppingBuffer(capacity, layout, random.Random(int(seeds[0].generate_state(1)[0])))
        schedule = Bursts(c.train_start, c.train_down_to, c.batch_size)
    else:
        buffer = ReplayBuffer(c.buffer_size, layout, np.random.default_rng(seeds[0]))
        schedule = EveryStep(c.train_start, c.batch_size, fuse_act=False)  # agent.get_action is its own predict
    if c.exploration == "ou":
        explorer = AdditiveNoise(
            OUNoise(
                spec.action_dim,
                np.random.default_rng(seeds[1]),
                theta=c.noise_theta,
                mu=c.noise_mu,
                dt=c.noise_dt,
                sigma=c.noise_sigma,
            ),
            1.0,
        )
    else:
        explorer = NoExploration()  # P001-NOEXPLORE
    return Agent(learner, buffer, transitions, schedule, explorer)


def _extras(rows: list[dict[str, Any]], config: MountainCarDDPGConfig) -> dict[str, Any]:
    last = rows[-config.goal_window :]
    return {
        "goal_hits_last_window": sum(r["score"] > 0 for r in last),
        "goal_hits_total": sum(r["score"] > 0 for r in rows),
        "first_goal_episode": next((r["episode"] for r in rows if r["score"] > 0), None),
        "last_window_mean_return": sum(r["score"] for r in last) / len(last) if last else None,
    }


EXPERIMENT = Experiment(
    name="mountaincar",
    config_cls=MountainCarDDPGConfig,
    make_env=lambda config, render_mode=None: make_env(config.env_id, render_mode=render_mode),
    env_spec=lambda env: box_spec(env, "DDPG (post 001)"),
    assemble=assemble,
    make_metric=lambda c: ReturnSpread(c.converge_window) if c.criterion == "converged" else GoalShare(c.goal_window),
    metric_label=lambda c: (
        f"spread of the last {c.converge_window} returns"
        if c.criterion == "converged"
        else f"share of the last {c.goal_window} episodes at the goal"
    ),
    description="post 001: DDPG on MountainCarContinuous-v0 from Keras 2 graph code; "
    "success = converged (faithful) or the goal in half the last 50 episodes (fixed)",
    summary_extras=_extras,
    post_reference='The post says it "roughly converged within 100 trials" and gives no number.',
    success_at_end=True,
    metric_in_score_units=False,
)
