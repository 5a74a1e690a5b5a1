"""The registry: an experiment is a config class plus how to build its env, agent and metric."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import gymnasium as gym

from keras_rl.configs import ExperimentConfig, PendulumDDPGConfig
from keras_rl.errors import ConfigError
from keras_rl.envs import make_env, require_box_actions
from keras_rl.metrics import PostEMA


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


def _pendulum_env(config: PendulumDDPGConfig, render_mode: str | None = None) -> gym.Env:
    kwargs = {"g": config.gravity} if config.env_id.startswith("Pendulum") else {}
    return make_env(config.env_id, render_mode=render_mode, **kwargs)


def _pendulum_agent(config: PendulumDDPGConfig, env: gym.Env):
    from keras_rl.ddpg import DDPGAgent

    obs_dim, action_dim, bound = require_box_actions(env, "DDPG (post 000)")
    return DDPGAgent(config, obs_dim, action_dim, bound)


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
    ),
}


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(
            f"unknown experiment {name!r}; choose one of {', '.join(sorted(EXPERIMENTS))}") from None
