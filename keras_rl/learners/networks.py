"""Subclassed Keras models, one per network in the posts."""

from __future__ import annotations

from collections.abc import Sequence

import keras
import tensorflow as tf


class Actor(keras.Model):
    """Post 000 §2.2: Dense 64 relu, Dense 64 relu, Dense(action_dim, tanh), times the bound.

    The post wraps the scaling in a fresh ``Lambda`` layer on every call; a plain
    multiplication computes the same thing without creating layers in the hot loop.
    """

    def __init__(self, action_dim: int, action_bound: float, hidden_units: Sequence[int] = (64, 64)):
        super().__init__()
        self.action_bound = float(action_bound)
        self.hidden = [keras.layers.Dense(units, activation="relu") for units in hidden_units]
        self.out = keras.layers.Dense(action_dim, activation="tanh")

    def call(self, state: tf.Tensor) -> tf.Tensor:  # [B, obs] -> [B, act]
        x = state
        for layer in self.hidden:
            x = layer(x)
        return self.out(x) * self.action_bound


class Critic(keras.Model):
    """Post 000 §2.2: concat(state, action), Dense 64 relu, Dense 64 relu, Dense 1."""

    def __init__(self, hidden_units: Sequence[int] = (64, 64)):
        super().__init__()
        self.hidden = [keras.layers.Dense(units, activation="relu") for units in hidden_units]
        self.out = keras.layers.Dense(1)

    def call(self, state: tf.Tensor, action: tf.Tensor) -> tf.Tensor:  # -> [B, 1]
        x = tf.concat([state, action], axis=-1)
        for layer in self.hidden:
            x = layer(x)
        return self.out(x)


def build(model: keras.Model, *input_dims: int) -> keras.Model:
    """Create a model's variables by calling it once on zeros of the given widths."""
    model(*[tf.zeros((1, dim), model.compute_dtype) for dim in input_dims])
    return model


def torch_linear_init(fan_in: int) -> keras.initializers.Initializer:
    """``nn.Linear``'s default: kaiming_uniform(a=sqrt(5)) = U(-1/sqrt(fan_in), 1/sqrt(fan_in)),
    for weights and biases alike."""
    bound = 1.0 / fan_in**0.5
    return keras.initializers.RandomUniform(-bound, bound)


class QNetwork(keras.Model):
    """Post 003 In [16]: Linear 128, relu, Linear 128, relu, Linear n_actions.

    ``init="torch"`` draws every weight and bias like ``nn.Linear``; ``"keras"`` keeps
    Dense's Glorot-uniform kernels and zero biases.
    """

    def __init__(
        self,
        obs_dim: int,
        n_actions: int,
        hidden_units: Sequence[int] = (128, 128),
        init: str = "torch",
        dtype: str | None = None,
    ):
        super().__init__(dtype=dtype)
        fan_ins = [obs_dim, *hidden_units]
        widths = [*hidden_units, n_actions]
        self.dense = []
        for i, (fan_in, width) in enumerate(zip(fan_ins, widths)):
            kwargs = (
                {"kernel_initializer": torch_linear_init(fan_in), "bias_initializer": torch_linear_init(fan_in)}
                if init == "torch"
                else {}
            )
            activation = "relu" if i < len(hidden_units) else None
            self.dense.append(keras.layers.Dense(width, activation=activation, dtype=dtype, **kwargs))

    def call(self, state: tf.Tensor) -> tf.Tensor:  # [B, obs] -> [B, n_actions]
        x = state
        for layer in self.dense:
            x = layer(x)
        return x


class MountainCarActor(keras.Model):
    """Post 001 ``Actor.__make_model``: GaussianNoise(1.0) -> BatchNormalization ->
    3 x Dense 32 selu -> Dense(action_dim, tanh).

    ``training`` is the Keras 2 learning phase the post's code ran with. Its ``K.function``
    and ``predict`` calls never feed it, so it stays at its default, 0 (FIDELITY
    P001-PHASE): the noise layer is the identity and BatchNormalization normalises with its
    initial moving statistics (mean 0, variance 1), which nothing ever updates.
    """

    def __init__(
        self,
        action_dim: int = 1,
        hidden_units: Sequence[int] = (32, 32, 32),
        noise_std: float = 1.0,
        training: bool = False,
    ):
        super().__init__()
        self.learning_phase = training
        self.noise = keras.layers.GaussianNoise(noise_std)
        self.norm = keras.layers.BatchNormalization()
        self.hidden = [keras.layers.Dense(units, activation="selu") for units in hidden_units]
        self.out = keras.layers.Dense(action_dim, activation="tanh")

    def call(self, state: tf.Tensor) -> tf.Tensor:  # [B, obs] -> [B, act]
        x = self.norm(self.noise(state, training=self.learning_phase), training=self.learning_phase)
        for layer in self.hidden:
            x = layer(x)
        return self.out(x)


class MountainCarCritic(keras.Model):
    """Post 001 ``Critic.__make_model``: state -> BatchNormalization -> Dense 32 selu ->
    concatenate with the action -> Dense 32 selu -> Dense 1. ``training`` as for the actor."""

    def __init__(self, hidden_units: Sequence[int] = (32, 32), training: bool = False):
        super().__init__()
        if len(hidden_units) != 2:
            raise ValueError(
                f"post 001's critic has two hidden layers (before and after the action joins), "
                f"got widths {tuple(hidden_units)}"
            )
        self.learning_phase = training
        self.norm = keras.layers.BatchNormalization()
        self.fc1 = keras.layers.Dense(hidden_units[0], activation="selu")
        self.fc2 = keras.layers.Dense(hidden_units[1], activation="selu")
        self.out = keras.layers.Dense(1)

    def call(self, state: tf.Tensor, action: tf.Tensor) -> tf.Tensor:  # -> [B, 1]
        x = self.fc1(self.norm(state, training=self.learning_phase))
        x = self.fc2(tf.concat([x, action], axis=-1))
        return self.out(x)
