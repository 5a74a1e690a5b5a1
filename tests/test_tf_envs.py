"""The TensorFlow envs (``keras_rl/tf_envs.py``) against the installed Gymnasium.

One step from 1,000 random states and actions per env, then 200-step trajectories under one
recorded action sequence. What is measured, and so asserted:

- TensorFlow's own kernels (eager, or a graph without XLA): the next state, the float32
  observation and the flags are bit for bit Gymnasium's for all three envs; so is the reward
  of CartPole and MountainCarContinuous. Pendulum's reward differs in about 0.15% of steps, by
  one float32 ulp of its torque cost (at most 2^-23 * 0.004 < 5e-10) or a float64 ulp of its
  other terms: NumPy squares a *scalar* with the C library's ``pow``, which is not always
  correctly rounded, and TensorFlow has no such ``pow`` (its own is further off; ``x * x`` is
  the nearest).
- Compiled by XLA (how a compiled engine runs them): XLA fuses ``a * b + c`` into one
  fused multiply-add, so a float64 state differs from Gymnasium's by a few ulps (relative
  1e-15) in about a tenth of the steps, and the float32 observation is still Gymnasium's;
  MountainCarContinuous, whose steps are float32, differs in about 4% of steps by at most one
  float32 ulp below 1 (2^-24). Measured over 20 x 1,000 steps per env; 200-step trajectories
  stay within 1e-6.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
import tensorflow as tf

from keras_rl import tf_envs

N = 1000


def _pendulum_cases(rng):
    states = np.stack([rng.uniform(-4 * np.pi, 4 * np.pi, N), rng.uniform(-8, 8, N)], -1)
    return states, rng.uniform(-2.5, 2.5, (N, 1)).astype(np.float32)  # beyond the bound too: clipped


def _cartpole_cases(rng):
    bounds = [(-2.4, 2.4), (-3, 3), (-0.21, 0.21), (-3, 3)]
    states = np.stack([rng.uniform(lo, hi, N) for lo, hi in bounds], -1)
    return states, rng.integers(0, 2, N)


def _mountaincar_cases(rng):
    """Straight after a reset (float64 state, velocity 0) or after a step (float32 values)."""
    fresh = rng.random(N) < 0.3
    position = rng.uniform(-1.2, 0.6, N)
    velocity = rng.uniform(-0.07, 0.07, N)
    position = np.where(fresh, position, position.astype(np.float32))
    velocity = np.where(fresh, 0.0, velocity.astype(np.float32))
    return np.stack([position, velocity], -1), rng.uniform(-1.5, 1.5, (N, 1)).astype(np.float32), fresh


def _gymnasium_steps(env_id, states, actions, fresh=None, **kwargs):
    env = gym.make(env_id, **kwargs).unwrapped
    env.reset(seed=0)
    out = []
    for i, (state, action) in enumerate(zip(states, actions)):
        if env_id == "MountainCarContinuous-v0":
            env.state = np.array(state) if fresh[i] else state.astype(np.float32)
        else:
            env.state = state.copy()
            env.steps_beyond_terminated = None
        obs, reward, terminated, _, _ = env.step(int(action) if env_id == "CartPole-v1" else action)
        out.append((np.asarray(env.state, np.float64), obs, reward, terminated))
    return [np.array(column) for column in zip(*out)]


def _ours(env_id, states, actions, fresh=None, xla=False):
    env = {"Pendulum-v1": tf_envs.Pendulum(10.0), "CartPole-v1": tf_envs.CartPole()}.get(
        env_id, tf_envs.MountainCarContinuous()
    )
    args = [tf.constant(states), tf.constant(actions)] + ([tf.constant(fresh)] if fresh is not None else [])
    step = tf.function(env.step, jit_compile=True) if xla else env.step
    return [np.asarray(v) for v in step(*args)]


def _cases(env_id):
    rng = np.random.default_rng(ENVS.index(env_id))
    if env_id == "Pendulum-v1":
        return (*_pendulum_cases(rng), None)
    if env_id == "CartPole-v1":
        return (*_cartpole_cases(rng), None)
    return _mountaincar_cases(rng)


ENVS = ["Pendulum-v1", "CartPole-v1", "MountainCarContinuous-v0"]


@pytest.mark.parametrize("env_id", ENVS)
def test_one_step_is_gymnasiums_bit_for_bit_on_tensorflows_kernels(env_id):
    states, actions, fresh = _cases(env_id)
    kwargs = {"g": 10.0} if env_id == "Pendulum-v1" else {}
    ref_state, ref_obs, ref_reward, ref_terminated = _gymnasium_steps(env_id, states, actions, fresh, **kwargs)
    state, obs, reward, terminated = _ours(env_id, states, actions, fresh)
    assert obs.dtype == np.float32 and ref_obs.dtype == np.float32
    np.testing.assert_array_equal(state, ref_state)
    np.testing.assert_array_equal(obs, ref_obs)
    np.testing.assert_array_equal(terminated, ref_terminated)
    if env_id == "Pendulum-v1":  # NumPy's scalar pow against x * x: see the module's docstring
        assert np.mean(reward == ref_reward) > 0.99
        assert np.max(np.abs(reward - ref_reward)) < 5e-10
    else:
        np.testing.assert_array_equal(reward, ref_reward)


@pytest.mark.parametrize("env_id", ENVS)
def test_one_step_compiled_by_xla_is_within_a_few_ulps(env_id):
    states, actions, fresh = _cases(env_id)
    kwargs = {"g": 10.0} if env_id == "Pendulum-v1" else {}
    ref_state, ref_obs, ref_reward, ref_terminated = _gymnasium_steps(env_id, states, actions, fresh, **kwargs)
    state, obs, reward, terminated = _ours(env_id, states, actions, fresh, xla=True)
    if env_id == "MountainCarContinuous-v0":  # float32 steps: measured at most one float32 ulp below 1
        assert np.max(np.abs(state - ref_state)) <= 2.0**-24
        assert np.max(np.abs(obs - ref_obs)) <= 2.0**-24
    else:  # measured at most 1.5 float64 ulps (of max(|x|, 1)) over 20,000 steps; the observation exact
        assert np.all(np.abs(state - ref_state) <= 4 * np.spacing(np.maximum(np.abs(ref_state), 1.0)))
        assert np.all(np.abs(obs - ref_obs) <= np.spacing(np.abs(ref_obs)))
    assert np.mean(state == ref_state) > 0.8  # most steps are still bit for bit
    assert np.mean(terminated == ref_terminated) == 1.0
    assert np.max(np.abs(reward - ref_reward)) < 5e-10


def _trajectory(env_id, steps=200):
    """Gymnasium's states and observations along one recorded action sequence, from its own
    reset with seed 7, and the action sequence."""
    env = gym.make(env_id, **({"g": 10.0} if env_id == "Pendulum-v1" else {}))
    obs, _ = env.reset(seed=7)
    inner = env.unwrapped
    start = np.asarray(inner.state, np.float64).copy()
    rng = np.random.default_rng(3)
    if env_id == "CartPole-v1":
        actions = rng.integers(0, 2, steps)
    else:
        actions = rng.uniform(-1.2, 1.2, (steps, 1)).astype(np.float32) * (2 if env_id == "Pendulum-v1" else 1)
    states, observations = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # CartPole's "step after terminated": the dynamics go on
        for action in actions:
            obs, *_ = inner.step(int(action) if env_id == "CartPole-v1" else action)
            states.append(np.asarray(inner.state, np.float64).copy())
            observations.append(obs)
    return start, actions, np.array(states), np.array(observations)


@pytest.mark.parametrize("env_id", ENVS)
@pytest.mark.parametrize("xla", [False, True])
def test_a_200_step_trajectory_under_recorded_actions_stays_within_1e_6(env_id, xla):
    start, actions, ref_states, ref_obs = _trajectory(env_id)
    env = {"Pendulum-v1": tf_envs.Pendulum(10.0), "CartPole-v1": tf_envs.CartPole()}.get(
        env_id, tf_envs.MountainCarContinuous()
    )

    def roll(state, actions):
        states, observations = tf.TensorArray(tf.float64, len(actions)), tf.TensorArray(tf.float32, len(actions))
        for i in tf.range(len(actions)):
            args = (state, actions[i]) + ((tf.equal(i, 0),) if env_id == "MountainCarContinuous-v0" else ())
            state, obs, _, _ = env.step(*args)
            states, observations = states.write(i, state), observations.write(i, obs)
        return states.stack(), observations.stack()

    # TensorFlow's kernels run eagerly: a graph lets Grappler rewrite the arithmetic (measured: a
    # float64 ulp apart from step 10 of CartPole)
    run = tf.function(roll, jit_compile=True) if xla else roll
    states, observations = run(tf.constant(start), tf.constant(actions))
    np.testing.assert_allclose(states.numpy(), ref_states, rtol=0, atol=1e-6)
    np.testing.assert_allclose(observations.numpy(), ref_obs, rtol=0, atol=1e-6)
    if not xla:  # TensorFlow's kernels: the whole trajectory bit for bit
        np.testing.assert_array_equal(states.numpy(), ref_states)
