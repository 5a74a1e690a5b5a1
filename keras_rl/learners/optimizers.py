"""A Keras optimizer that computes exactly what ``torch.optim.AdamW`` computes.

Keras' own AdamW differs from torch's by default (weight decay 0.004 vs 0.01, epsilon
1e-7 vs 1e-8) and in where epsilon goes: Keras adds it to ``sqrt(v)`` and folds both bias
corrections into the step size; torch divides ``sqrt(v)`` by ``sqrt(1 - beta2^t)`` first
and adds epsilon after. With amsgrad torch keeps the running max of ``v`` and uses it in
that same place. Parity with the PyTorch tutorial (issue #3) needs torch's arithmetic.
"""

from __future__ import annotations

import keras
from keras import ops


class TorchAdamW(keras.optimizers.Optimizer):
    """torch.optim.AdamW (single-tensor path, ``maximize=False``), step for step::

        p <- p * (1 - lr * weight_decay)
        m <- m + (1 - beta1) * (g - m)            # exp_avg.lerp_(grad, 1 - beta1)
        v <- beta2 * v + (1 - beta2) * g * g
        v_max <- max(v_max, v)                    # amsgrad only
        denom <- sqrt(v_max or v) / sqrt(1 - beta2^t) + eps
        p <- p - lr / (1 - beta1^t) * m / denom

    The decoupled weight decay is Keras' own ``_apply_weight_decay`` (``p - p*wd*lr``),
    which runs before the update step, as torch's ``param.mul_`` does.
    """

    def __init__(self, learning_rate: float = 1e-3, beta_1: float = 0.9, beta_2: float = 0.999,
                 epsilon: float = 1e-8, weight_decay: float = 0.01, amsgrad: bool = False,
                 name: str = "torch_adamw", **kwargs):
        for label, value in (("learning_rate", learning_rate), ("epsilon", epsilon)):
            if not value > 0:
                raise ValueError(f"{label} must be positive, got {value}")
        if weight_decay < 0:
            raise ValueError(f"weight_decay must be zero or more, got {weight_decay}")
        super().__init__(learning_rate=learning_rate, weight_decay=weight_decay or None, name=name, **kwargs)
        self.beta_1, self.beta_2, self.epsilon, self.amsgrad = beta_1, beta_2, epsilon, amsgrad

    def build(self, var_list):
        if self.built:
            return
        super().build(var_list)
        self._m = [self.add_variable_from_reference(v, "m") for v in var_list]
        self._v = [self.add_variable_from_reference(v, "v") for v in var_list]
        self._v_max = [self.add_variable_from_reference(v, "v_max") for v in var_list] if self.amsgrad else []

    def update_step(self, gradient, variable, learning_rate):
        i = self._get_variable_index(variable)
        lr = ops.cast(learning_rate, variable.dtype)
        g = ops.cast(gradient, variable.dtype)
        t = ops.cast(self.iterations + 1, variable.dtype)
        # convert_to_tensor with the dtype: ops.cast of a Python float goes through float32
        # first, and 1 - float32(0.999) is off by 1.3e-5 relative.
        beta_1 = ops.convert_to_tensor(self.beta_1, dtype=variable.dtype)
        beta_2 = ops.convert_to_tensor(self.beta_2, dtype=variable.dtype)
        bias_correction1 = 1 - ops.power(beta_1, t)
        bias_correction2 = 1 - ops.power(beta_2, t)
        m, v = self._m[i], self._v[i]
        self.assign(m, m + (1 - self.beta_1) * (g - m))
        self.assign(v, self.beta_2 * v + (1 - self.beta_2) * g * g)
        second = v
        if self.amsgrad:
            self.assign(self._v_max[i], ops.maximum(self._v_max[i], v))
            second = self._v_max[i]
        denom = ops.sqrt(second) / ops.sqrt(bias_correction2) + self.epsilon
        self.assign_sub(variable, (lr / bias_correction1) * m / denom)

    def get_config(self):
        config = super().get_config()
        config.update(beta_1=self.beta_1, beta_2=self.beta_2, epsilon=self.epsilon, amsgrad=self.amsgrad)
        return config
