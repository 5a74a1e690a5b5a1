"""The posts' three envs in TensorFlow, for a training loop compiled whole (one XLA program per
chunk of steps, no host call per env step).

Each is a pure function of its state: ``step(state, action) -> (state, observation, reward,
terminated)``, elementwise over any leading axes (a seed axis, say), and ``observe(state)``.
The state is what Gymnasium's env keeps (``env.unwrapped.state``), in the dtype Gymnasium
computes it in; the observation is the float32 array Gymnasium returns. Reset states are not
drawn here: the engine takes them from the Gymnasium env's own generator, seeded as the run
seeds it, so both engines start every episode in the same state. The time limits are the
registered ones (``MAX_STEPS``); truncation is the engine's to count.

The arithmetic follows Gymnasium 1.x under NumPy 2's promotion rules (NEP 50) operation for
operation, the float32 steps included: in Pendulum-v1, ``0.001 * u**2`` and ``3.0 * u`` are
float32 products (``u`` is the float32 action) added to float64 terms; in
MountainCarContinuous-v0 the state is stored as float32 after every step, so each step's
arithmetic is float32, except the first after a reset (a float64 state) and where the action is
clipped to a Python float. ``tests/test_tf_envs.py`` measures the agreement against the
installed Gymnasium: bit for bit where the operations are IEEE-exact, within a stated ulp bound
where a transcendental function (``sin``, ``cos``) is TensorFlow's own.
"""

from __future__ import annotations

import math

import tensorflow as tf

from keras_rl.dynamics import MAX_STEPS, CartPoleDynamics

__all__ = ["MAX_STEPS", "CartPole", "MountainCarContinuous", "Pendulum"]

F32, F64 = tf.float32, tf.float64


class Pendulum:
    """``gymnasium.envs.classic_control.PendulumEnv``: state ``[..., 2]`` float64 (theta,
    theta dot), action ``[..., 1]`` float32 torque."""

    max_speed, max_torque, dt, mass, length = 8.0, 2.0, 0.05, 1.0, 1.0
    obs_dim = 3

    def __init__(self, g: float = 10.0):
        self.g = float(g)

    @staticmethod
    def observe(state: tf.Tensor) -> tf.Tensor:
        th, thdot = state[..., 0], state[..., 1]
        return tf.cast(tf.stack([tf.cos(th), tf.sin(th), thdot], axis=-1), F32)

    def step(self, state: tf.Tensor, action: tf.Tensor):
        th, thdot = state[..., 0], state[..., 1]
        u = tf.clip_by_value(action[..., 0], -self.max_torque, self.max_torque)  # float32, as np.clip keeps it
        normalized = tf.math.floormod(th + math.pi, 2 * math.pi) - math.pi
        torque_cost = tf.cast(tf.constant(0.001, F32) * (u * u), F64)  # 0.001 * (u**2): a float32 product
        costs = normalized * normalized + 0.1 * (thdot * thdot) + torque_cost
        gain = 3 * self.g / (2 * self.length)
        push = tf.cast(tf.constant(3.0 / (self.mass * self.length**2), F32) * u, F64)  # 3.0 / (m l^2) * u: float32
        newthdot = thdot + (gain * tf.sin(th) + push) * self.dt
        newthdot = tf.clip_by_value(newthdot, -self.max_speed, self.max_speed)
        newth = th + newthdot * self.dt
        new = tf.stack([newth, newthdot], axis=-1)
        return new, self.observe(new), -costs, tf.zeros_like(costs, tf.bool)


class CartPole(CartPoleDynamics):
    """``gymnasium.envs.classic_control.CartPoleEnv`` in TensorFlow (``dynamics.CartPoleDynamics``):
    state ``[..., 4]`` float64, action ``[...]`` int (0 left, 1 right)."""

    @staticmethod
    def observe(state: tf.Tensor) -> tf.Tensor:
        return tf.cast(state, F32)

    def step(self, state: tf.Tensor, action: tf.Tensor):
        x, x_dot, theta, theta_dot = (state[..., i] for i in range(4))
        force = tf.cast(tf.where(tf.equal(action, 1), self.force_mag, -self.force_mag), F64)
        new = tf.stack(self.euler(x, x_dot, theta, theta_dot, force, tf.cos(theta), tf.sin(theta)), axis=-1)
        terminated = self.terminated(new[..., 0], new[..., 2])
        return new, self.observe(new), tf.ones_like(new[..., 0]), terminated


class MountainCarContinuous:
    """``gymnasium.envs.classic_control.Continuous_MountainCarEnv``: state ``[..., 2]`` float64
    (position, velocity) holding what Gymnasium holds: float64 values straight after a reset,
    float32 values after any step; ``fresh`` ``[...]`` bool says which. Action ``[..., 1]``
    float32."""

    min_action, max_action = -1.0, 1.0
    min_position, max_position, max_speed, goal_position, power = -1.2, 0.6, 0.07, 0.45, 0.0015
    goal_velocity = 0.0
    obs_dim = 2

    @staticmethod
    def observe(state: tf.Tensor) -> tf.Tensor:
        return tf.cast(state, F32)

    def step(self, state: tf.Tensor, action: tf.Tensor, fresh: tf.Tensor):
        """One step; ``fresh``: the state is a reset's float64 one (Gymnasium's first step)."""
        a = action[..., 0]
        clipped = (a < self.min_action) | (a > self.max_action)
        force = tf.clip_by_value(a, self.min_action, self.max_action)
        pos64, vel64 = state[..., 0], state[..., 1]
        pos32, vel32 = tf.cast(pos64, F32), tf.cast(vel64, F32)
        # 3 * position: float32 after a step, float64 after a reset; cos in float64 either way
        three_pos = tf.where(fresh, 3 * pos64, tf.cast(3 * pos32, F64))
        hill = 0.0025 * tf.cos(three_pos)
        # force * power - hill: float32 when force is the float32 action, float64 when clipped
        inc32 = force * tf.constant(self.power, F32) - tf.cast(hill, F32)
        inc64 = tf.cast(force, F64) * self.power - hill
        velocity = tf.where(
            fresh,
            vel64 + tf.where(clipped, inc64, tf.cast(inc32, F64)),
            tf.cast(vel32 + tf.where(clipped, tf.cast(inc64, F32), inc32), F64),
        )
        velocity = tf.clip_by_value(velocity, -self.max_speed, self.max_speed)  # a Python float when clamped
        # position += velocity: float64 after a reset, else float32 (a clamped velocity is cast to it)
        position = tf.where(fresh, pos64 + velocity, tf.cast(pos32 + tf.cast(velocity, F32), F64))
        position = tf.clip_by_value(position, self.min_position, self.max_position)
        velocity = tf.where((position == self.min_position) & (velocity < 0), tf.zeros_like(velocity), velocity)
        pos_f32, vel_f32 = tf.cast(position, F32), tf.cast(velocity, F32)
        at_goal = tf.where(fresh, position >= self.goal_position, pos_f32 >= tf.constant(self.goal_position, F32))
        terminated = at_goal & (vel_f32 >= self.goal_velocity)
        reward = (
            tf.where(terminated, tf.constant(100.0, F64), tf.constant(0.0, F64))
            - tf.cast(a, F64) * tf.cast(a, F64) * 0.1
        )
        new = tf.cast(tf.stack([pos_f32, vel_f32], axis=-1), F64)
        return new, self.observe(new), tf.cast(reward, F64), terminated
