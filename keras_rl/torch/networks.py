"""The PyTorch networks of posts 000 and 001, layer for layer as the Keras ones in
``keras_rl.learners.networks``; each can pair its weights with a Keras model's
(``keras_pairs``) for ``keras_rl.torch.weights.copy_from_keras``."""

from __future__ import annotations

from collections.abc import Sequence

from keras_rl.torch import require_torch
from keras_rl.torch.weights import dense_pairs

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402
from torch import nn  # noqa: E402

F = nn.functional


class Actor(nn.Module):
    """Post 000 §2.2: Linear 64 relu, Linear 64 relu, Linear(action_dim) tanh, times the bound."""

    def __init__(self, obs_dim: int, action_dim: int, action_bound: float, hidden_units: Sequence[int] = (64, 64)):
        super().__init__()
        widths = [obs_dim, *hidden_units]
        self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths, widths[1:]))
        self.out = nn.Linear(widths[-1], action_dim)
        self.action_bound = float(action_bound)

    def forward(self, state):  # [B, obs] -> [B, act]
        x = state
        for layer in self.hidden:
            x = F.relu(layer(x))
        return torch.tanh(self.out(x)) * self.action_bound

    def keras_pairs(self, model) -> list:
        return dense_pairs([*self.hidden, self.out], [*model.hidden, model.out])


class Critic(nn.Module):
    """Post 000 §2.2: concat(state, action), Linear 64 relu, Linear 64 relu, Linear 1."""

    def __init__(self, obs_dim: int, action_dim: int, hidden_units: Sequence[int] = (64, 64)):
        super().__init__()
        widths = [obs_dim + action_dim, *hidden_units]
        self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths, widths[1:]))
        self.out = nn.Linear(widths[-1], 1)

    def forward(self, state, action):  # -> [B, 1]
        x = torch.cat([state, action], dim=-1)
        for layer in self.hidden:
            x = F.relu(layer(x))
        return self.out(x)

    def keras_pairs(self, model) -> list:
        return dense_pairs([*self.hidden, self.out], [*model.hidden, model.out])


class KerasBatchNorm(nn.Module):
    """Keras' ``BatchNormalization`` on the last axis: epsilon 1e-3, momentum 0.99, the
    moving variance updated with the *biased* batch variance (``nn.BatchNorm1d`` uses the
    unbiased one). ``training`` is the Keras learning phase (post 001 ran with 0)."""

    def __init__(self, features: int, training: bool = False, epsilon: float = 1e-3, momentum: float = 0.99):
        super().__init__()
        self.weight = nn.Parameter(torch.ones(features))  # gamma
        self.bias = nn.Parameter(torch.zeros(features))  # beta
        self.register_buffer("running_mean", torch.zeros(features))
        self.register_buffer("running_var", torch.ones(features))
        self.learning_phase, self.epsilon, self.momentum = bool(training), float(epsilon), float(momentum)

    def forward(self, x):
        if self.learning_phase:
            mean, var = x.mean(0), x.var(0, unbiased=False)
            with torch.no_grad():
                self.running_mean.copy_(self.running_mean * self.momentum + mean * (1 - self.momentum))
                self.running_var.copy_(self.running_var * self.momentum + var * (1 - self.momentum))
        else:
            mean, var = self.running_mean, self.running_var
        return (x - mean) * torch.rsqrt(var + self.epsilon) * self.weight + self.bias

    def keras_pairs(self, layer) -> list:
        return [
            (self.weight, layer.gamma, False),
            (self.bias, layer.beta, False),
            (self.running_mean, layer.moving_mean, False),
            (self.running_var, layer.moving_variance, False),
        ]


class MountainCarActor(nn.Module):
    """Post 001 ``Actor.__make_model``: GaussianNoise(1.0) -> BatchNormalization ->
    3 x Linear 32 selu -> Linear(action_dim) tanh; ``training`` is the learning phase."""

    def __init__(
        self,
        obs_dim: int,
        action_dim: int = 1,
        hidden_units: Sequence[int] = (32, 32, 32),
        noise_std: float = 1.0,
        training: bool = False,
    ):
        super().__init__()
        self.learning_phase, self.noise_std = bool(training), float(noise_std)
        self.norm = KerasBatchNorm(obs_dim, training)
        widths = [obs_dim, *hidden_units]
        self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths, widths[1:]))
        self.out = nn.Linear(widths[-1], action_dim)

    def forward(self, state):
        x = state + self.noise_std * torch.randn_like(state) if self.learning_phase else state
        x = self.norm(x)
        for layer in self.hidden:
            x = F.selu(layer(x))
        return torch.tanh(self.out(x))

    def keras_pairs(self, model) -> list:
        return self.norm.keras_pairs(model.norm) + dense_pairs([*self.hidden, self.out], [*model.hidden, model.out])


class MountainCarCritic(nn.Module):
    """Post 001 ``Critic.__make_model``: BatchNormalization -> Linear 32 selu -> concat the
    action -> Linear 32 selu -> Linear 1."""

    def __init__(
        self, obs_dim: int, action_dim: int = 1, hidden_units: Sequence[int] = (32, 32), training: bool = False
    ):
        super().__init__()
        self.norm = KerasBatchNorm(obs_dim, training)
        self.fc1 = nn.Linear(obs_dim, hidden_units[0])
        self.fc2 = nn.Linear(hidden_units[0] + action_dim, hidden_units[1])
        self.out = nn.Linear(hidden_units[1], 1)

    def forward(self, state, action):
        x = F.selu(self.fc1(self.norm(state)))
        x = F.selu(self.fc2(torch.cat([x, action], dim=-1)))
        return self.out(x)

    def keras_pairs(self, model) -> list:
        return self.norm.keras_pairs(model.norm) + dense_pairs(
            [self.fc1, self.fc2, self.out], [model.fc1, model.fc2, model.out]
        )
