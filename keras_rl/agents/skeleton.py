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
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
                raise NonFiniteLossError(
                    f"{name} became {value} at update {self.total_updates} ({where}); "
                    "the run stops here and keeps the episodes already written"
                )
            self.sums[name] += value

    def stats(self) -> EpisodeStats:
        n = self.updates
        return EpisodeStats(n, {k: (v / n if n else None) for k, v in self.sums.items()})


def run_updates(learner, batches: list, fuse_act: bool, next_state, want_action: bool) -> tuple[list, Any]:
    """A solo learner's calls for one env step's update batches (``schedules.py``): every
    update in turn, the last fused with picking the next action where the schedule allows
    it and an action is wanted; a step without updates is ``step_without_batch`` (post 003
    still soft-updates then). Returns (losses of each update, the next action or None)."""
    losses = [learner.train(rows) for rows in batches[:-1]]
    if not batches:
        return losses, learner.step_without_batch(next_state, want_action=want_action)
    if want_action and fuse_act:
        last, action = learner.train_and_act(batches[-1], next_state)
        return [*losses, last], action
    losses.append(learner.train(batches[-1]))
    return losses, (learner.act(next_state) if want_action else None)


class Agent:
    """A learner, a buffer and three strategies, driven one env step at a time.

    The verbs (``begin_episode``, ``step``, ``end_episode``) run one seed with its own
    learner. Each is built from phases that never call the learner (``start_episode``,
    ``store``, ``record_losses``, ``explore``): the episode loop (``train/loop.py``) drives
    those for every seed of a seed axis and makes one learner call for all of them.
    """

    def __init__(self, learner, buffer, transitions, schedule, explorer):
        self.learner, self.buffer = learner, buffer
        self.transitions, self.schedule, self.explorer = transitions, schedule, explorer
        self.loss_names: tuple[str, ...] = tuple(learner.loss_names)
        self.tally = LossTally(self.loss_names)
        self.total_steps = 0
        self.state: np.ndarray | None = None
        """The state the policy acts on next."""
        self._action: Any = None

    # -- the verbs (one seed, its own learner) -----------------------------------------------
    def begin_episode(self, obs) -> Any:
        self.reset_episode_stats()
        return self.explore(self.learner.act(self.start_episode(obs)))

    def step(self, reward: float, obs, terminated: bool, truncated: bool) -> Any:
        """Store, train, and return the next action (None once the episode is over)."""
        over = terminated or truncated
        batches = self.store(reward, obs, terminated, truncated)
        losses, action = run_updates(self.learner, batches, self.schedule.fuse_act, self.state, not over)
        self.record_losses(losses)
        return None if over else self.explore(action)

    # -- the phases (no learner call) ---------------------------------------------------------
    def reset_episode_stats(self) -> None:
        self.explorer.reset()  # post 000 §2.4: pre_noise = np.zeros(action_size)
        self.tally.reset()

    def start_episode(self, obs) -> np.ndarray:
        """A new episode's first observation; returns the state to act on."""
        self.transitions.begin_episode()
        self.state = self.transitions.observe(obs)
        return self.state

    def store(self, reward: float, obs, terminated: bool, truncated: bool) -> list:
        """An env step's transitions into the buffer; returns the step's update batches."""
        self.total_steps += 1
        self.buffer.add_rows(self.transitions.rows(self.state, self._action, reward, obs, terminated, truncated))
        self.state = self.transitions.observe(obs)
        return self.schedule.batches(self.buffer, self.total_steps)

    def record_losses(self, losses) -> None:
        """Each update's losses into the episode's tally (a non-finite one raises)."""
        for one in losses:
            self.tally.add(one, f"env step {self.total_steps}")

    def explore(self, action) -> Any:
        """The explorer's action from the policy's, which the next ``store`` pairs with the state."""
        self._action = self.explorer(action)
        return self._action

    def end_episode(self) -> EpisodeStats:
        return self.tally.stats()

    def parts_state(self) -> dict[str, Any]:
        """Everything but the learner that the agent carries between env steps, mid-episode
        included (``--resume``; a seed axis checkpoints its learner slice apart)."""
        return {
            "buffer": self.buffer.state_dict(),
            "transitions": self.transitions.state_dict(),
            "explorer": self.explorer.state_dict(),
            "total_steps": self.total_steps,
            "tally": {
                "sums": dict(self.tally.sums),
                "updates": self.tally.updates,
                "total_updates": self.tally.total_updates,
            },
            "state": None if self.state is None else self.state.copy(),
            "action": self._action,
        }

    def load_parts_state(self, state: dict[str, Any]) -> None:
        self.buffer.load_state_dict(state["buffer"])
        self.transitions.load_state_dict(state["transitions"])
        self.explorer.load_state_dict(state["explorer"])
        self.total_steps = int(state["total_steps"])
        tally = state["tally"]
        self.tally.sums, self.tally.updates = dict(tally["sums"]), int(tally["updates"])
        self.tally.total_updates = int(tally["total_updates"])
        self.state, self._action = state["state"], state["action"]

    def state_dict(self) -> dict[str, Any]:
        """The learner's state and the parts' (for ``--resume``)."""
        return {"learner": self.learner.state_dict(), **self.parts_state()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.learner.load_state_dict(state["learner"])
        self.load_parts_state(state)

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
