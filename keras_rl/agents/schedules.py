"""Training schedules: which updates an env step makes, once its transitions are stored.

``batches(buffer, total_steps)`` draws the step's training batches (packed rows, one per
update; none when the step does not train). ``fuse_act``: the step's last update and the
next action may be one compiled call (the posts pick step t+1's action with the weights
step t's update made). The schedule only decides; the agent (``skeleton.run_updates``) or
the episode loop (``train/loop.py``, for a seed axis) turns the batches into learner calls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    train_every: int = 1
    fuse_act: bool = True

    def batches(self, buffer, total_steps: int) -> list[np.ndarray]:
        if len(buffer) >= self.train_start and total_steps % self.train_every == 0:
            return [buffer.sample_rows(self.batch_size)]  # random.sample: without replacement
        return []


@dataclass(frozen=True)
class Bursts:
    """Post 001 P001-TRIGGER: ``if len(agent.memory) > 1000: agent.train()`` every env step,
    and ``train()`` pops batch after batch ``while len(self.memory) > 100``, each its own
    update (with its soft update). The trigger is strict: ``> train_start``. The batches
    are popped before the first update; the buffer draws from its own generator, which no
    update touches, so they are the batches the post pops one update at a time."""

    train_start: int
    train_down_to: int
    batch_size: int
    fuse_act: bool = False  # agent.get_action is its own predict

    def batches(self, buffer, total_steps: int) -> list[np.ndarray]:
        out = []
        if len(buffer) > self.train_start:
            while len(buffer) > self.train_down_to:
                out.append(buffer.sample_rows(self.batch_size))
        return out
