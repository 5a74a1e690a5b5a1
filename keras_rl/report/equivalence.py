"""Equivalence verdicts: where we say "no difference", a two-one-sided test (TOST) against a
margin fixed before the runs (issue #20).

Two arms (Keras against PyTorch, batched against solo seeds) give one of three readings:

- **equivalent within the margin**: the 90% interval of the difference lies inside the margin
  (Schuirmann's TOST at 5%: each one-sided test rejects "the difference is at least the
  margin");
- **different**: not equivalent, and the 95% interval excludes no difference;
- **inconclusive at n seeds**: neither; more seeds would be needed to say.

The margins are pre-registered: written here, and in ``docs/findings.md``, on 2026-11-23,
before any of the 30-seed runs they judge was made. Changing them after seeing those runs
would void the verdicts; a change goes in with its reason and reruns nothing but the report.

- success rate: within ±0.15 (absolute), Newcombe's hybrid score interval;
- median episodes to threshold: the ratio of the arms' medians within 0.90-1.10 (±10%),
  percentile bootstrap; seeds that never reached the threshold count as budget + 1 (they rank
  last), and an arm where half or more never reached it has no median to compare.

A seed's episodes to threshold is read as the plans and the margins above word it (issue 52):
the first episode whose metric met the threshold, a seed that never met it counting as budget
+ 1 (``FIRST_PASSING``). Until issue 52 the code counted a seed's first passing episode only
when the seed also succeeded (``CONVERGED_AT_END``). The two differ only where success is not
"reached the threshold" (post 001, judged at the end of the run: a seed can pass the threshold
and lose it); there the plans' reading governs the verdict and the code's is reported beside
it, labelled (``Equivalence.beside``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from keras_rl.report.stats import Interval, bootstrap_interval, success_difference_ci

Reading = Literal["equivalent within the margin", "different", "inconclusive"]

FIRST_PASSING = "first passing episode"
"""The plans' reading of a seed's episodes to threshold: its first episode whose metric met the
threshold, whatever happened after (None: never). It governs every verdict."""
CONVERGED_AT_END = "counted only if converged at the end"
"""The code's reading before issue 52: the first passing episode of a seed that also succeeded,
None for any other. Reported beside the plans' reading where the two differ (post 001)."""

SUCCESS_RATE_MARGIN = 0.15
"""Pre-registered (2026-11-23): |rate(a) - rate(b)| < 0.15 is "no difference" in success."""
MEDIAN_RATIO_MARGIN = 0.10
"""Pre-registered (2026-11-23): median(a) / median(b) within 1 ± 0.10 is "no difference" in speed."""
TOST_ALPHA = 0.05
"""Each one-sided test at 5%: the (1 - 2 * 0.05) = 90% interval inside the margin."""


@dataclass(frozen=True)
class Equivalence:
    quantity: str
    estimate: float
    tost: Interval  # the 90% interval (TOST)
    test: Interval  # the 95% interval (difference or not)
    margin: tuple[float, float]
    null: float  # "no difference": 0 for a difference, 1 for a ratio
    n: tuple[int, int]
    reading: Reading
    note: str = ""
    beside: Equivalence | None = None
    """The same quantity by the code's reading before issue 52 (``CONVERGED_AT_END``), where it
    differs from the plans' (which this one is, and which governs)."""

    def sentence(self) -> str:
        """The reading with its numbers, as a report states it (the code's reading beside it,
        labelled, where there is one)."""
        n = f"{self.n[0]} and {self.n[1]} seeds" if self.n[0] != self.n[1] else f"{self.n[0]} seeds each"
        said = "inconclusive at " + n if self.reading == "inconclusive" else self.reading
        if not np.isfinite(self.estimate):  # nothing to estimate: say why, not "nan; nan to nan"
            text = f"{self.quantity}: **{said}** (no estimate; {n})" + (f". {self.note}" if self.note else "")
        else:
            text = (
                f"{self.quantity}: **{said}** ({self.estimate:.3g}; 90% interval {self.tost.low:.3g} to "
                f"{self.tost.high:.3g}, 95% {self.test.low:.3g} to {self.test.high:.3g}; margin "
                f"{self.margin[0]:.3g} to {self.margin[1]:.3g}, set before the runs; {n})"
                + (f". {self.note}" if self.note else "")
            )
        if self.beside is None:
            return text
        return (
            f"{text}, by the plan's reading (a seed's {FIRST_PASSING}); beside it, not governing, the code's "
            f"reading before issue 52 ({CONVERGED_AT_END}): {self.beside.sentence()}"
        )


def read(tost: Interval, test: Interval, margin: tuple[float, float], null: float) -> Reading:
    if margin[0] < tost.low and tost.high < margin[1]:
        return "equivalent within the margin"
    if not test.low <= null <= test.high:
        return "different"
    return "inconclusive"


def success_rate_equivalence(
    successes_a: int, n_a: int, successes_b: int, n_b: int, margin: float = SUCCESS_RATE_MARGIN
) -> Equivalence:
    """rate(a) - rate(b) against ±margin (Newcombe's interval at 90% and 95%)."""
    tost = success_difference_ci(successes_a, n_a, successes_b, n_b, confidence=1 - 2 * TOST_ALPHA)
    test = success_difference_ci(successes_a, n_a, successes_b, n_b, confidence=0.95)
    bounds = (-margin, margin)
    return Equivalence(
        "success rate difference", tost.estimate, tost, test, bounds, 0.0, (n_a, n_b), read(tost, test, bounds, 0.0)
    )


def median_ratio_equivalence(
    a,
    b,
    budget: int,
    margin: float = MEDIAN_RATIO_MARGIN,
    rng: np.random.Generator | None = None,
    n_resamples: int = 10_000,
) -> Equivalence:
    """median(a) / median(b) of episodes to threshold against 1 ± margin. ``a`` and ``b`` hold
    each seed's episode, or None for a seed that never reached the threshold (budget + 1)."""
    x, y = (np.array([budget + 1 if v is None else v for v in arm], float) for arm in (a, b))
    bounds, n = (1 - margin, 1 + margin), (len(x), len(y))
    if any(np.median(arm) > budget for arm in (x, y)):
        nan = Interval(float("nan"), float("nan"), float("nan"))
        return Equivalence(
            "median episodes to threshold, ratio",
            float("nan"),
            nan,
            nan,
            bounds,
            1.0,
            n,
            "inconclusive",
            "Half or more of an arm's seeds never reached the threshold: no median to compare",
        )
    rng = np.random.default_rng(0) if rng is None else rng

    def ratio(u, v, axis=-1):
        return np.median(u, axis=axis) / np.median(v, axis=axis)

    intervals = []
    for confidence in (1 - 2 * TOST_ALPHA, 0.95):
        low, high = bootstrap_interval(
            (x, y), ratio, np.random.default_rng(rng.integers(2**32)), n_resamples, confidence
        )
        intervals.append(Interval(float(ratio(x, y)), low, high))
    tost, test = intervals
    return Equivalence(
        "median episodes to threshold, ratio", tost.estimate, tost, test, bounds, 1.0, n, read(tost, test, bounds, 1.0)
    )


@dataclass(frozen=True)
class Arm:
    """One arm's seeds: each one's first passing episode (None: never) and whether it succeeded."""

    reached: Sequence[int | None]
    success: Sequence[bool]

    @classmethod
    def of(cls, records) -> Arm:
        """From ``summary.json`` records (dicts) or ``RunSummary`` objects."""
        records = list(records)
        pick = (lambda r, k: r[k]) if all(isinstance(r, dict) for r in records) else getattr
        return cls(
            [None if pick(r, "reached_at_episode") is None else int(pick(r, "reached_at_episode")) for r in records],
            [bool(pick(r, "success")) for r in records],
        )

    @property
    def seeds(self) -> int:
        return len(self.reached)

    @property
    def successes(self) -> int:
        return sum(self.success)

    def hits(self, reading: str = FIRST_PASSING) -> list[int]:
        """The episodes of the seeds that reached the threshold by ``reading``, in seed order."""
        if reading == FIRST_PASSING:
            return [r for r in self.reached if r is not None]
        if reading == CONVERGED_AT_END:
            return [r for r, ok in zip(self.reached, self.success, strict=True) if ok and r is not None]
        raise ValueError(f"no reading {reading!r}; the readings are {FIRST_PASSING!r} and {CONVERGED_AT_END!r}")

    def stats(self, reading: str) -> dict:
        """Success rate and the distribution of episodes to threshold of one arm's seeds.

        The success rate is the post's criterion (``self.success``); episodes to threshold are the
        hits by ``reading`` (``FIRST_PASSING``, the plans' reading, which
        governs every comparison, or ``CONVERGED_AT_END``, the code's before issue 52, printed beside
        it where the two differ), in seed order. IQR is the 25th to 75th percentile (NumPy's default
        linear interpolation). The one place these percentiles are computed (``aggregate``,
        ``compare``, ``sweep`` and the maintainers' runs table use it).
        """
        hits = self.hits(reading)
        successes = int(self.successes)
        out: dict = {
            "seeds": self.seeds,
            "successes": successes,
            "success_rate": successes / self.seeds if self.seeds else 0.0,
            "episodes_to_threshold": hits,
        }
        if hits:
            q25, q50, q75 = np.percentile(np.asarray(hits, float), [25, 50, 75])
            out.update(median=float(q50), q25=float(q25), q75=float(q75), min=int(min(hits)), max=int(max(hits)))
        else:
            out.update(median=None, q25=None, q75=None, min=None, max=None)
        return out

    def episodes(self, reading: str = FIRST_PASSING) -> list[int | None]:
        """Every seed's episodes to threshold by ``reading``: the hits, then None (counted as budget
        + 1) for each seed that never reached it. Not in seed order: the bootstrap's draws depend
        on the order, and this is the order the committed verdicts were drawn in."""
        hits = self.hits(reading)
        return [*hits, *([None] * (self.seeds - len(hits)))]


def speed_equivalence(a: Arm, b: Arm, budget: int) -> Equivalence:
    """The median ratio by the plans' reading, with the code's old reading beside it where the
    two differ."""
    speed = median_ratio_equivalence(a.episodes(), b.episodes(), budget)
    if all(arm.episodes() == arm.episodes(CONVERGED_AT_END) for arm in (a, b)):
        return speed
    beside = median_ratio_equivalence(a.episodes(CONVERGED_AT_END), b.episodes(CONVERGED_AT_END), budget)
    return replace(speed, beside=beside)


def framework_verdict(a: Arm, b: Arm, budget: int) -> tuple[str, list[Equivalence]]:
    """Two arms (Keras, PyTorch) judged on both pre-set margins: the headline and the two verdicts
    (the median ratio by the plans' reading, which alone makes the headline)."""
    success = success_rate_equivalence(a.successes, a.seeds, b.successes, b.seeds)
    speed = speed_equivalence(a, b, budget)
    readings = {success.reading, speed.reading}
    seeds = (a.seeds, b.seeds)
    n = f"{seeds[0]} seeds each" if seeds[0] == seeds[1] else f"{seeds[0]} and {seeds[1]} seeds"
    if "different" in readings:
        headline = "The frameworks differ"
    elif readings == {"equivalent within the margin"}:
        headline = "Equivalent within the margins set before the runs"
    else:
        headline = f"Inconclusive at {n}: neither a difference nor equivalence within the margins is shown"
    return headline, [success, speed]
