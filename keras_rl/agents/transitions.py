"""Transition rules: what a step puts in the buffer, and when.

The posts disagree on which done flag is stored, on normalising states, and on whether a
transition is stored as it happens or at the episode's end with its reward replaced.
``TransitionRule`` holds those choices; a post's builder sets them from its quirk switches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from keras_rl.buffers import Layout

DoneFlag = Literal["terminated", "truncated", "either"]


@dataclass
class TransitionRule:
    layout: Layout
    done_flag: DoneFlag = "terminated"
    """Which of env.step's flags is stored as ``done`` (zeroing the bootstrap):
    ``terminated`` (correct), ``truncated`` (post 000's P000-DONE) or ``either`` (post 001's
    old 4-tuple ``done``, P001-DONE)."""
    obs_low: np.ndarray | None = None
    obs_span: np.ndarray | None = None
    """When set, states are normalised to ``(obs - low) / span`` (post 001)."""
    store_raw_next_state: bool = False
    """Store ``next_state`` un-normalised (post 001's P001-NEXTSTATE)."""
    episode_rewards: Callable[[list[float]], np.ndarray] | None = None
    """When set, a transition is held until its episode ends, and then all of the episode's
    rewards are replaced by ``episode_rewards(rewards)`` (post 001's P001-RETURNS)."""

    def __post_init__(self) -> None:
        self._held: list[np.ndarray] = []

    def begin_episode(self) -> None:
        self._held = []

    def state_dict(self) -> dict:
        return {"held": [row.copy() for row in self._held]}

    def load_state_dict(self, state: dict) -> None:
        self._held = [np.array(row) for row in state["held"]]

    def observe(self, obs) -> np.ndarray:
        """The state the policy sees: float32, normalised where the post normalises."""
        state = np.asarray(obs, dtype=np.float32)
        if self.obs_low is not None:
            state = (state - self.obs_low) / self.obs_span
        return state

    def rows(self, state: np.ndarray, action, reward: float, obs, terminated: bool, truncated: bool) -> np.ndarray:
        """The packed rows ``[k, width]`` to store after this step (``k`` may be 0)."""
        done = {"terminated": terminated, "truncated": truncated, "either": terminated or truncated}[self.done_flag]
        next_state = (
            np.asarray(obs, np.float32) if self.obs_low is None or self.store_raw_next_state else self.observe(obs)
        )
        row = np.concatenate([state, np.ravel(action), [reward], next_state, [float(done)]]).astype(np.float32)
        if self.episode_rewards is None:
            return row[None, :]
        self._held.append(row)
        if not (terminated or truncated):
            return np.empty((0, self.layout.width), np.float32)
        rows = np.stack(self._held)
        col = self.layout.obs_dim + self.layout.action_dim  # the reward column
        # the rewards as stored (float32), back to float64 for the post's arithmetic
        rows[:, col] = self.episode_rewards(rows[:, col].astype(np.float64).tolist())
        self._held = []
        return rows
