"""Multi-seed statistics for comparing two sets of runs (SciPy and statsmodels underneath).

- ``median_difference_ci``: a percentile-bootstrap 95% CI of median(a) - median(b), the
  two samples resampled independently (``scipy.stats.bootstrap``).
- ``mann_whitney``: the two-sided Mann-Whitney U test (``scipy.stats.mannwhitneyu``).
- ``success_difference_ci``: a difference of two success rates with Newcombe's hybrid score
  95% interval, built from each rate's Wilson interval (statsmodels'
  ``confint_proportions_2indep``); unlike a bootstrap it stays informative at 10/10 and 0/10.
- ``iqm_ci``: the interquartile mean (the mean of the middle 50%, ``trim_mean(x, 0.25)``)
  with rliable's stratified-bootstrap percentile CI. rliable resamples runs with
  replacement *within each task* and recomputes the aggregate; with one task per
  comparison, as here, that is the ordinary bootstrap over seeds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats
from statsmodels.stats.proportion import confint_proportions_2indep


def iqm(x, axis=None):
    """Interquartile mean: the 25%-trimmed mean (rliable's ``aggregate_iqm``); one number, or one per
    row along ``axis`` (the bootstrap's resamples)."""
    value = stats.trim_mean(np.asarray(x, float), 0.25, axis=axis)
    return float(value) if axis is None else value


@dataclass(frozen=True)
class Interval:
    estimate: float
    low: float
    high: float

    def __str__(self) -> str:
        return f"{self.estimate:.4g} [{self.low:.4g}, {self.high:.4g}]"


def bootstrap_interval(
    samples: tuple, statistic, rng: np.random.Generator, n_resamples: int, confidence: float = 0.95
) -> tuple[float, float]:
    """A percentile-bootstrap interval of ``statistic(*samples, axis=-1)``, which takes every
    resample at once as the rows of its arguments (the same resamples, and the same numbers, as one
    call per resample; 10,000 calls were most of a forest row's time)."""
    if any(len(s) < 2 for s in samples) or all(np.ptp(s) == 0 for s in samples):
        value = statistic(*samples, axis=-1)  # a degenerate sample has a degenerate interval
        return float(value), float(value)
    res = stats.bootstrap(
        samples,
        statistic,
        n_resamples=n_resamples,
        confidence_level=confidence,
        method="percentile",
        vectorized=True,
        random_state=rng,
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def median_difference_ci(a, b, rng: np.random.Generator | None = None, n_resamples: int = 10_000) -> Interval:
    """median(a) - median(b) with a 95% percentile-bootstrap interval."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    rng = np.random.default_rng(0) if rng is None else rng

    def diff(x, y, axis=-1):
        return np.median(x, axis=axis) - np.median(y, axis=axis)

    low, high = bootstrap_interval((a, b), diff, rng, n_resamples)
    return Interval(float(diff(a, b)), low, high)


def iqm_ci(x, rng: np.random.Generator | None = None, n_resamples: int = 10_000) -> Interval:
    """IQM of one set of runs with a 95% (stratified, one task) bootstrap interval."""
    x = np.asarray(x, float)
    rng = np.random.default_rng(0) if rng is None else rng
    low, high = bootstrap_interval((x,), iqm, rng, n_resamples)
    return Interval(iqm(x), low, high)


def mann_whitney(a, b) -> tuple[float, float]:
    """(U statistic of ``a``, two-sided p-value); (nan, nan) when either sample is empty."""
    if len(a) == 0 or len(b) == 0:
        return float("nan"), float("nan")
    res = stats.mannwhitneyu(a, b, alternative="two-sided")
    return float(res.statistic), float(res.pvalue)


def censored_mann_whitney(a, b, budget: int) -> tuple[float, float]:
    """``mann_whitney`` over every seed: a seed that never reached the threshold (None) counts
    as ``budget + 1``, tied with the others that never did and ranked after every seed that
    did. With all censoring at one time this is Gehan's test, the treatment ``check`` uses and
    the one the median ratio's ``budget + 1`` matches; dropping those seeds instead would test
    the successes only."""
    x, y = ([budget + 1 if v is None else v for v in arm] for arm in (a, b))
    if len(x) and len(y) and len(set(x) | set(y)) == 1:
        return float("nan"), 1.0  # every seed tied: nothing tells the arms apart
    return mann_whitney(x, y)


def fisher_exact(successes_a: int, n_a: int, successes_b: int, n_b: int) -> float:
    """Two-sided Fisher exact test p-value for two success rates (SciPy's ``fisher_exact``)."""
    for s, n in ((successes_a, n_a), (successes_b, n_b)):
        if not 0 <= s <= n:
            raise ValueError(f"successes must lie in [0, n], got {s} of {n}")
    table = [[successes_a, n_a - successes_a], [successes_b, n_b - successes_b]]
    return float(stats.fisher_exact(table, alternative="two-sided").pvalue)


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """A success rate's Wilson score interval (``scipy.stats.binomtest``), as the tables give it."""
    ci = stats.binomtest(successes, n).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def success_difference_ci(successes_a: int, n_a: int, successes_b: int, n_b: int, confidence: float = 0.95) -> Interval:
    """rate(a) - rate(b) with Newcombe's (1998, method 10) hybrid score interval at
    ``confidence`` (95% by default), from each rate's Wilson score interval (statsmodels'
    ``confint_proportions_2indep``, method ``newcomb``)."""
    for k, n in ((successes_a, n_a), (successes_b, n_b)):
        if n < 1 or not 0 <= k <= n:
            raise ValueError(f"successes must lie in [0, n] with n >= 1, got {k} of {n}")
    low, high = confint_proportions_2indep(
        successes_a, n_a, successes_b, n_b, method="newcomb", compare="diff", alpha=1 - confidence
    )
    return Interval(successes_a / n_a - successes_b / n_b, float(low), float(high))
