"""Equivalence verdicts (keras_rl/report/equivalence.py): TOST against pre-registered margins."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from keras_rl.report.equivalence import (
    MEDIAN_RATIO_MARGIN,
    SUCCESS_RATE_MARGIN,
    median_ratio_equivalence,
    read,
    success_rate_equivalence,
)
from keras_rl.report.stats import Interval, success_difference_ci


def test_the_three_readings_by_hand():
    margin = (-0.15, 0.15)
    assert read(Interval(0, -0.1, 0.1), Interval(0, -0.12, 0.12), margin, 0.0) == "equivalent within the margin"
    assert read(Interval(0.3, 0.2, 0.4), Interval(0.3, 0.18, 0.42), margin, 0.0) == "different"
    assert read(Interval(0, -0.2, 0.2), Interval(0, -0.25, 0.25), margin, 0.0) == "inconclusive"
    # a real but small difference, inside the margin, is equivalent (TOST asks about the margin)
    assert read(Interval(0.05, 0.02, 0.08), Interval(0.05, 0.01, 0.09), margin, 0.0) == "equivalent within the margin"


def test_success_rates_at_30_seeds_can_be_equivalent_where_10_seeds_cannot():
    thirty = success_rate_equivalence(30, 30, 30, 30)
    assert thirty.reading == "equivalent within the margin" and thirty.margin == (-0.15, 0.15)
    ten = success_rate_equivalence(10, 10, 10, 10)
    assert ten.reading == "inconclusive" and "inconclusive at 10 seeds each" in ten.sentence()
    assert success_rate_equivalence(17, 30, 30, 30).reading == "different"


def test_the_tost_interval_is_newcombes_at_90_percent_inside_the_95_percent_one():
    e = success_rate_equivalence(17, 30, 25, 30)
    assert e.test == success_difference_ci(17, 30, 25, 30)  # the 95% interval the reports already give
    assert e.test.low < e.tost.low < e.estimate < e.tost.high < e.test.high
    assert e.estimate == pytest.approx(17 / 30 - 25 / 30)


def test_median_ratio_readings():
    rng = np.random.default_rng(0)
    base = rng.normal(130, 20, 200).round()
    same = median_ratio_equivalence(list(base[:100]), list(base[100:]), budget=1000)
    assert same.reading == "equivalent within the margin" and same.margin == (0.9, 1.1)
    slower = median_ratio_equivalence(list(base[:30] * 1.5), list(base[30:60]), budget=1000)
    assert slower.reading == "different" and slower.estimate > 1.3
    few = median_ratio_equivalence(list(base[:5]), list(base[5:10]), budget=1000)
    assert few.reading == "inconclusive"
    censored = median_ratio_equivalence([None] * 6 + [100] * 4, [100] * 10, budget=300)
    assert censored.reading == "inconclusive" and "never reached" in censored.note


def test_the_margins_are_the_ones_docs_findings_states_were_set_before_the_runs():
    text = (Path(__file__).resolve().parents[1] / "docs" / "findings.md").read_text().lower()
    assert (SUCCESS_RATE_MARGIN, MEDIAN_RATIO_MARGIN) == (0.15, 0.10)
    assert "success rates within ±0.15" in text and "within ±10%" in text and "2026-11-23" in text


def test_a_ratio_with_no_median_says_why_without_printing_nan():
    from keras_rl.report.equivalence import median_ratio_equivalence

    judged = median_ratio_equivalence([None, None, 5], [3, 4, 5], budget=10)
    assert judged.reading == "inconclusive"
    sentence = judged.sentence()
    assert "nan" not in sentence and "no median to compare" in sentence


def test_mann_whitney_counts_the_seeds_that_never_reached_the_threshold_as_the_median_does():
    """One treatment of censoring everywhere: a seed that never reached the threshold is
    budget + 1 in the test as in the median ratio (it was dropped from the test before,
    so CartPole's Keras-against-PyTorch p read 0.35 on the successes alone)."""
    import json

    from scipy.stats import mannwhitneyu

    from keras_rl.report.stats import censored_mann_whitney

    by_hand = mannwhitneyu([3, 11], [4, 5], alternative="two-sided")
    assert censored_mann_whitney([3, None], [4, 5], budget=10) == pytest.approx((by_hand.statistic, by_hand.pvalue))
    assert censored_mann_whitney([None, None], [None], budget=10)[1] == 1.0
    root = Path(__file__).resolve().parent.parent
    committed = json.loads((root / "results" / "compare" / "cartpole" / "result.json").read_text())
    k, t = (committed["frameworks"][fw] for fw in ("keras", "torch"))
    with_censored = censored_mann_whitney(
        k["episodes_to_threshold"] + [None] * (30 - k["successes"]),
        t["episodes_to_threshold"] + [None] * (30 - t["successes"]),
        budget=600,
    )
    assert committed["mann_whitney"][1] == pytest.approx(with_censored[1]) == pytest.approx(0.6275, abs=1e-3)
