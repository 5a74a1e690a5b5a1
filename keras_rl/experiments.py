"""The registry: an experiment is a config class plus how to build its env, agent and metric."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import gymnasium as gym

from keras_rl.configs import CartPoleDQNConfig, ExperimentConfig, PendulumDDPGConfig
from keras_rl.errors import ConfigError
from keras_rl.envs import make_env, require_box_actions, require_discrete_actions
from keras_rl.metrics import PostEMA, RollingMean


@dataclass(frozen=True)
class Experiment:
    name: str
    config_cls: type[ExperimentConfig]
    make_env: Callable[..., gym.Env]
    """``make_env(config, render_mode=None)``."""
    make_agent: Callable[[Any, gym.Env], Any]
    """``make_agent(config, env)`` -> an agent with begin_episode/step/greedy_action/networks."""
    make_metric: Callable[[Any], Any]
    """``make_metric(config)`` -> an object with ``update(score) -> value``."""
    metric_label: str
    threshold_inclusive: bool
    """Success is ``metric >= threshold`` when True, ``metric > threshold`` when False."""
    description: str
    summary_extras: Callable[[list[dict[str, Any]], Any], dict[str, Any]] = lambda rows, config: {}
    """Experiment-specific numbers for ``summary.json``."""
    post_reference: str = ""
    """What the post itself reports, for ``summary.md``."""


def _pendulum_env(config: PendulumDDPGConfig, render_mode: str | None = None) -> gym.Env:
    kwargs = {"g": config.gravity} if config.env_id.startswith("Pendulum") else {}
    return make_env(config.env_id, render_mode=render_mode, **kwargs)


def _pendulum_agent(config: PendulumDDPGConfig, env: gym.Env):
    from keras_rl.ddpg import DDPGAgent

    obs_dim, action_dim, bound = require_box_actions(env, "DDPG (post 000)")
    return DDPGAgent(config, obs_dim, action_dim, bound)


def _cartpole_env(config: CartPoleDQNConfig, render_mode: str | None = None) -> gym.Env:
    return make_env(config.env_id, render_mode=render_mode)


def _cartpole_agent(config: CartPoleDQNConfig, env: gym.Env):
    obs_dim, n_actions = require_discrete_actions(env, "DQN (post 003)")
    if config.framework == "torch":
        from keras_rl.torch import require_torch

        require_torch().set_num_threads(1)
        from keras_rl.torch.dqn_tutorial import TutorialDQNAgent

        return TutorialDQNAgent(config, obs_dim, n_actions, env.action_space)
    from keras_rl.dqn import DQNAgent

    return DQNAgent(config, obs_dim, n_actions, env.action_space)


def _cartpole_extras(rows: list[dict[str, Any]], config: CartPoleDQNConfig) -> dict[str, Any]:
    last = [r["score"] for r in rows[-config.mean_window:]]
    return {"last_100_mean": sum(last) / len(last) if last else None,
            "last_100_share_at_500": sum(s >= 500 for s in last) / len(last) if last else None}


EXPERIMENTS: dict[str, Experiment] = {
    "pendulum": Experiment(
        name="pendulum",
        config_cls=PendulumDDPGConfig,
        make_env=_pendulum_env,
        make_agent=_pendulum_agent,
        make_metric=lambda c: PostEMA(c.ema_decay),
        metric_label="EMA 0.9 (post's score_avg)",
        threshold_inclusive=False,
        description="post 000: DDPG on Pendulum-v1 (g=10), success = EMA > -300",
        post_reference="The post reports the EMA passing -300 after 153 episodes (one run).",
    ),
    "cartpole": Experiment(
        name="cartpole",
        config_cls=CartPoleDQNConfig,
        make_env=_cartpole_env,
        make_agent=_cartpole_agent,
        make_metric=lambda c: RollingMean(c.mean_window),
        metric_label="100-episode mean duration",
        threshold_inclusive=True,
        description="post 003: the PyTorch DQN tutorial on CartPole-v1 (keras or torch), "
                    "success = 100-episode mean >= 475 within 600 episodes",
        summary_extras=_cartpole_extras,
        post_reference=("The tutorial claims the model \"constantly achieves 500 steps within 600 training "
                        "episodes\"; CartPole-v1's reward threshold is 475."),
    ),
}


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(
            f"unknown experiment {name!r}; choose one of {', '.join(sorted(EXPERIMENTS))}") from None
