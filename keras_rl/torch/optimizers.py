"""``KerasAdam``: ``torch.optim.Adam`` stepping as ``keras.optimizers.Adam`` does.

Both posts use Keras' ``Adam`` (``epsilon=1e-7`` added to ``sqrt(v)`` *before* the bias
correction). ``torch.optim.Adam`` adds its ``eps`` after it, which for gradients below
~3e-4 changes the first steps by more than 1e-5. The seed-batched version, with a step
count per seed, is ``keras_rl.torch.stacked.SeedKerasAdam``.
"""

from __future__ import annotations

import math

from keras_rl.torch import require_torch

torch = require_torch()


class KerasAdam(torch.optim.Adam):
    """``torch.optim.Adam`` stepping as ``keras.optimizers.Adam`` does.

    Keras: ``p -= lr * sqrt(1-b2^t)/(1-b1^t) * m / (sqrt(v) + eps)``. torch:
    ``p -= lr/(1-b1^t) * m / (sqrt(v)/sqrt(1-b2^t) + eps_t)``. The two are equal when
    ``eps_t = eps / sqrt(1-b2^t)``, so that is the ``eps`` each step gets.
    """

    def __init__(self, params, lr: float, epsilon: float = 1e-7, betas=(0.9, 0.999)):
        if not lr > 0:
            raise ValueError(f"learning rate must be positive, got {lr}")
        super().__init__(params, lr=lr, betas=betas, eps=epsilon)
        self.epsilon = float(epsilon)
        self.iterations = 0

    @torch.no_grad()
    def step(self, closure=None):
        self.iterations += 1
        for group in self.param_groups:
            group["eps"] = self.epsilon / math.sqrt(1.0 - group["betas"][1] ** self.iterations)
        return super().step(closure)
