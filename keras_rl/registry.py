"""The one registry: experiment name -> ``Experiment`` (config, env, agent, metric), and
``build_agent``, which puts a post's parts around the learner ``learners/table.py`` picks."""

from __future__ import annotations

from typing import Any

from keras_rl.errors import ConfigError
from keras_rl.experiment import Experiment
from keras_rl.learners.table import implementation
from keras_rl.posts import cartpole, mountaincar, pendulum

EXPERIMENTS: dict[str, Experiment] = {p.EXPERIMENT.name: p.EXPERIMENT for p in (pendulum, cartpole, mountaincar)}


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(
            f"unknown experiment {name!r}; choose one of {', '.join(sorted(EXPERIMENTS))}") from None


def build_agent(experiment: Experiment, config, env, **learner_options: Any):
    """The agent for ``config`` on ``env``: the table's learner inside the post's parts (or,
    for a ``whole_agent`` entry, the agent the table's factory builds)."""
    spec = experiment.env_spec(env)
    impl = implementation(experiment.name, config.framework)
    factory = impl.load()
    if impl.whole_agent:
        return factory(config, spec, env.action_space)
    return experiment.assemble(config, spec, factory(config, spec, **learner_options), env.action_space)
