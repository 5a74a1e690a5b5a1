"""What a post contributes to the registry: its config, env, agent and metric, in one record."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from keras_rl.config import ExperimentConfig
from keras_rl.envs import EnvSpec


@dataclass(frozen=True)
class Experiment:
    name: str
    config_cls: type[ExperimentConfig]
    make_env: Callable[..., gym.Env]
    """``make_env(config, render_mode=None)``."""
    env_spec: Callable[[gym.Env], EnvSpec]
    """The sizes and bounds of ``env``, or an error if the algorithm cannot run on it."""
    assemble: Callable[..., Any]
    """``assemble(config, spec, learner, action_space)`` -> an ``agents.skeleton.Agent``: the
    post's buffer, transition rule, schedule and explorer around a learner."""
    make_metric: Callable[[Any], Any]
    """``make_metric(config)`` -> a ``metrics.Metric``."""
    metric_label: Callable[[Any], str]
    """The metric's name in plots and tables, given the config."""
    description: str
    summary_extras: Callable[[list[dict[str, Any]], Any], dict[str, Any]] = lambda rows, config: {}
    """Experiment-specific numbers for ``summary.json``."""
    post_reference: str = ""
    """What the post itself reports, for ``summary.md``."""
    success_at_end: bool = False
    """Judge success on the final metric (post 001) rather than on a first crossing."""
    metric_in_score_units: bool = True
    """False when the metric is not on the score's scale (plots give it its own axis)."""
