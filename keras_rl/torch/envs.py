"""The posts' envs as PyTorch tensor functions, for an engine that steps many seeds at once
(issue 53): each a pure function of its state, ``step(state, action) -> (state, observation,
reward, terminated)``, elementwise over any leading axes (a seed axis, say), on whatever device
the tensors are on. The state is what Gymnasium's env keeps (``env.unwrapped.state``), float64;
the observation is the float32 array Gymnasium returns. Reset states are not drawn here: an
engine takes them from each seed's own Gymnasium generator, so both engines start every episode
alike (as ``keras_rl/tf_envs.py`` does for TensorFlow, whose CartPole this follows operation
for operation). Time limits are the engine's to count (``MAX_STEPS``).

``tests/test_torch_envs.py`` measures the agreement with the installed Gymnasium on the CPU: the
state, observation, reward and flag are bit for bit wherever PyTorch's float64 ``sin``/``cos``
round as the C library's ``math.sin``/``math.cos`` do (every step on the AMD EPYC; on an Intel
Xeon about 4 angles in 1,000 round otherwise, and those steps agree within a relative 1e-14). A
GPU's ``sin``/``cos`` need not; its agreement is to be measured where one is lent (issue 53).
"""

from __future__ import annotations

import torch

from keras_rl.dynamics import MAX_STEPS, CartPoleDynamics

__all__ = ["MAX_STEPS", "CartPole"]


class CartPole(CartPoleDynamics):
    """``gymnasium.envs.classic_control.CartPoleEnv`` in PyTorch (``dynamics.CartPoleDynamics``):
    state ``[..., 4]`` float64, action ``[...]`` integer (0 left, 1 right)."""

    @staticmethod
    def observe(state: torch.Tensor) -> torch.Tensor:
        return state.to(torch.float32)

    def step(self, state: torch.Tensor, action: torch.Tensor):
        x, x_dot, theta, theta_dot = state.unbind(-1)
        force = torch.where(action == 1, self.force_mag, -self.force_mag).to(state.dtype)
        new = torch.stack(self.euler(x, x_dot, theta, theta_dot, force, torch.cos(theta), torch.sin(theta)), dim=-1)
        terminated = self.terminated(new[..., 0], new[..., 2])
        return new, self.observe(new), torch.ones_like(new[..., 0]), terminated
