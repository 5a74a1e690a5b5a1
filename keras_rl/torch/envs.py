"""The posts' envs as PyTorch tensor functions, for an engine that steps many seeds at once
(issue 53): each a pure function of its state, ``step(state, action) -> (state, observation,
reward, terminated)``, elementwise over any leading axes (a seed axis, say), on whatever device
the tensors are on. The state is what Gymnasium's env keeps (``env.unwrapped.state``), float64;
the observation is the float32 array Gymnasium returns. Reset states are not drawn here: an
engine takes them from each seed's own Gymnasium generator, so both engines start every episode
alike (as ``keras_rl/tf_envs.py`` does for TensorFlow, whose CartPole this follows operation
for operation). Time limits are the engine's to count (``MAX_STEPS``).

``tests/test_torch_envs.py`` measures the agreement with the installed Gymnasium on the CPU: the
state, observation, reward and flag are bit for bit (PyTorch's float64 ``sin``/``cos`` round as
the C library's ``math.sin``/``math.cos`` do there). A GPU's ``sin``/``cos`` need not; its
agreement is to be measured where one is lent (issue 53).
"""

from __future__ import annotations

import math

import torch

MAX_STEPS = {"CartPole-v1": 500}
"""Gymnasium's registered ``max_episode_steps`` (its ``TimeLimit``)."""


class CartPole:
    """``gymnasium.envs.classic_control.CartPoleEnv`` (Euler, reward 1 per step): state
    ``[..., 4]`` float64 (x, x dot, theta, theta dot), action ``[...]`` integer (0 left, 1 right)."""

    gravity, masscart, masspole, length, force_mag, tau = 9.8, 1.0, 0.1, 0.5, 10.0, 0.02
    total_mass = masspole + masscart
    polemass_length = masspole * length
    theta_threshold_radians = 12 * 2 * math.pi / 360
    x_threshold = 2.4
    obs_dim = 4

    @staticmethod
    def observe(state: torch.Tensor) -> torch.Tensor:
        return state.to(torch.float32)

    def step(self, state: torch.Tensor, action: torch.Tensor):
        x, x_dot, theta, theta_dot = state.unbind(-1)
        force = torch.where(action == 1, self.force_mag, -self.force_mag).to(state.dtype)
        costheta, sintheta = torch.cos(theta), torch.sin(theta)
        temp = (force + self.polemass_length * (theta_dot * theta_dot) * sintheta) / self.total_mass
        thetaacc = (self.gravity * sintheta - costheta * temp) / (
            self.length * (4.0 / 3.0 - self.masspole * (costheta * costheta) / self.total_mass)
        )
        xacc = temp - self.polemass_length * thetaacc * costheta / self.total_mass
        new = torch.stack(
            [
                x + self.tau * x_dot,
                x_dot + self.tau * xacc,
                theta + self.tau * theta_dot,
                theta_dot + self.tau * thetaacc,
            ],
            dim=-1,
        )
        nx, ntheta = new[..., 0], new[..., 2]
        terminated = (
            (nx < -self.x_threshold)
            | (nx > self.x_threshold)
            | (ntheta < -self.theta_threshold_radians)
            | (ntheta > self.theta_threshold_radians)
        )
        return new, self.observe(new), torch.ones_like(nx), terminated
