"""The registry: an experiment is a config class plus how to build its env, agent and metric."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import gymnasium as gym

from keras_rl.configs import CartPoleDQNConfig, ExperimentConfig, MountainCarDDPGConfig, PendulumDDPGConfig
from keras_rl.errors import ConfigError
from keras_rl.envs import make_env, require_box_actions, require_discrete_actions
from keras_rl.metrics import GoalShare, PostEMA, ReturnSpread, RollingMean


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
    metric_label: str | Callable[[Any], str]
    """The metric's name in plots and tables; a function of the config where it depends on it."""
    description: str
    summary_extras: Callable[[list[dict[str, Any]], Any], dict[str, Any]] = lambda rows, config: {}
    """Experiment-specific numbers for ``summary.json``."""
    post_reference: str = ""
    """What the post itself reports, for ``summary.md``."""
    success_at_end: bool = False
    """Judge success on the final metric (post 001) rather than on a first crossing."""
    metric_in_score_units: bool = True
    """False when the metric is not on the score's scale (plots give it its own axis)."""


def _pendulum_env(config: PendulumDDPGConfig, render_mode: str | None = None) -> gym.Env:
    kwargs = {"g": config.gravity} if config.env_id.startswith("Pendulum") else {}
    return make_env(config.env_id, render_mode=render_mode, **kwargs)


def _pendulum_agent(config: PendulumDDPGConfig, env: gym.Env):
    from keras_rl.ddpg import DDPGAgent

    obs_dim, action_dim, bound = require_box_actions(env, "DDPG (post 000)")
    return DDPGAgent(config, obs_dim, action_dim, bound)


def _plain_env(config: ExperimentConfig, render_mode: str | None = None) -> gym.Env:
    """``gym.make(config.env_id)`` with the env's defaults (posts 001 and 003)."""
    return make_env(config.env_id, render_mode=render_mode)


def _cartpole_agent(config: CartPoleDQNConfig, env: gym.Env):
    obs_dim, n_actions = require_discrete_actions(env, "DQN (post 003)")
    if config.framework == "torch":
        from keras_rl.torch import single_threaded

        single_threaded()
        from keras_rl.torch.dqn_tutorial import TutorialDQNAgent

        return TutorialDQNAgent(config, obs_dim, n_actions, env.action_space)
    from keras_rl.dqn import DQNAgent

    return DQNAgent(config, obs_dim, n_actions, env.action_space)


def _cartpole_extras(rows: list[dict[str, Any]], config: CartPoleDQNConfig) -> dict[str, Any]:
    last = [r["score"] for r in rows[-config.mean_window:]]
    return {"last_100_mean": sum(last) / len(last) if last else None,
            "last_100_share_at_500": sum(s >= 500 for s in last) / len(last) if last else None}


def _mountaincar_agent(config: MountainCarDDPGConfig, env: gym.Env):
    from keras_rl.episodic_ddpg import EpisodicDDPGAgent

    _, action_dim, _ = require_box_actions(env, "DDPG (post 001)")
    max_steps = env.spec.max_episode_steps if env.spec and env.spec.max_episode_steps else 999
    return EpisodicDDPGAgent(config, env.observation_space.low, env.observation_space.high, action_dim, max_steps)


def _mountaincar_extras(rows: list[dict[str, Any]], config: MountainCarDDPGConfig) -> dict[str, Any]:
    last = rows[-config.goal_window:]
    return {"goal_hits_last_window": sum(r["score"] > 0 for r in last),
            "goal_hits_total": sum(r["score"] > 0 for r in rows),
            "first_goal_episode": next((r["episode"] for r in rows if r["score"] > 0), None),
            "last_window_mean_return": sum(r["score"] for r in last) / len(last) if last else None}


EXPERIMENTS: dict[str, Experiment] = {
    "pendulum": Experiment(
        name="pendulum",
        config_cls=PendulumDDPGConfig,
        make_env=_pendulum_env,
        make_agent=_pendulum_agent,
        make_metric=lambda c: PostEMA(c.ema_decay),
        metric_label="EMA 0.9 (post's score_avg)",
        description="post 000: DDPG on Pendulum-v1 (g=10), success = EMA > -300",
        post_reference="The post reports the EMA passing -300 after 153 episodes (one run).",
    ),
    "cartpole": Experiment(
        name="cartpole",
        config_cls=CartPoleDQNConfig,
        make_env=_plain_env,
        make_agent=_cartpole_agent,
        make_metric=lambda c: RollingMean(c.mean_window),
        metric_label="100-episode mean duration",
        description="post 003: the PyTorch DQN tutorial on CartPole-v1 (keras or torch), "
                    "success = 100-episode mean >= 475 within 600 episodes",
        summary_extras=_cartpole_extras,
        post_reference=("The tutorial claims the model \"constantly achieves 500 steps within 600 training "
                        "episodes\"; CartPole-v1's reward threshold is 475."),
    ),
    "mountaincar": Experiment(
        name="mountaincar",
        config_cls=MountainCarDDPGConfig,
        make_env=_plain_env,
        make_agent=_mountaincar_agent,
        make_metric=lambda c: (ReturnSpread(c.converge_window) if c.criterion == "converged"
                               else GoalShare(c.goal_window)),
        metric_label=lambda c: (f"spread of the last {c.converge_window} returns" if c.criterion == "converged"
                                else f"share of the last {c.goal_window} episodes at the goal"),
        description="post 001: DDPG on MountainCarContinuous-v0 from Keras 2 graph code; "
                    "success = converged (faithful) or the goal in half the last 50 episodes (fixed)",
        summary_extras=_mountaincar_extras,
        post_reference="The post says it \"roughly converged within 100 trials\" and gives no number.",
        success_at_end=True,
        metric_in_score_units=False,
    ),
}


def metric_label(experiment: Experiment, config) -> str:
    label = experiment.metric_label
    return label(config) if callable(label) else label


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(
            f"unknown experiment {name!r}; choose one of {', '.join(sorted(EXPERIMENTS))}") from None
