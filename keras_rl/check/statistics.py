"""Per-seed statistics of a run, the decision between two samples of them, and the decision
rule's error rates by resampling.

A statistic reads one seed's ``episodes.csv`` rows, cut to the first ``episodes`` episodes
(a tier may look at fewer episodes than the post's budget: runs are prefixes of longer runs,
since nothing in a run depends on its budget):

- ``episodes_to_threshold``: the first episode whose metric meets the threshold; a seed that
  never gets there counts as ``episodes + 1`` (censored: it ranks after every seed that did);
- ``success``: 1 if it got there (post 001: if the metric meets it after the last episode);
- ``auc``: the area under the learning curve, the mean score over the episodes; a run that
  stopped at the threshold (post 000) counts its last metric, an average of scores on the
  score's scale, for each episode it did not play;
- ``final_metric``: the metric after the last episode;
- ``median_score``: the median of the episodes' scores (a run that stopped at the threshold
  counts its last metric for each episode it did not play, as ``auc`` does). Post 001's
  faithful metric swings between seeds; its scores' median does not (issue 35's sensitive tier).

``decide`` compares the baseline's values with the new ones: a two-sided Mann-Whitney U test,
or Fisher's exact test for ``success``; "changed" when p < alpha, in either direction (for a
faithful reproduction, learning faster is a change in fidelity too).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats
from statsmodels.stats.multitest import multipletests

from keras_rl.report.stats import fisher_exact, mann_whitney

STATISTICS = ("episodes_to_threshold", "success", "auc", "final_metric", "median_score")


def _metrics(rows: list[dict[str, Any]], episodes: int) -> list[float]:
    out = [float("nan") if r["metric"] is None else float(r["metric"]) for r in rows[:episodes]]
    if len(out) < episodes and out:  # stopped at the threshold: it stays solved
        out += [out[-1]] * (episodes - len(out))
    return out


def seed_statistic(
    name: str, rows: list[dict[str, Any]], episodes: int, passes: Callable[[float], bool], success_at_end: bool = False
) -> float:
    """Statistic ``name`` of one seed's episode rows, cut to ``episodes``."""
    if name not in STATISTICS:
        raise ValueError(f"unknown statistic {name!r}; choose one of {', '.join(STATISTICS)}")
    if not rows:
        raise ValueError("a run with no episodes has no statistic")
    metrics = _metrics(rows, episodes)
    reached = next((i + 1 for i, m in enumerate(metrics[: len(rows)]) if passes(m)), None)
    if name == "episodes_to_threshold":
        return float(reached if reached is not None else episodes + 1)
    if name == "success":
        complete = len(rows) >= episodes
        return float(passes(metrics[-1]) and complete if success_at_end else reached is not None)
    if name in ("auc", "median_score"):
        scores = [float(r["score"]) for r in rows[:episodes]]
        scores += [metrics[-1]] * (episodes - len(scores))
        return float(np.mean(scores) if name == "auc" else np.median(scores))
    return metrics[-1]


def settles_at_threshold(name: str, success_at_end: bool = False) -> bool:
    """Whether a seed's first crossing of its threshold settles statistic ``name``, so that nothing
    it plays after can move it: episodes to the threshold, and ``success`` read at any time (post
    001's, read after the last episode, is not). A check's solo seeds stop there."""
    return name == "episodes_to_threshold" or (name == "success" and not success_at_end)


@dataclass(frozen=True)
class Decision:
    p: float
    changed: bool
    test: str
    statistic_value: float
    """The test's statistic (Mann-Whitney U of the new sample, or Fisher's odds ratio input)."""


def decide(
    baseline: Sequence[float] | np.ndarray, new: Sequence[float] | np.ndarray, statistic: str, alpha: float
) -> Decision:
    """Two-sided test of ``new`` against ``baseline``; changed when p < alpha."""
    base, fresh = np.asarray(baseline, float), np.asarray(new, float)
    if len(base) == 0 or len(fresh) == 0:
        raise ValueError("both samples need at least one seed")
    test = "Fisher's exact test (two-sided)" if statistic == "success" else "Mann-Whitney U (two-sided)"
    if np.isnan(base).any() or np.isnan(fresh).any():  # a run that blew up is a change in itself
        return Decision(0.0, True, test, float("nan"))
    if statistic == "success":
        p = fisher_exact(int(fresh.sum()), len(fresh), int(base.sum()), len(base))
        return Decision(p, p < alpha, test, float(fresh.mean()))
    if np.ptp(np.concatenate([base, fresh])) == 0:  # all equal: nothing to tell apart
        return Decision(1.0, False, "Mann-Whitney U (two-sided)", float("nan"))
    u, p = mann_whitney(fresh, base)
    return Decision(p, p < alpha, "Mann-Whitney U (two-sided)", u)


PAIRED_TEST = "Wilcoxon signed-rank on twins (two-sided)"


def paired_differences(
    baseline: Sequence[float] | np.ndarray, new: Sequence[float] | np.ndarray, statistic: str
) -> np.ndarray:
    """Each twin's difference ``new - baseline``: of the logs for episodes to threshold (a change
    of learning speed is a ratio: 10% slower is the same step for a fast seed and a slow one), of
    the values for the other statistics. Shape ``[..., n]``, twins in the last axis."""
    base, fresh = np.asarray(baseline, float), np.asarray(new, float)
    if base.shape != fresh.shape:
        raise ValueError(f"twins pair one to one: {base.shape} baseline values against {fresh.shape} new")
    if statistic == "episodes_to_threshold":
        return np.log(fresh) - np.log(base)
    return fresh - base


def decide_paired(
    baseline: Sequence[float] | np.ndarray, new: Sequence[float] | np.ndarray, statistic: str, alpha: float
) -> Decision:
    """Two-sided test of twins, ``new[i]`` the rerun of the seed of ``baseline[i]``: Wilcoxon's
    signed-rank test on ``paired_differences``, zero differences dropped (a twin whose statistic did
    not move says nothing about the direction); no non-zero difference gives p = 1. For
    ``success``, the signs of the discordant twins (McNemar's exact test, the same test for 0/1
    differences). Changed when p < alpha."""
    d = paired_differences(baseline, new, statistic)
    if len(d) == 0:
        raise ValueError("a paired test needs at least one twin")
    if np.isnan(d).any():  # a run that blew up is a change in itself
        return Decision(0.0, True, PAIRED_TEST, float("nan"))
    moved = d[d != 0]
    if len(moved) == 0:
        return Decision(1.0, False, PAIRED_TEST, 0.0)
    if statistic == "success":
        up = int((moved > 0).sum())
        p = float(stats.binomtest(up, len(moved), 0.5).pvalue)
        return Decision(p, p < alpha, "McNemar's exact test on twins (two-sided)", float(up))
    result = stats.wilcoxon(moved, zero_method="wilcox")
    p = float(result.pvalue)
    return Decision(p, p < alpha, PAIRED_TEST, float(result.statistic))


def paired_changed_many(differences: np.ndarray, alpha: float) -> np.ndarray:
    """``decide_paired(...).changed`` for every row of twin differences at once (the calibration's
    thousands of resampled checks); rows of all-zero differences are never changed."""
    d = np.atleast_2d(np.asarray(differences, float))
    changed = np.isnan(d).any(axis=1)
    live = ~changed & (d != 0).any(axis=1)
    if live.any():
        with np.errstate(invalid="ignore", divide="ignore"):
            p = stats.wilcoxon(d[live], zero_method="wilcox", axis=1).pvalue
        changed[live] = np.nan_to_num(p, nan=1.0) < alpha
    return changed


def changed_many(
    baselines: Sequence[Sequence[float]] | np.ndarray,
    news: Sequence[Sequence[float]] | np.ndarray,
    statistic: str,
    alpha: float,
) -> np.ndarray:
    """``decide(baselines[i], news[i], statistic, alpha).changed`` for every row at once: the
    calibrations' thousands of resampled checks in one SciPy call per p-value method instead
    of one call each. Each row takes the method ``decide`` would (SciPy's ``auto``: exact for
    a sample of at most 8 without ties, the normal approximation otherwise)."""
    base, fresh = np.atleast_2d(np.asarray(baselines, float)), np.atleast_2d(np.asarray(news, float))
    if base.shape[0] != fresh.shape[0]:
        raise ValueError(f"{base.shape[0]} baselines for {fresh.shape[0]} new samples")
    if statistic == "success":  # Fisher's test has no vectorised form in SciPy
        return np.array([decide(b, f, statistic, alpha).changed for b, f in zip(base, fresh)], bool)
    both = np.concatenate([fresh, base], axis=1)
    changed = np.isnan(both).any(axis=1)  # a run that blew up is a change in itself
    live = ~changed & (np.ptp(np.where(changed[:, None], 0.0, both), axis=1) != 0)  # all equal: no change
    tied = (np.diff(np.sort(both, axis=1), axis=1) == 0).any(axis=1)
    small = min(fresh.shape[1], base.shape[1]) <= 8
    for method, rows in (("exact", live & ~tied & small), ("asymptotic", live & (tied | (not small)))):
        if rows.any():
            p = stats.mannwhitneyu(fresh[rows], base[rows], alternative="two-sided", method=method, axis=1).pvalue
            changed[rows] = p < alpha
    return changed


def smallest_p(statistic: str, n_baseline: int, n_new: int) -> float:
    """The smallest p ``decide`` can give for these sample sizes: the most extreme outcome
    (every fresh seed beyond every baseline seed, or the success rates 0 against 1)."""
    if statistic == "success":
        return decide(np.ones(n_baseline), np.zeros(n_new), statistic, 0.5).p
    return decide(np.arange(n_baseline), np.arange(n_baseline, n_baseline + n_new), statistic, 0.5).p


def false_alarm_rate(
    baseline: Sequence[float] | np.ndarray,
    n: int,
    statistic: str,
    alpha: float,
    repeats: int = 10_000,
    rng: np.random.Generator | None = None,
) -> float:
    """How often the rule cries "changed" when nothing changed: draw ``n`` of the baseline's
    seeds as the "new" runs, test them against the rest, ``repeats`` times."""
    rng = rng if rng is not None else np.random.default_rng(0)
    values = np.asarray(baseline, float)
    if not 0 < n < len(values):
        raise ValueError(f"need 0 < n < {len(values)} baseline seeds, got n={n}")
    picks = np.stack([rng.permutation(len(values)) for _ in range(repeats)])
    return int(changed_many(values[picks[:, n:]], values[picks[:, :n]], statistic, alpha).sum()) / repeats


def power(
    baseline: Sequence[float] | np.ndarray,
    changed: Sequence[float] | np.ndarray,
    n: int,
    statistic: str,
    alpha: float,
    repeats: int = 2_000,
    rng: np.random.Generator | None = None,
) -> float:
    """How often the rule flags a changed learner: ``n`` seeds drawn (with replacement) from
    the changed runs, tested against the whole baseline, ``repeats`` times."""
    rng = rng if rng is not None else np.random.default_rng(1)
    values, other = np.asarray(baseline, float), np.asarray(changed, float)
    fresh = np.stack([other[rng.integers(0, len(other), n)] for _ in range(repeats)])
    return int(changed_many(np.broadcast_to(values, (repeats, len(values))), fresh, statistic, alpha).sum()) / repeats


def detectable_shift(
    baseline: Sequence[float] | np.ndarray,
    n: int,
    alpha: float,
    target: float = 0.8,
    budget: int | None = None,
    repeats: int = 500,
    rng: np.random.Generator | None = None,
) -> int | None:
    """The smallest shift d (in episodes) of episodes-to-threshold that the rule flags with
    probability ``target``: "new" runs are baseline seeds drawn with replacement, d episodes
    slower (capped at the censoring value ``budget + 1``). None if no shift up to the budget is."""
    values = np.asarray(baseline, float)
    cap = budget + 1 if budget is not None else np.inf
    limit = int(budget if budget is not None else values.max())
    lo, hi = 0, limit
    if power(values, np.minimum(values + hi, cap), n, "episodes_to_threshold", alpha, repeats, rng) < target:
        return None
    while hi - lo > 1:  # power grows with the shift: bisect
        mid = (lo + hi) // 2
        if power(values, np.minimum(values + mid, cap), n, "episodes_to_threshold", alpha, repeats, rng) >= target:
            hi = mid
        else:
            lo = mid
    return hi


# -- error rates of the check as it runs: n fresh seeds against the whole baseline, and the
# -- family of posts one command checks ---------------------------------------------------


def holm_adjusted(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (Holm 1979): ``changed`` where adjusted p < alpha
    keeps the family-wise false-alarm rate of the whole set of tests at alpha, whatever
    their dependence. One test: its own p. (statsmodels' ``multipletests``.)"""
    if not len(pvalues):
        return []
    return [float(p) for p in multipletests(list(pvalues), method="holm")[1]]


def _ranks_with_sum(total: int, size: int, rank_sum: int) -> list[int]:
    """A ``size``-subset of the ranks 1..total whose sum is ``rank_sum`` (any one will do:
    the two-sided Mann-Whitney p depends on the ranks only through their sum)."""
    ranks = list(range(1, size + 1))
    extra = rank_sum - sum(ranks)
    for k in range(size - 1, -1, -1):  # lift the largest rank first, as far as it may go
        room = (total - (size - 1 - k)) - ranks[k]
        step = min(room, extra)
        ranks[k] += step
        extra -= step
    if extra:
        raise ValueError(f"no {size} of ranks 1..{total} sum to {rank_sum}")
    return ranks


def exact_false_alarm_rate(n_new: int, n_baseline: int, alpha: float) -> float:
    """The exact false-alarm rate of ``decide`` (Mann-Whitney, as the check computes its p)
    for ``n_new`` fresh seeds against a baseline of ``n_baseline``, when both come from one
    continuous distribution: every split of the ranks 1..N is equally likely, so the rate is
    the share of rank sums, counted with their multiplicity, whose p falls below alpha."""
    from math import comb

    total = n_new + n_baseline
    counts: list[dict[int, int]] = [{0: 1}] + [{} for _ in range(n_new)]  # counts[k][s]: k ranks summing to s
    for rank in range(1, total + 1):
        for k in range(min(rank, n_new), 0, -1):
            for s, c in counts[k - 1].items():
                counts[k][s + rank] = counts[k].get(s + rank, 0) + c
    region, low = rejection_region(n_new, n_baseline, alpha), n_new * (n_new + 1) // 2  # U = rank sum - low
    alarms = sum(count for rank_sum, count in counts[n_new].items() if region[rank_sum - low])
    return alarms / comb(total, n_new)


@dataclass(frozen=True)
class FalseAlarm:
    """The false-alarm rate of one post's rule as the check runs it."""

    rate: float
    method: str
    standard_error: float  # 0 for an exact rate


def check_false_alarm_rate(
    baseline: Sequence[float] | np.ndarray,
    n: int,
    statistic: str,
    alpha: float,
    repeats: int = 4_000,
    rng: np.random.Generator | None = None,
) -> FalseAlarm:
    """How often ``n`` fresh seeds of an unchanged learner are called changed against this
    whole baseline. Untied values (a continuous statistic): exact, by ranks. Tied values
    (success, or episodes-to-threshold with censored seeds): ``repeats`` pooled samples of
    ``n + len(baseline)`` seeds drawn from the baseline's values (its empirical distribution,
    ties included), each split at random into baseline and new."""
    values = np.asarray(baseline, float)
    if statistic != "success" and len(np.unique(values)) == len(values):
        return FalseAlarm(exact_false_alarm_rate(n, len(values), alpha), "exact (ranks)", 0.0)
    rng = rng if rng is not None else np.random.default_rng(2)
    m = len(values)
    pooled = np.stack([values[rng.integers(0, m, m + n)] for _ in range(repeats)])
    rate = int(changed_many(pooled[:, :m], pooled[:, m:], statistic, alpha).sum()) / repeats
    return FalseAlarm(rate, f"resampled ({repeats} pooled draws)", float(np.sqrt(rate * (1 - rate) / repeats)))


POOLED_DRAWS = 20_000
"""Pooled resamples behind every false-alarm rate a check states (the report, the command's
figure, ``results/checks/family.json``), from one seed: one figure, computed one way."""


def command_false_alarm_rate(
    baseline: Sequence[float] | np.ndarray, n: int, statistic: str, level: float
) -> FalseAlarm:
    """One post's false-alarm rate as a check states it: ``n`` fresh seeds against this whole
    baseline at ``level`` (``check_false_alarm_rate``, ``POOLED_DRAWS`` draws from seed 0)."""
    return check_false_alarm_rate(baseline, n, statistic, level, POOLED_DRAWS, np.random.default_rng(0))


def family_false_alarm_rate(rates: Sequence[float]) -> float:
    """The chance that at least one of independent tests with these false-alarm rates fires:
    the whole command's false-alarm rate (each post's seeds are its own runs)."""
    if len(rates) == 1:  # exactly the one post's rate, not 1 - (1 - r) rounded
        return float(rates[0])
    return float(1.0 - np.prod([1.0 - r for r in rates]))


def rejection_region(n_new: int, n_baseline: int, alpha: float) -> np.ndarray:
    """For untied values: which Mann-Whitney U of the new sample (0 .. n * m, U counting the
    baseline values below each new one) ``decide`` calls changed, as a boolean mask."""
    total = n_new + n_baseline
    low = n_new * (n_new + 1) // 2
    news = np.array([_ranks_with_sum(total, n_new, low + u) for u in range(n_new * n_baseline + 1)], float)
    everyone = np.arange(1, total + 1, dtype=float)
    bases = np.stack([np.setdiff1d(everyone, new, assume_unique=True) for new in news])
    return changed_many(bases, news, "final_metric", alpha)


def false_alarm_rate_given_baseline(baseline_quantiles: np.ndarray, n_new: int, region: np.ndarray) -> float:
    """The false-alarm rate of one fixed baseline: new seeds drawn from the same continuous
    distribution F, the baseline's values given as their quantiles F(b). Each new value falls
    into a gap between baseline values with the gap's probability (the spacings), so U, the
    sum over new values of the baseline values below each, has an exact distribution: the
    n-fold convolution of the gaps' distribution."""
    q = np.sort(np.asarray(baseline_quantiles, float))
    gaps = np.diff(np.concatenate([[0.0], q, [1.0]]))  # P(a new value has k baseline values below it)
    pmf = np.array([1.0])
    for _ in range(n_new):
        pmf = np.convolve(pmf, gaps)
    return float(pmf[region].sum())


def baseline_spread(
    n_new: int, n_baseline: int, alpha: float, baselines: int = 4_000, rng: np.random.Generator | None = None
) -> dict[str, float]:
    """How the check's false-alarm rate depends on which baseline of ``n_baseline`` seeds it was
    given: over ``baselines`` baselines drawn from one continuous distribution (the rank test
    is distribution-free, so uniform quantiles stand for any), each baseline's exact rate.
    Returns its mean (the rate averaged over baselines), 5th, 50th and 95th percentiles, and
    the share of baselines whose rate exceeds alpha."""
    rng = rng if rng is not None else np.random.default_rng(3)
    region = rejection_region(n_new, n_baseline, alpha)
    rates = np.array([false_alarm_rate_given_baseline(rng.random(n_baseline), n_new, region) for _ in range(baselines)])
    p5, p50, p95 = np.percentile(rates, [5, 50, 95])
    return {
        "mean": float(rates.mean()),
        "p5": float(p5),
        "median": float(p50),
        "p95": float(p95),
        "share_above_alpha": float((rates > alpha).mean()),
        "baselines": baselines,
    }
