"""Comparing networks' weights, as the stacked-learner tests do."""

from __future__ import annotations

import numpy as np


def max_gap(a: dict, b: dict) -> float:
    """The largest absolute difference between two {network: [arrays]} maps of the same shapes."""
    return max(float(np.max(np.abs(x - y))) for name in a for x, y in zip(a[name], b[name], strict=True))
