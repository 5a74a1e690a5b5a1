"""A group-sequential check: fresh seeds in stages against the frozen baseline, stopping as
soon as the evidence says "changed" or says that more seeds would not find what the check
is for.

The stages are fixed before any mutant is met (``DESIGN``): stages of 5 fresh seeds up to
30; at each stage the rule's own test (``statistics.decide``: Mann-Whitney, or Fisher for
``success``) of all the fresh seeds so far against the whole baseline gives a p-value;

- **changed** when p < ``efficacy`` (one nominal level at every stage, Pocock's shape);
- **consistent** when p > ``futility`` (from the second stage on): an unchanged learner's
  p is uniform, so most of its checks stop early, while a change the check should find
  keeps p small. ``DESIGN`` starts at 0.5; the committed designs use the bound
  ``choose_futility`` picked on the mutants' tuning seeds (``keras_rl/check/sequential.json``);
- at the last stage, changed if p < ``efficacy``, else consistent.

The efficacy level is calibrated so that the whole sequence, futility stops included,
calls an unchanged learner changed at most ``alpha`` of the time (``calibrate``), by the
resampling ``statistics.check_false_alarm_rate`` uses: pooled samples drawn from the
baseline's own values (ties and censoring included), split into a baseline and a fresh
sequence. With ``alpha`` = 1% / posts per post, the whole command stays under 1%
family-wise (Bonferroni).

``simulate`` measures a design's rate of "changed" and its expected number of fresh seeds,
under no change (fresh seeds drawn like the baseline) or under a mutant (fresh seeds drawn
with replacement from the mutant's runs); ``fixed_power`` measures the fixed-n rule the
same way, so the two are compared on the same draws.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from keras_rl.check.statistics import decide


@dataclass(frozen=True)
class SequentialDesign:
    stages: tuple[int, ...] = (5, 10, 15, 20, 25, 30)
    """Fresh seeds seen at each look (cumulative)."""
    efficacy: float = 0.002
    """Stop as changed when a look's p is below this (calibrated per post: ``calibrate``)."""
    futility: float = 0.5
    """Stop as consistent when a look's p is above this, from the second look on."""

    def __post_init__(self) -> None:
        if not self.stages or list(self.stages) != sorted(set(self.stages)) or self.stages[0] < 1:
            raise ValueError(f"stages must be increasing seed counts, got {self.stages}")
        if not 0 < self.efficacy < self.futility <= 1:
            raise ValueError(f"need 0 < efficacy < futility <= 1, got {self.efficacy} and {self.futility}")


DESIGN = SequentialDesign()
"""The design as set before any mutant was simulated (2026-11-23): its efficacy level is
then calibrated per post on the baseline alone."""


@dataclass(frozen=True)
class SequentialOutcome:
    verdict: str
    """``changed`` or ``consistent``."""
    seeds: int
    """Fresh seeds used."""
    pvalues: tuple[float, ...]
    """One per look made."""


def look_pvalues(baseline: np.ndarray, fresh: np.ndarray, statistic: str, stages: Sequence[int]) -> np.ndarray:
    """The p-value at every look, for one sequence of fresh values (``len(fresh) >= stages[-1]``)."""
    return np.array([decide(baseline, fresh[:n], statistic, 0.5).p for n in stages])


def run_design(design: SequentialDesign, pvalues: Sequence[float]) -> SequentialOutcome:
    """Where the design stops on a sequence of look p-values (one per stage, or as many as
    have been made: the outcome is then ``continue`` until the design decides)."""
    seen: list[float] = []
    for k, p in enumerate(pvalues):
        seen.append(float(p))
        if p < design.efficacy:
            return SequentialOutcome("changed", design.stages[k], tuple(seen))
        last = k == len(design.stages) - 1
        if last or (k > 0 and p > design.futility):
            return SequentialOutcome("consistent", design.stages[k], tuple(seen))
    return SequentialOutcome("continue", design.stages[len(seen) - 1] if seen else 0, tuple(seen))


def _outcomes(design: SequentialDesign, pmatrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(changed, seeds used) for each row of look p-values, vectorised ``run_design``."""
    reps, looks = pmatrix.shape
    stages = np.asarray(design.stages)
    stop_changed = pmatrix < design.efficacy
    stop_futile = pmatrix > design.futility
    stop_futile[:, 0] = False
    stop_futile[:, -1] = True  # the last look always decides
    stop = stop_changed | stop_futile
    first = stop.argmax(axis=1)
    changed = stop_changed[np.arange(reps), first]
    return changed, stages[first]


def null_pvalues(
    baseline: Sequence[float] | np.ndarray,
    statistic: str,
    stages: Sequence[int],
    repeats: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Look p-values of ``repeats`` unchanged checks: pooled draws from the baseline's values
    (as many as the baseline, then the fresh sequence), the first part as the baseline."""
    values = np.asarray(baseline, float)
    m, n = len(values), max(stages)
    out = np.empty((repeats, len(stages)))
    for r in range(repeats):
        pooled = values[rng.integers(0, m, m + n)]
        out[r] = look_pvalues(pooled[:m], pooled[m:], statistic, stages)
    return out


def mutant_pvalues(
    baseline: Sequence[float] | np.ndarray,
    changed: Sequence[float] | np.ndarray,
    statistic: str,
    stages: Sequence[int],
    repeats: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Look p-values of ``repeats`` checks of a changed learner: fresh sequences drawn with
    replacement from its runs' values, against the whole baseline."""
    base, other = np.asarray(baseline, float), np.asarray(changed, float)
    n = max(stages)
    out = np.empty((repeats, len(stages)))
    for r in range(repeats):
        out[r] = look_pvalues(base, other[rng.integers(0, len(other), n)], statistic, stages)
    return out


def calibrate(design: SequentialDesign, null: np.ndarray, alpha: float) -> SequentialDesign:
    """The design with the largest efficacy level whose false-alarm rate on the null look
    p-values ``null`` is at most ``alpha`` (futility stops included: they only end checks as
    consistent). The levels tried are the null p-values themselves, so the rate is exact
    for these draws."""
    candidates = np.unique(null[(null > 0) & (null < design.futility)])
    best = replace(design, efficacy=min(float(candidates.min()) if len(candidates) else 1e-12, design.futility / 2))
    lo, hi = 0, len(candidates) - 1
    while lo <= hi:  # the rate grows with the level: the largest level under alpha
        mid = (lo + hi) // 2
        trial = replace(design, efficacy=float(candidates[mid]))
        if _outcomes(trial, null)[0].mean() <= alpha:
            best, lo = trial, mid + 1
        else:
            hi = mid - 1
    return best


def at_level(design: SequentialDesign, alpha: float) -> SequentialDesign:
    """The design with its efficacy level set to ``alpha`` / its number of looks. By the union
    bound over the looks, an unchanged learner is then called changed at most ``alpha`` of the
    time, whatever the futility bound (futility stops only end checks as consistent), as far as
    each look's p-value is valid. No simulation: for a level the committed calibration was not
    made at, such as a bisect step's share of the bisect's alpha."""
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    return replace(design, efficacy=min(alpha / len(design.stages), design.futility / 2))


@dataclass(frozen=True)
class Operating:
    """A design's (or the fixed-n rule's) behaviour on one scenario's simulated checks."""

    changed: float
    """Share of checks that said changed (the false-alarm rate under no change; power under a mutant)."""
    seeds_mean: float
    """Fresh seeds per check, on average."""
    repeats: int


def simulate(design: SequentialDesign, pmatrix: np.ndarray) -> Operating:
    changed, seeds = _outcomes(design, pmatrix)
    return Operating(float(changed.mean()), float(seeds.mean()), len(pmatrix))


def fixed_rule(pmatrix: np.ndarray, stages: Sequence[int], n: int, alpha: float) -> Operating:
    """The fixed-n rule on the same draws: its one look at ``n`` fresh seeds (a stage)."""
    k = list(stages).index(n)
    return Operating(float((pmatrix[:, k] < alpha).mean()), float(n), len(pmatrix))


FUTILITY_CANDIDATES = (0.2, 0.3, 0.5, 0.7, 1.0)
"""Futility bounds ``choose_futility`` tries (1.0: no futility stop), written down with its
criterion on 2026-11-24, before any mutant's seeds 10-29 were run (issue #21, item 4)."""


def choose_futility(
    null: np.ndarray,
    mutants: Sequence[np.ndarray],
    fixed_power: float,
    alpha: float,
    base: SequentialDesign = DESIGN,
) -> tuple[SequentialDesign, list[dict[str, float]]]:
    """The futility bound, chosen on the tuning half of the mutants' runs (``mutants``: one
    look-p matrix each). Each candidate of ``FUTILITY_CANDIDATES`` gets its efficacy level
    calibrated on ``null`` to ``alpha``. The criterion: among candidates whose mean power over
    the mutants is at least ``fixed_power`` (the fixed-n rule's, at the same family level, on
    the same draws), the fewest seeds on average over two cases weighted equally, no change and
    the mean over the mutants; with none that powerful, the most power. Ties go to the larger
    bound (fewer stops for futility). Returns the design and every candidate's figures."""
    if not mutants:
        raise ValueError("choose_futility needs at least one mutant's look p-values")
    table = []
    for futility in FUTILITY_CANDIDATES:
        design = calibrate(replace(base, futility=futility), null, alpha)
        under = [simulate(design, pm) for pm in mutants]
        table.append(
            {
                "futility": futility,
                "efficacy": design.efficacy,
                "false_alarm_rate": simulate(design, null).changed,
                "power": float(np.mean([o.changed for o in under])),
                "seeds_no_change": simulate(design, null).seeds_mean,
                "seeds_mutants": float(np.mean([o.seeds_mean for o in under])),
            }
        )
    for row in table:
        row["seeds_cost"] = (row["seeds_no_change"] + row["seeds_mutants"]) / 2
    powerful = [r for r in table if r["power"] >= fixed_power]
    if powerful:
        best = min(powerful, key=lambda r: (r["seeds_cost"], -r["futility"]))
    else:
        best = max(table, key=lambda r: (r["power"], r["futility"]))
    return replace(base, futility=best["futility"], efficacy=best["efficacy"]), table
