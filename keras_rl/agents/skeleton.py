"""The one agent skeleton, with Dopamine's three verbs.

    action = agent.begin_episode(obs)
    while action is not None:
        obs, reward, terminated, truncated, _ = env.step(action)
        action = agent.step(reward, obs, terminated, truncated)
    stats = agent.end_episode()          # EpisodeStats: updates, mean losses

Every post runs this same body. They differ only in the parts handed in: the learner
(``learners/table.py``), the buffer, the ``TransitionRule`` (what is stored), the schedule
(when it trains) and the explorer (how it explores). A post's builder in
``keras_rl/posts/`` sets those from its config.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from keras_rl.errors import NonFiniteLossError


@dataclass(frozen=True)
class EpisodeStats:
    updates: int
    """Learner updates during the episode."""
    mean_losses: dict[str, float | None]
    """Each loss averaged over the episode's updates (None when it had none)."""


class LossTally:
    """Per-episode sums of each loss; a non-finite loss stops the run, naming the loss and where."""

    def __init__(self, names: tuple[str, ...]):
        self.names = tuple(names)
        self.total_updates = 0
        self.reset()

    def reset(self) -> None:
        self.sums = dict.fromkeys(self.names, 0.0)
        self.updates = 0

    def add(self, losses: Mapping[str, Any], where: str) -> None:
        self.updates += 1
        self.total_updates += 1
        for name, value in losses.items():
            value = float(value)
            if not math.isfinite(value):
                raise NonFiniteLossError(f"{name} became {value} at update {self.total_updates} ({where}); "
                                         "the run stops here and keeps the episodes already written")
            self.sums[name] += value

    def stats(self) -> EpisodeStats:
        n = self.updates
        return EpisodeStats(n, {k: (v / n if n else None) for k, v in self.sums.items()})


class Agent:
    """A learner, a buffer and three strategies, driven one env step at a time."""

    def __init__(self, learner, buffer, transitions, schedule, explorer):
        self.learner, self.buffer = learner, buffer
        self.transitions, self.schedule, self.explorer = transitions, schedule, explorer
        self.loss_names: tuple[str, ...] = tuple(learner.loss_names)
        self.tally = LossTally(self.loss_names)
        self.total_steps = 0
        self._state: np.ndarray | None = None
        self._action: Any = None

    def begin_episode(self, obs) -> Any:
        self.explorer.reset()  # post 000 §2.4: pre_noise = np.zeros(action_size)
        self.tally.reset()
        self.transitions.begin_episode()
        self._state = self.transitions.observe(obs)
        self._action = self.explorer(self.learner.act(self._state))
        return self._action

    def step(self, reward: float, obs, terminated: bool, truncated: bool) -> Any:
        """Store, train, and return the next action (None once the episode is over)."""
        self.total_steps += 1
        over = terminated or truncated
        self.buffer.add_rows(self.transitions.rows(self._state, self._action, reward, obs, terminated, truncated))
        next_state = self.transitions.observe(obs)
        losses, action = self.schedule.after_store(self.learner, self.buffer, self.total_steps, next_state, over)
        for one in losses:
            self.tally.add(one, f"env step {self.total_steps}")
        if over:
            return None
        if action is None:
            action = self.learner.act(next_state)
        self._state, self._action = next_state, self.explorer(action)
        return self._action

    def end_episode(self) -> EpisodeStats:
        return self.tally.stats()

    def state_dict(self) -> dict[str, Any]:
        """Everything the agent carries from one episode to the next (for ``--resume``)."""
        return {"learner": self.learner.state_dict(), "buffer": self.buffer.state_dict(),
                "transitions": self.transitions.state_dict(), "explorer": self.explorer.state_dict(),
                "total_steps": self.total_steps, "total_updates": self.tally.total_updates}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.learner.load_state_dict(state["learner"])
        self.buffer.load_state_dict(state["buffer"])
        self.transitions.load_state_dict(state["transitions"])
        self.explorer.load_state_dict(state["explorer"])
        self.total_steps, self.tally.total_updates = int(state["total_steps"]), int(state["total_updates"])

    @property
    def updates(self) -> int:
        """Updates over the whole run."""
        return self.tally.total_updates

    def greedy_action(self, obs) -> Any:
        """The policy's action with no exploration (post 000 §3's test section)."""
        return self.learner.act(self.transitions.observe(obs))

    def save(self, run_dir: Path) -> None:
        self.learner.save(run_dir)

    def load_policy(self, run_dir: Path) -> None:
        self.learner.load_policy(run_dir)
