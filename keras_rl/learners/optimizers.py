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

    def __init__(
        self,
        learning_rate: float = 1e-3,
        beta_1: float = 0.9,
        beta_2: float = 0.999,
        epsilon: float = 1e-8,
        weight_decay: float = 0.01,
        amsgrad: bool = False,
        name: str = "torch_adamw",
        **kwargs,
    ):
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


class SeedAdam:
    """Keras' Adam for S stacked seeds, each with its own step count, and a mask.

    The arithmetic is ``keras.optimizers.Adam.update_step``'s, op for op, with the step
    count a vector ``[S]``: ``alpha = lr * sqrt(1 - beta2^t) / (1 - beta1^t)`` per seed,
    ``m += (g - m)(1 - beta1)``, ``v += (g^2 - v)(1 - beta2)``, ``p -= m * alpha / (sqrt(v) + eps)``.
    A seed whose mask is False keeps its slice of every variable, its moments and its step
    count bit for bit (post 001's seeds train different numbers of batches on one env
    step, P001-POP). With every mask True it computes what a Keras Adam per seed computes.
    """

    def __init__(
        self,
        variables,
        seeds: int,
        learning_rate: float,
        beta_1: float = 0.9,
        beta_2: float = 0.999,
        epsilon: float = 1e-7,
    ):
        import tensorflow as tf

        self.learning_rate = tf.Variable(learning_rate, dtype=tf.float32, trainable=False, name="learning_rate")
        self.beta_1, self.beta_2, self.epsilon = beta_1, beta_2, epsilon
        self.steps = tf.Variable(tf.zeros([seeds], tf.int64), trainable=False, name="steps")
        self.m = [tf.Variable(tf.zeros_like(v), trainable=False, name="m") for v in variables]
        self.v = [tf.Variable(tf.zeros_like(v), trainable=False, name="v") for v in variables]

    @property
    def variables(self) -> list:
        """In the order a checkpoint holds them (``SliceState`` slices every one with a seed axis)."""
        return [self.steps, self.learning_rate, *self.m, *self.v]

    def apply(self, grads, variables, mask) -> None:
        """One step for the seeds where ``mask`` [S] is True."""
        import tensorflow as tf

        for g, variable, m, v in zip(grads, variables, self.m, self.v, strict=True):
            dtype = variable.dtype
            shape = [-1] + [1] * (len(variable.shape) - 1)  # [S, 1, ...]: per seed, broadcast
            local_step = tf.reshape(tf.cast(self.steps + 1, dtype), shape)
            beta_1_power = tf.pow(tf.cast(self.beta_1, dtype), local_step)
            beta_2_power = tf.pow(tf.cast(self.beta_2, dtype), local_step)
            lr = tf.cast(self.learning_rate, dtype)
            alpha = lr * tf.sqrt(1 - beta_2_power) / (1 - beta_1_power)
            g = tf.cast(g, dtype)
            new_m = m + (g - m) * (1 - self.beta_1)
            new_v = v + (tf.square(g) - v) * (1 - self.beta_2)
            new_p = variable - (new_m * alpha) / (tf.sqrt(new_v) + self.epsilon)
            keep = tf.reshape(mask, shape)
            m.assign(tf.where(keep, new_m, m))
            v.assign(tf.where(keep, new_v, v))
            variable.assign(tf.where(keep, new_p, variable))
        self.steps.assign(tf.where(mask, self.steps + 1, self.steps))
