"""Environment construction with checks that name the problem."""

from __future__ import annotations

import gymnasium as gym

from keras_rl.errors import ConfigError, EnvironmentMismatchError


def make_env(env_id: str, render_mode: str | None = None, **kwargs) -> gym.Env:
    """``gym.make`` with a clear error for an unknown id or bad keyword arguments."""
    try:
        return gym.make(env_id, render_mode=render_mode, **kwargs)
    except gym.error.Error as exc:  # NameNotFound, VersionNotFound, ...
        raise ConfigError(f"unknown environment {env_id!r}: {exc}") from None
    except TypeError as exc:
        raise ConfigError(f"environment {env_id!r} rejected its arguments {kwargs}: {exc}") from None


def require_box_actions(env: gym.Env, algorithm: str) -> tuple[int, int, float]:
    """(obs_dim, action_dim, action_bound) of a flat Box env, or an error saying why not."""
    space = env.action_space
    env_id = env.spec.id if env.spec else type(env.unwrapped).__name__
    if not isinstance(space, gym.spaces.Box):
        raise EnvironmentMismatchError(
            f"{algorithm} needs a continuous Box action space, but {env_id} has {space}")
    if len(space.shape) != 1 or len(env.observation_space.shape) != 1:
        raise EnvironmentMismatchError(
            f"{algorithm} needs flat observations and actions; {env_id} has observation shape "
            f"{env.observation_space.shape} and action shape {space.shape}")
    if not (space.high == -space.low).all():
        raise EnvironmentMismatchError(
            f"{algorithm} scales tanh by one symmetric bound; {env_id}'s action bounds are "
            f"{space.low}..{space.high}")
    return env.observation_space.shape[0], space.shape[0], float(space.high[0])


def require_discrete_actions(env: gym.Env, algorithm: str) -> tuple[int, int]:
    """(obs_dim, n_actions) of a flat-observation Discrete env, or an error saying why not."""
    env_id = env.spec.id if env.spec else type(env.unwrapped).__name__
    if not isinstance(env.action_space, gym.spaces.Discrete):
        raise EnvironmentMismatchError(
            f"{algorithm} needs a Discrete action space, but {env_id} has {env.action_space}")
    if len(env.observation_space.shape) != 1:
        raise EnvironmentMismatchError(f"{algorithm} needs flat observations; {env_id} has "
                                       f"shape {env.observation_space.shape}")
    return env.observation_space.shape[0], int(env.action_space.n)
