"""Environment construction, and what an agent needs to know of an env (``EnvSpec``)."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from keras_rl.errors import ConfigError, EnvironmentMismatchError


@dataclass(frozen=True)
class EnvSpec:
    """The sizes and bounds a learner and an agent are built for."""

    obs_dim: int
    action_dim: int
    """Columns an action takes in a stored transition (1 for a discrete action)."""
    action_bound: float = 1.0
    """Box actions: the symmetric bound ``high`` (tanh is scaled by it)."""
    n_actions: int | None = None
    """Discrete actions: how many."""
    obs_low: np.ndarray | None = None
    obs_high: np.ndarray | None = None
    max_episode_steps: int | None = None


def make_env(env_id: str, render_mode: str | None = None, **kwargs) -> gym.Env:
    """``gym.make`` with a clear error for an unknown id or bad keyword arguments."""
    try:
        return gym.make(env_id, render_mode=render_mode, **kwargs)
    except gym.error.Error as exc:  # NameNotFound, VersionNotFound, ...
        raise ConfigError(f"unknown environment {env_id!r}: {exc}") from None
    except TypeError as exc:
        raise ConfigError(f"environment {env_id!r} rejected its arguments {kwargs}: {exc}") from None


def check_env_id(env_id: str) -> None:
    """A ConfigError naming an environment Gymnasium does not know, without making it (so a study
    refuses it before anything is written)."""
    try:
        gym.spec(env_id)
    except gym.error.Error as exc:
        raise ConfigError(f"unknown environment {env_id!r}: {exc}") from None


def _env_id(env: gym.Env) -> str:
    return env.spec.id if env.spec else type(env.unwrapped).__name__


def box_spec(env: gym.Env, algorithm: str) -> EnvSpec:
    """The spec of a flat Box env, or an error saying why it does not fit ``algorithm``."""
    space = env.action_space
    env_id = _env_id(env)
    if not isinstance(space, gym.spaces.Box):
        raise EnvironmentMismatchError(f"{algorithm} needs a continuous Box action space, but {env_id} has {space}")
    observations = env.observation_space
    if not isinstance(observations, gym.spaces.Box):
        raise EnvironmentMismatchError(f"{algorithm} needs Box observations, but {env_id} has {observations}")
    if len(space.shape) != 1 or len(observations.shape) != 1:
        raise EnvironmentMismatchError(
            f"{algorithm} needs flat observations and actions; {env_id} has observation shape "
            f"{env.observation_space.shape} and action shape {space.shape}"
        )
    if not (space.high == -space.low).all():
        raise EnvironmentMismatchError(
            f"{algorithm} scales tanh by one symmetric bound; {env_id}'s action bounds are {space.low}..{space.high}"
        )
    return EnvSpec(
        observations.shape[0],
        space.shape[0],
        float(space.high[0]),
        obs_low=observations.low,
        obs_high=observations.high,
        max_episode_steps=env.spec.max_episode_steps if env.spec else None,
    )


def discrete_spec(env: gym.Env, algorithm: str) -> EnvSpec:
    """The spec of a flat-observation Discrete env, or an error saying why it does not fit."""
    env_id = _env_id(env)
    if not isinstance(env.action_space, gym.spaces.Discrete):
        raise EnvironmentMismatchError(
            f"{algorithm} needs a Discrete action space, but {env_id} has {env.action_space}"
        )
    shape = env.observation_space.shape
    if shape is None or len(shape) != 1:
        raise EnvironmentMismatchError(f"{algorithm} needs flat observations; {env_id} has shape {shape}")
    return EnvSpec(
        shape[0],
        1,
        n_actions=int(env.action_space.n),
        max_episode_steps=env.spec.max_episode_steps if env.spec else None,
    )
