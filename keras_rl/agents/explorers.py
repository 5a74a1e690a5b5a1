"""Explorers: how the policy's action becomes the action played.

Each has ``reset()`` (called at every episode start) and ``__call__(action) -> action``.
The noise process itself (``OUNoise``) has the SB3 ActionNoise shape: ``__call__`` and
``reset``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from keras_rl.rngs import rng_state, set_rng_state


class OUNoise:
    """Ornstein-Uhlenbeck noise, discretised as in post 000 §2.3.2::

        x' = x + theta * (mu - x) * dt + sigma * sqrt(dt) * N(0, 1)

    ``carry_state=True`` is a real OU process: each call starts from the previous
    output, and ``reset`` (at each episode start) returns the state to zero.

    ``carry_state=False`` is what post 000's loop actually computes (quirk
    P000-NOISE): ``pre_noise`` is zeroed at each episode start and never assigned
    inside the episode, so every call starts from zero and the noise is i.i.d.
    ``N(theta*mu*dt, (sigma*sqrt(dt))^2)``.
    """

    def __init__(
        self,
        dim: int,
        rng: np.random.Generator,
        theta: float = 0.15,
        mu: float = 0.0,
        dt: float = 0.1,
        sigma: float = 0.2,
        carry_state: bool = True,
    ):
        self.dim = int(dim)
        self.rng = rng
        self.theta, self.mu, self.dt, self.sigma = float(theta), float(mu), float(dt), float(sigma)
        self.carry_state = carry_state
        self.state = np.zeros(self.dim)

    def reset(self) -> None:
        self.state = np.zeros(self.dim)

    def state_dict(self) -> dict[str, Any]:
        return {"state": self.state.copy(), "rng": rng_state(self.rng)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.state = np.array(state["state"])
        set_rng_state(self.rng, state["rng"])

    def __call__(self) -> np.ndarray:
        x = self.state
        out = x + self.theta * (self.mu - x) * self.dt + self.sigma * np.sqrt(self.dt) * self.rng.normal(size=self.dim)
        if self.carry_state:
            self.state = out
        return out


class NoExploration:
    """Play the policy's action as it is (post 001's P001-NOEXPLORE; greedy evaluation)."""

    def reset(self) -> None:
        pass

    def __call__(self, action: Any) -> Any:
        return action

    def state_dict(self) -> dict[str, Any]:
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        pass


class AdditiveNoise:
    """``np.clip(action + noise, -bound, bound)``: the posts add float64 noise to a float32
    action, which TensorFlow (post 000's tensor + ndarray) casts to float32 first."""

    def __init__(self, noise: OUNoise, bound: float):
        self.noise, self.bound = noise, float(bound)

    def reset(self) -> None:
        self.noise.reset()

    def state_dict(self) -> dict[str, Any]:
        return self.noise.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.noise.load_state_dict(state)

    def __call__(self, action: np.ndarray) -> np.ndarray:
        return np.clip(action + self.noise().astype(np.float32), -self.bound, self.bound)


def decaying_epsilon(eps_start: float, eps_end: float, eps_decay: float) -> Callable[[int], float]:
    """Post 003 In [31]: ``EPS_END + (EPS_START - EPS_END) * exp(-1. * steps_done / EPS_DECAY)``.

    ``steps_done`` counts env steps over the whole run (it is incremented on every
    ``select_action``), so epsilon decays per step, not per episode.
    """
    return lambda steps_done: eps_end + (eps_start - eps_end) * math.exp(-1.0 * steps_done / eps_decay)


class EpsilonGreedy:
    """Post 003 In [31] ``select_action``: one uniform draw per step; below epsilon, a
    random action from ``action_space.sample()``; otherwise the greedy one."""

    def __init__(self, epsilon: Callable[[int], float], rng: np.random.Generator, action_space):
        self.epsilon, self.rng, self.action_space = epsilon, rng, action_space
        self.steps_done = 0

    def reset(self) -> None:
        pass  # steps_done runs over the whole training run

    def state_dict(self) -> dict[str, Any]:
        # action_space.sample()'s generator is the env's: the run's checkpoint saves it
        return {"steps_done": self.steps_done, "rng": rng_state(self.rng)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.steps_done = int(state["steps_done"])
        set_rng_state(self.rng, state["rng"])

    def __call__(self, greedy_action: int) -> int:
        sample = self.rng.random()
        threshold = self.epsilon(self.steps_done)
        self.steps_done += 1
        return greedy_action if sample > threshold else int(self.action_space.sample())
