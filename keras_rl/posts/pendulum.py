"""Post 000: DDPG on Gymnasium ``Pendulum-v1`` (g=10), TF2 Keras, GradientTape updates.

Section numbers refer to ``../shared/seeds/000_97338310014de2ac.txt``. The quirks
(FIDELITY P000-*) are the switches at the end of the config; ``assemble`` turns them into
the agent's parts, and the learner (``learners/ddpg.py``, ``torch/ddpg.py``) takes the
rest (the (B,B) broadcast target, the no-op target copy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from keras_rl.agents.explorers import AdditiveNoise, OUNoise
from keras_rl.agents.schedules import EveryStep
from keras_rl.agents.skeleton import Agent
from keras_rl.agents.transitions import TransitionRule
from keras_rl.buffers import Layout, ReplayBuffer
from keras_rl.config import ExperimentConfig, fraction, named_fields, non_negative, positive, unit, widths
from keras_rl.envs import EnvSpec, box_spec, make_env
from keras_rl.experiment import Experiment
from keras_rl.metrics import PostEMA


@named_fields
@dataclass(frozen=True, kw_only=True)
class PendulumDDPGConfig(ExperimentConfig):
    """Post 000's hyperparameters and quirk switches."""

    experiment: ClassVar[str] = "pendulum"
    post: ClassVar[str] = "000_97338310014de2ac"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "faithful": {},
        "fixed": {
            "noise_restarts_from_zero": False,
            "done_from_truncated": False,
            "broadcast_target": False,
            "target_copy_is_noop": False,
        },
    }
    QUIRKS: ClassVar = {
        "noise_restarts_from_zero": ("P000-NOISE", False),
        "done_from_truncated": ("P000-DONE", False),
        "broadcast_target": ("P000-BROADCAST", False),
        "target_copy_is_noop": ("P000-TARGETINIT", False),
    }
    RENAMED: ClassVar = {"hidden_units": lambda v: {"actor_hidden_units": v, "critic_hidden_units": v}}

    # -- environment (§2.4 Main) --------------------------------------------------------
    env_id: str = "Pendulum-v1"
    """§2.4: ``gym.make('Pendulum-v1', g = 10)``."""
    gravity: float = positive(10.0)
    """§2.4: ``g = 10`` (Gymnasium's default is 10.0 too)."""

    # -- networks (§2.2) ----------------------------------------------------------------
    actor_hidden_units: tuple[int, ...] = widths((64, 64))
    """§2.2: the Actor's ``Dense(64, relu)`` twice."""
    critic_hidden_units: tuple[int, ...] = widths((64, 64))
    """§2.2: the Critic's ``Dense(64, relu)`` twice, on concat(state, action)."""

    # -- hyperparameters (§2.3.1) -------------------------------------------------------
    actor_lr: float = positive(1e-3)
    """§2.3.1: ``self.actor_optimizer = Adam(learning_rate=0.001)``."""
    critic_lr: float = positive(1e-3)
    """§2.3.1: ``self.critic_optimizer = Adam(learning_rate=0.001)``."""
    gamma: float = unit(0.99)
    """§2.3.1: ``self.gamma = 0.99``."""
    tau: float = unit(0.001)
    """§2.3.1: ``self.tau = 0.001``; used by ``update_target_networks`` after every update."""
    buffer_size: int = positive(2000)
    """§2.3.1: ``self.memory = deque(maxlen=2000)``: FIFO eviction at capacity."""
    batch_size: int = positive(64)
    """§2.3.1: ``self.batch_size = 64``; ``random.sample`` draws without replacement (§2.3.3)."""
    train_start: int = positive(1000)
    """§2.3.1/§2.4: train when ``len(agent.memory) >= agent.train_start`` (1000)."""
    train_every: int = positive(1)
    """§2.4: ``train_model()`` runs once per env step once the buffer holds train_start."""

    # -- exploration (§2.3.2) -----------------------------------------------------------
    noise_theta: float = non_negative(0.15)
    """§2.3.2: ``ou_noise(..., rho=0.15, ...)``: mean reversion rate."""
    noise_mu: float = 0.0
    """§2.3.2: ``mu=0``."""
    noise_dt: float = positive(0.1)
    """§2.3.2: ``dt=1e-1``."""
    noise_sigma: float = non_negative(0.2)
    """§2.3.2: ``sigma=0.2``; each step adds ``sigma*sqrt(dt)*N(0,1)``."""
    action_clip: float = positive(2.0)
    """§2.4: ``np.clip(action + noise, -2, 2)``; the stored action is this clipped one."""

    # -- run protocol (§2.4) ------------------------------------------------------------
    episodes: int = positive(1000)
    """§2.4: ``num_episode = 1000``: the post's own budget."""
    threshold: float = -300.0
    """§2.4: ``if score_avg > -300``: success is the EMA strictly above -300."""
    ema_decay: float = fraction(0.9)
    """§2.4: ``score_avg = 0.9 * score_avg + 0.1 * score if score_avg != 0 else score``."""
    stop_at_threshold: bool = True
    """§2.4: the run saves the actor and ``sys.exit()``s at the first EMA above -300."""

    # -- quirk switches: faithful defaults; see reproductions/FIDELITY.md ----------------
    noise_restarts_from_zero: bool = True
    """P000-NOISE. §2.4: ``pre_noise = np.zeros(...)`` at every episode start and never
    updated inside the episode, so each step's noise starts from zero: i.i.d. Gaussian
    with sigma ``0.2*sqrt(0.1)``. False: a real OU process carried across steps."""
    done_from_truncated: bool = True
    """P000-DONE. §2.4: ``next_state, reward, _, done, _ = env.step(...)`` keeps
    ``truncated`` and drops ``terminated``: the time-limit step is stored as terminal.
    False: only ``terminated`` is terminal, so truncation bootstraps."""
    broadcast_target: bool = True
    """P000-BROADCAST. §2.3.3: rewards (B,1) + gamma * Q' (B,1) * (1 - dones) (B,) gives
    a (B,B) target and the critic loss averages over that matrix. False: (B,1) targets."""
    target_copy_is_noop: bool = True
    """P000-TARGETINIT. §2.4: ``agent.update_target_networks(1.0)`` runs before any model
    is built; ``get_weights()`` of an unbuilt subclassed model is ``[]``, so the copy does
    nothing and the targets start from their own random init. False: a real hard copy."""


def make_pendulum_env(config: PendulumDDPGConfig, render_mode: str | None = None) -> gym.Env:
    kwargs = {"g": config.gravity} if config.env_id.startswith("Pendulum") else {}
    return make_env(config.env_id, render_mode=render_mode, **kwargs)


def assemble(config: PendulumDDPGConfig, spec: EnvSpec, learner, action_space=None) -> Agent:
    """Post 000's agent: OU noise added and clipped, a FIFO buffer, one update per env step."""
    c = config
    layout = Layout(spec.obs_dim, spec.action_dim)
    buffer_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(c.seed).spawn(2))
    noise = OUNoise(
        spec.action_dim,
        noise_rng,
        theta=c.noise_theta,
        mu=c.noise_mu,
        dt=c.noise_dt,
        sigma=c.noise_sigma,
        carry_state=not c.noise_restarts_from_zero,
    )  # P000-NOISE
    return Agent(
        learner,
        ReplayBuffer(c.buffer_size, layout, buffer_rng),
        TransitionRule(layout, done_flag="truncated" if c.done_from_truncated else "terminated"),  # P000-DONE
        EveryStep(c.train_start, c.batch_size, c.train_every, fuse_act=True),
        AdditiveNoise(noise, c.action_clip),
    )


EXPERIMENT = Experiment(
    name="pendulum",
    config_cls=PendulumDDPGConfig,
    make_env=make_pendulum_env,
    env_spec=lambda env: box_spec(env, "DDPG (post 000)"),
    assemble=assemble,
    make_metric=lambda c: PostEMA(c.ema_decay),
    metric_label=lambda c: "EMA 0.9 (post's score_avg)",
    description="post 000: DDPG on Pendulum-v1 (g=10), success = EMA > -300",
    post_reference="The post reports the EMA passing -300 after 153 episodes (one run).",
)
