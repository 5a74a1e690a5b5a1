"""The PyTorch envs (``keras_rl/torch/envs.py``) against the installed Gymnasium, as
``tests/test_tf_envs.py`` measures the TensorFlow ones: one step from 1,000 random states and
actions, and 200-step trajectories under recorded actions (a terminated episode resets to the
state Gymnasium's own reset draws). Measured on this CPU: the state, the float32 observation, the
reward and the flag are Gymnasium's bit for bit (PyTorch's float64 ``sin``/``cos`` round as the C
library's here), so that is what is asserted."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="needs the torch extra")

from keras_rl.torch.envs import MAX_STEPS, CartPole  # noqa: E402


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
    for mine, theirs in zip(ours, ref):
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
        for i, env in enumerate(envs):
            their_obs, their_reward, their_terminated, _, _ = env.step(int(actions[t, i]))
            assert np.array_equal(obs[i].numpy(), their_obs), (t, i)
            assert np.array_equal(new[i].numpy(), np.asarray(env.unwrapped.state, np.float64)), (t, i)
            assert (reward[i].item(), bool(terminated[i])) == (their_reward, their_terminated)
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
