"""Training schedules: when, after storing a step's transitions, the learner trains.

``after_store(learner, buffer, total_steps, next_state, over)`` runs the step's updates and
returns ``(losses of each update, the next action or None)``. A schedule that can fuse the
last update with picking the next action does (one compiled call); when it returns no
action and the episode goes on, the agent asks the learner for one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class EveryStep:
    """One update per env step once the buffer holds ``train_start`` transitions.

    Post 000 §2.4 (``if len(agent.memory) >= agent.train_start: agent.train_model()``),
    post 003 (``optimize_model()`` returns early below ``BATCH_SIZE``) and post 001's fixed
    variant. ``fuse_act``: train and pick the next action in one compiled call (posts 000
    and 003); post 001 acts through a separate ``predict``.
    """

    train_start: int
    batch_size: int
    every: int = 1
    fuse_act: bool = True

    def after_store(self, learner, buffer, total_steps: int, next_state, over: bool) -> tuple[list, Any]:
        if len(buffer) >= self.train_start and total_steps % self.every == 0:
            rows = buffer.sample_rows(self.batch_size)  # random.sample: without replacement
            if over or not self.fuse_act:
                return [learner.train(rows)], None
            losses, action = learner.train_and_act(rows, next_state)
            return [losses], action
        return [], learner.act_without_update(next_state, want_action=not over)


@dataclass(frozen=True)
class Bursts:
    """Post 001 P001-TRIGGER: ``if len(agent.memory) > 1000: agent.train()`` every env step,
    and ``train()`` pops batch after batch ``while len(self.memory) > 100``, each its own
    update (with its soft update). The trigger is strict: ``> train_start``."""

    train_start: int
    train_down_to: int
    batch_size: int

    def after_store(self, learner, buffer, total_steps: int, next_state, over: bool) -> tuple[list, Any]:
        losses = []
        if len(buffer) > self.train_start:
            while len(buffer) > self.train_down_to:
                losses.append(learner.train(buffer.sample_rows(self.batch_size)))
        return losses, None
