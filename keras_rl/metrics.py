"""Per-episode progress metrics, each as the post computed it."""

from __future__ import annotations

import math


import operator

COMPARISONS = {">": operator.gt, ">=": operator.ge, "<=": operator.le, "<": operator.lt}


class Metric:
    """A per-episode progress metric: ``update(score) -> value``, and ``passes`` to judge it."""

    comparison = ">="

    def passes(self, value: float, threshold: float) -> bool:
        """Whether ``value`` meets ``threshold`` by this metric's comparison (never for NaN)."""
        return math.isfinite(value) and COMPARISONS[self.comparison](value, threshold)


class PostEMA(Metric):
    """Post 000 §2.4: ``score_avg = 0.9 * score_avg + 0.1 * score if score_avg != 0 else score``.

    The average starts at 0 and 0 means "not started", so the first score initialises
    it. Faithfully, an average that lands exactly on 0.0 would restart from the next
    score; with Pendulum's real-valued returns that does not happen in practice.
    Success is ``score_avg > -300``: strictly above.
    """

    comparison = ">"

    def __init__(self, decay: float = 0.9):
        self.decay = decay
        self.value = 0.0

    def update(self, score: float) -> float:
        self.value = self.decay * self.value + (1 - self.decay) * score if self.value != 0 else score
        return self.value


class RollingMean(Metric):
    """Post 003's ``plot_durations``: the mean of the last ``window`` durations.

    The tutorial plots ``torch.cat((torch.zeros(99), means))``: zero until ``window``
    episodes exist, then ``unfold(0, 100, 1).mean(1)``. We report the same numbers.
    """

    def __init__(self, window: int = 100):
        self.window = window
        self.scores: list[float] = []

    def update(self, score: float) -> float:
        self.scores.append(score)
        if len(self.scores) < self.window:
            return 0.0
        return sum(self.scores[-self.window:]) / self.window


class GoalShare(Metric):
    """Post 001 (MountainCarContinuous): the share of the last ``window`` episodes that
    reached the goal. An episode reached it iff its return is positive: the goal pays
    +100 and the action cost is at most 0.1 per step over at most 999 steps."""

    def __init__(self, window: int = 50):
        self.window = window
        self.hits: list[bool] = []

    def update(self, score: float) -> float:
        self.hits.append(score > 0)
        recent = self.hits[-self.window:]
        return sum(recent) / self.window




class ReturnSpread(Metric):
    """Post 001's "roughly converged": the spread (max - min) of the last ``window`` returns.

    Infinite until ``window`` episodes exist. Success is a spread at or below the threshold.
    """

    comparison = "<="

    def __init__(self, window: int = 10):
        self.window = window
        self.scores: list[float] = []

    def update(self, score: float) -> float:
        self.scores.append(score)
        if len(self.scores) < self.window:
            return float("inf")
        recent = self.scores[-self.window:]
        return max(recent) - min(recent)

    def passes(self, value: float, threshold: float) -> bool:
        return value <= threshold  # inf (too few episodes) never passes; NaN never passes
