"""``SeedAxisLearner``: what the episode loop (``train/loop.PartsAxis``) calls on a learner
that holds a seed axis. Every array in or out has the seed axis first (``[S, ...]``).

Three kinds implement it: ``learners/stacked.SoloAsStack`` (any solo learner, S=1, call for
call the solo run), post 001's stacked Keras learner (``learners/stacked.py``; posts 000 and
003's were retired for the compiled engine) and the stacked PyTorch learner
(``torch/stacked.py``). ``takes_masks`` says whether ``train`` accepts a ``mask`` (post 001's
bursts, where seeds train different numbers of batches on one env step); the loop refuses such
a batch for a learner without it, before it trains.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np


class SeedAxisLearner(Protocol):
    loss_names: Sequence[str]
    takes_masks: bool

    def compile(self) -> None:
        """Trace the compiled steps (the loop calls it once, before its first env step)."""

    def act(self, states: np.ndarray) -> np.ndarray:
        """Each seed's policy action for its state."""

    def train(self, rows: np.ndarray, mask: np.ndarray | None = None) -> Mapping[str, Any]:
        """One update per seed on its rows ``[S, B, width]``; each loss ``[S]``. ``mask``
        (only where ``takes_masks``): the seeds that train; the others' slices stand still."""

    def train_and_act(
        self, rows: np.ndarray, states: np.ndarray, separate: bool = False
    ) -> tuple[Mapping[str, Any], Any]:
        """``train`` then ``act`` (fused into one call unless ``separate``)."""

    def step_without_batch(self, states: np.ndarray, episode_ended: bool = False) -> np.ndarray:
        """An env step with nothing to train on yet: the every-step work, and the next actions."""

    def slice_state(self, k: int) -> dict:
        """Seed k's part of the learner's state, for its checkpoint."""

    def load_slice_state(self, k: int, state: dict) -> None: ...

    def save_slice(self, k: int, run_dir) -> None:
        """Seed k's final weights into its run folder."""
