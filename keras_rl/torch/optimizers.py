"""``KerasAdam``: ``torch.optim.Adam`` stepping as ``keras.optimizers.Adam`` does.

Both posts use Keras' ``Adam`` (``epsilon=1e-7`` added to ``sqrt(v)`` *before* the bias
correction). ``torch.optim.Adam`` adds its ``eps`` after it, which for gradients below
~3e-4 changes the first steps by more than 1e-5. The seed-batched version, with a step
count per seed, is ``SeedKerasAdam``.
"""

from __future__ import annotations

import math

from keras_rl.errors import ConfigError
from keras_rl.torch import PORTABLE_SWITCH, portable_arithmetic, require_torch

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402


class KerasAdam(torch.optim.Adam):
    """``torch.optim.Adam`` stepping as ``keras.optimizers.Adam`` does.

    Keras: ``p -= lr * sqrt(1-b2^t)/(1-b1^t) * m / (sqrt(v) + eps)``. torch:
    ``p -= lr/(1-b1^t) * m / (sqrt(v)/sqrt(1-b2^t) + eps_t)``. The two are equal when
    ``eps_t = eps / sqrt(1-b2^t)``, so that is the ``eps`` each step gets.
    """

    def __init__(self, params, lr: float, epsilon: float = 1e-7, betas=(0.9, 0.999)):
        if not lr > 0:
            raise ValueError(f"learning rate must be positive, got {lr}")
        super().__init__(params, lr=lr, betas=betas, eps=epsilon, fused=portable_arithmetic() or None)
        self.epsilon = float(epsilon)
        self.iterations = 0

    @torch.no_grad()
    def step(self, closure=None):
        self.iterations += 1
        for group in self.param_groups:
            group["eps"] = self.epsilon / math.sqrt(1.0 - group["betas"][1] ** self.iterations)
        return super().step(closure)


def check_same_arithmetic(*states: dict) -> None:
    """A ConfigError where a checkpoint's optimizer ``states`` were made under another arithmetic than
    this process's: a run resumed across ``KERAS_RL_PORTABLE_TORCH`` would mix the two
    (``portable_arithmetic``). A learner asks before it loads anything."""
    fused = {bool(group.get("fused")) for state in states for group in state["param_groups"]}
    if fused != {portable_arithmetic()}:
        made = "with" if True in fused else "without"
        raise ConfigError(
            f"this checkpoint was made {made} the portable arithmetic ({PORTABLE_SWITCH}=1): "
            f"resume it {made} {PORTABLE_SWITCH}=1"
        )


def not_portable(engine: str) -> None:
    """A ConfigError where ``KERAS_RL_PORTABLE_TORCH=1`` asks ``engine`` (whose hand-written
    optimizer steps take torch's square root) for the portable arithmetic it does not have."""
    if portable_arithmetic():
        raise ConfigError(
            f"{PORTABLE_SWITCH}=1 covers the Gymnasium loop's torch.optim steps; the {engine} writes its "
            f"own optimizer step, whose square root follows the CPU: unset {PORTABLE_SWITCH}"
        )


def keep_where(mask, like):
    return mask.reshape([-1] + [1] * (like.dim() - 1))


class SeedKerasAdam:
    """``KerasAdam`` (torch's Adam with Keras' epsilon placement) for stacked parameters,
    each seed with its own step count; a seed whose mask is False keeps its slice of every
    parameter, its moments and its step count bit for bit. With every mask True it is the
    solo optimizer's arithmetic per seed (torch's single-tensor Adam: ``m.lerp_(g, 1-b1)``,
    ``v = b2 v + (1-b2) g^2``, ``p -= lr/(1-b1^t) * m / (sqrt(v)/sqrt(1-b2^t) + eps_t)``,
    with ``eps_t = eps / sqrt(1-b2^t)``; the bias corrections in double precision)."""

    def __init__(self, params, seeds: int, lr: float, epsilon: float = 1e-7, betas=(0.9, 0.999)):
        self.params = list(params)
        self.lr, self.epsilon, (self.beta_1, self.beta_2) = float(lr), float(epsilon), betas
        self.steps = torch.zeros(seeds, dtype=torch.int64)
        self.m = [torch.zeros_like(p) for p in self.params]
        self.v = [torch.zeros_like(p) for p in self.params]
        self.mask = torch.ones(seeds, dtype=torch.bool)

    def zero_grad(self, set_to_none: bool = False) -> None:
        for p in self.params:
            p.grad = None

    @torch.no_grad()
    def step(self) -> None:
        t = (self.steps + 1).to(torch.float64)
        bias_correction1 = 1 - self.beta_1**t
        bias_correction2_sqrt = (1 - self.beta_2**t).sqrt()
        step_size = (self.lr / bias_correction1).to(torch.float32)
        eps = (self.epsilon / bias_correction2_sqrt).to(torch.float32)
        bc2 = bias_correction2_sqrt.to(torch.float32)
        for p, m, v in zip(self.params, self.m, self.v, strict=True):
            g = p.grad
            keep = keep_where(self.mask, p)
            new_m = m.lerp(g, 1 - self.beta_1)
            new_v = v.mul(self.beta_2).addcmul(g, g, value=1 - self.beta_2)
            denom = new_v.sqrt() / keep_where(bc2, p) + keep_where(eps, p)
            new_p = p - keep_where(step_size, p) * (new_m / denom)
            m.copy_(torch.where(keep, new_m, m))
            v.copy_(torch.where(keep, new_v, v))
            p.copy_(torch.where(keep, new_p, p))
        self.steps = torch.where(self.mask, self.steps + 1, self.steps)

    def tensors(self) -> list:
        return [self.steps, *self.m, *self.v]
