"""Per-episode progress metrics, each as the post computed it."""

from __future__ import annotations

import math


class PostEMA:
    """Post 000 §2.4: ``score_avg = 0.9 * score_avg + 0.1 * score if score_avg != 0 else score``.

    The average starts at 0 and 0 means "not started", so the first score initialises
    it. Faithfully, an average that lands exactly on 0.0 would restart from the next
    score; with Pendulum's real-valued returns that does not happen in practice.
    """

    def __init__(self, decay: float = 0.9):
        self.decay = decay
        self.value = 0.0

    def update(self, score: float) -> float:
        self.value = self.decay * self.value + (1 - self.decay) * score if self.value != 0 else score
        return self.value


def crossed(value: float, threshold: float, inclusive: bool) -> bool:
    """Whether ``value`` passes ``threshold`` (``>=`` when inclusive, else ``>``)."""
    if not math.isfinite(value):
        return False
    return value >= threshold if inclusive else value > threshold
