"""Exploration noise objects with ``__call__`` and ``reset`` (the SB3 ActionNoise shape)."""

from __future__ import annotations

import numpy as np


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

    def __init__(self, dim: int, rng: np.random.Generator, theta: float = 0.15, mu: float = 0.0,
                 dt: float = 0.1, sigma: float = 0.2, carry_state: bool = True):
        self.dim = int(dim)
        self.rng = rng
        self.theta, self.mu, self.dt, self.sigma = float(theta), float(mu), float(dt), float(sigma)
        self.carry_state = carry_state
        self.state = np.zeros(self.dim)

    def reset(self) -> None:
        self.state = np.zeros(self.dim)

    def __call__(self) -> np.ndarray:
        x = self.state
        out = x + self.theta * (self.mu - x) * self.dt + self.sigma * np.sqrt(self.dt) * self.rng.normal(size=self.dim)
        if self.carry_state:
            self.state = out
        return out
