"""The one registry: experiment name -> ``Experiment`` (config, env, agent, metric), and
``build_agent``, which puts a post's parts around the learner ``learners/table.py`` picks."""

from __future__ import annotations

from typing import Any

from keras_rl.envs import EnvSpec
from keras_rl.errors import ConfigError
from keras_rl.experiment import Experiment
from keras_rl.learners.table import implementation
from keras_rl.posts import cartpole, mountaincar, pendulum

EXPERIMENTS: dict[str, Experiment] = {p.EXPERIMENT.name: p.EXPERIMENT for p in (pendulum, cartpole, mountaincar)}


def register(experiment: Experiment, learners: dict[str, str]) -> None:
    """Add a post from outside the package, in one call: its ``Experiment`` (config, env, agent
    parts, metric) and, per framework, its learner factory as ``"module:callable"`` (called as
    ``factory(config, spec)``, returning a ``learners/protocol.Learner``). Nothing under
    ``keras_rl/`` changes; ``reproduce``, ``--resume``, ``aggregate`` and ``evaluate`` run it
    (``tests/test_fourth_post.py`` registers a toy post and runs them end to end)."""
    from keras_rl.learners.table import IMPLEMENTATIONS, Implementation

    if experiment.name in EXPERIMENTS:
        raise ConfigError(f"an experiment named {experiment.name!r} is registered already")
    if not learners:
        raise ConfigError(f"{experiment.name}: register at least one framework's learner")
    EXPERIMENTS[experiment.name] = experiment
    for framework, path in learners.items():
        IMPLEMENTATIONS[(experiment.name, framework)] = Implementation(path)


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(f"unknown experiment {name!r}; choose one of {', '.join(sorted(EXPERIMENTS))}") from None


def build_agent(experiment: Experiment, config, env, **learner_options: Any):
    """The agent for ``config`` on ``env`` (see ``agent_for``)."""
    return agent_for(config, experiment.env_spec(env), env.action_space, **learner_options)


def agent_for(config, spec: EnvSpec, action_space=None, **learner_options: Any):
    """The table's learner (``learners/table.py``) inside the post's parts (``assemble``), or,
    for a ``whole_agent`` entry, the agent the table's factory builds. ``learner_options``
    go to a learner factory (the Keras ones take ``xla``)."""
    experiment = get_experiment(config.experiment)
    impl = implementation(experiment.name, config.framework)
    factory = impl.load()
    if impl.whole_agent:
        return factory(config, spec, action_space)
    return experiment.assemble(config, spec, factory(config, spec, **learner_options), action_space)
