"""Env wrappers the tests use to make a run fail or be interrupted at a chosen env step."""

import os
import signal

import gymnasium as gym


class NaNRewardAfter(gym.Wrapper):
    """Rewards turn NaN after ``after_steps`` steps."""

    def __init__(self, env, after_steps):
        super().__init__(env)
        self.after, self.steps = after_steps, 0

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        return obs, (float("nan") if self.steps > self.after else reward), terminated, truncated, info


class SigintAt(gym.Wrapper):
    """Sends this process a SIGINT during env step ``at``, as a Ctrl-C mid-episode would."""

    def __init__(self, env, at):
        super().__init__(env)
        self.at, self.steps = at, 0

    def step(self, action):
        self.steps += 1
        if self.steps == self.at:
            os.kill(os.getpid(), signal.SIGINT)
        return self.env.step(action)
