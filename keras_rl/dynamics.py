"""The posts' env dynamics written once, for the tensor libraries' envs (``tf_envs.py`` in
TensorFlow, ``torch/envs.py`` in PyTorch): the constants and the arithmetic of a step, in
Gymnasium's order of operations, on whatever tensors the caller passes. The library supplies
what differs between them (``cos``, ``sin``, ``where``, ``stack``, dtypes), so both compute the
same operations on the same values. No tensor library is imported here.
"""

from __future__ import annotations

import math

MAX_STEPS = {"Pendulum-v1": 200, "CartPole-v1": 500, "MountainCarContinuous-v0": 999}
"""Gymnasium's registered ``max_episode_steps`` (its ``TimeLimit``)."""


class CartPoleDynamics:
    """``gymnasium.envs.classic_control.CartPoleEnv`` (Euler, reward 1 per step): state
    (x, x dot, theta, theta dot) float64, action 0 (left) or 1 (right)."""

    gravity, masscart, masspole, length, force_mag, tau = 9.8, 1.0, 0.1, 0.5, 10.0, 0.02
    total_mass = masspole + masscart
    polemass_length = masspole * length
    theta_threshold_radians = 12 * 2 * math.pi / 360
    x_threshold = 2.4
    obs_dim = 4

    def euler(self, x, x_dot, theta, theta_dot, force, costheta, sintheta):
        """The next (x, x dot, theta, theta dot) from the state, the signed force and the pole
        angle's cosine and sine, as ``CartPoleEnv.step`` computes them."""
        temp = (force + self.polemass_length * (theta_dot * theta_dot) * sintheta) / self.total_mass
        thetaacc = (self.gravity * sintheta - costheta * temp) / (
            self.length * (4.0 / 3.0 - self.masspole * (costheta * costheta) / self.total_mass)
        )
        xacc = temp - self.polemass_length * thetaacc * costheta / self.total_mass
        return (
            x + self.tau * x_dot,
            x_dot + self.tau * xacc,
            theta + self.tau * theta_dot,
            theta_dot + self.tau * thetaacc,
        )

    def terminated(self, x, theta):
        """The pole fell or the cart left the track (elementwise boolean tensors)."""
        return (
            (x < -self.x_threshold)
            | (x > self.x_threshold)
            | (theta < -self.theta_threshold_radians)
            | (theta > self.theta_threshold_radians)
        )
