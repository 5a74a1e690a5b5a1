"""The group-sequential check (``keras_rl/check/sequential.py``): stopping, calibration and
its operating characteristics on samples whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from keras_rl.check.sequential import (
    SequentialDesign,
    _outcomes,
    at_level,
    calibrate,
    fixed_rule,
    look_pvalues,
    mutant_pvalues,
    null_pvalues,
    run_design,
    simulate,
)

DESIGN = SequentialDesign(stages=(5, 10, 15, 20), efficacy=0.01, futility=0.5)


@pytest.mark.parametrize(
    "pvalues, verdict, seeds",
    [
        ([0.001], "changed", 5),  # clear at the first look
        ([0.9, 0.8], "consistent", 10),  # futility waits for the second look
        ([0.2, 0.3, 0.005], "changed", 15),
        ([0.2, 0.3, 0.4, 0.02], "consistent", 20),  # the last look decides
        ([0.2, 0.3], "continue", 10),  # not decided yet
    ],
)
def test_the_design_stops_where_its_boundaries_say(pvalues, verdict, seeds):
    out = run_design(DESIGN, pvalues)
    assert (out.verdict, out.seeds) == (verdict, seeds)
    assert out.pvalues == tuple(pvalues[: len(out.pvalues)])


def test_the_vectorised_outcomes_are_run_design_row_by_row():
    rng = np.random.default_rng(0)
    pmatrix = rng.random((500, 4)) ** 3  # plenty of small p-values, so every exit is taken
    changed, seeds = _outcomes(DESIGN, pmatrix)
    for row, c, n in zip(pmatrix, changed, seeds):
        out = run_design(DESIGN, row)
        assert (out.verdict == "changed", out.seeds) == (bool(c), int(n))


def test_invalid_designs_are_refused():
    with pytest.raises(ValueError, match="increasing"):
        SequentialDesign(stages=(10, 5))
    with pytest.raises(ValueError, match="efficacy < futility"):
        SequentialDesign(efficacy=0.6, futility=0.5)


def test_a_design_at_a_given_level_splits_it_over_its_looks_and_stays_under_it():
    """``at_level`` (a bisect step's share): efficacy alpha / looks, so the null rate, futility
    stops included, stays under alpha by the union bound; here about half of it, since the
    looks' p-values are correlated."""
    design = at_level(DESIGN, 0.08)
    assert design.efficacy == pytest.approx(0.02) and design.futility == DESIGN.futility
    rng = np.random.default_rng(2)
    null = null_pvalues(rng.normal(size=100), "final_metric", design.stages, 1500, rng)
    rate = _outcomes(design, null)[0].mean()
    assert 0 < rate <= 0.08
    with pytest.raises(ValueError, match="alpha must lie"):
        at_level(DESIGN, 0)


def test_calibration_keeps_the_false_alarm_rate_at_alpha_and_is_the_largest_such_level():
    rng = np.random.default_rng(1)
    baseline = rng.normal(size=30)
    null = null_pvalues(baseline, "final_metric", DESIGN.stages, 1500, rng)
    alpha = 0.02
    design = calibrate(DESIGN, null, alpha)
    assert simulate(design, null).changed <= alpha
    larger = np.unique(null[(null > design.efficacy) & (null < design.futility)])
    assert simulate(SequentialDesign(DESIGN.stages, float(larger[0]), DESIGN.futility), null).changed > alpha
    # Under no change a look's p is uniform: the futility bound ends half the checks at the
    # second look, and the rest use fewer seeds than the cap.
    _, seeds = _outcomes(design, null)
    assert abs((seeds == 10).mean() - 0.5) < 0.05
    assert 10 < seeds.mean() < 20


@pytest.mark.slow  # thousands of simulated checks
def test_a_clear_change_is_found_at_the_first_look_and_a_null_one_is_not():
    rng = np.random.default_rng(2)
    baseline = rng.normal(size=30)
    design = calibrate(DESIGN, null_pvalues(baseline, "final_metric", DESIGN.stages, 1500, rng), 0.01)
    shifted = mutant_pvalues(baseline, rng.normal(4.0, 1.0, size=30), "final_metric", DESIGN.stages, 300, rng)
    found = simulate(design, shifted)
    assert found.changed == 1.0 and found.seeds_mean == 5.0
    same = mutant_pvalues(baseline, rng.normal(size=30), "final_metric", DESIGN.stages, 300, rng)
    assert simulate(design, same).changed < 0.05
    assert fixed_rule(shifted, DESIGN.stages, 10, 0.01).changed == 1.0


def test_look_pvalues_are_the_checks_own_test_at_each_look():
    from keras_rl.check.statistics import decide

    rng = np.random.default_rng(3)
    baseline, fresh = rng.normal(size=30), rng.normal(0.5, 1, size=20)
    got = look_pvalues(baseline, fresh, "auc", (5, 20))
    assert got[0] == decide(baseline, fresh[:5], "auc", 0.01).p and got[1] == decide(baseline, fresh, "auc", 0.01).p


def _choice_inputs():
    rng = np.random.default_rng(5)
    baseline = rng.normal(size=30)
    stages = (5, 10, 15, 20)
    null = null_pvalues(baseline, "final_metric", stages, 800, rng)
    gross = mutant_pvalues(baseline, rng.normal(3.0, 1.0, 15), "final_metric", stages, 300, rng)
    return SequentialDesign(stages=stages), null, gross


def test_futility_is_chosen_by_its_written_criterion():
    """Issue #21, item 4: against a change every bound finds, the criterion picks the bound
    that spends the fewest seeds (the lowest: it ends unchanged checks soonest), and every
    candidate keeps its false-alarm rate at alpha."""
    from keras_rl.check.sequential import FUTILITY_CANDIDATES, choose_futility

    base, null, gross = _choice_inputs()
    design, table = choose_futility(null, [gross], fixed_power=0.9, alpha=0.02, base=base)
    assert [r["futility"] for r in table] == list(FUTILITY_CANDIDATES)
    assert all(r["false_alarm_rate"] <= 0.02 and r["power"] > 0.95 for r in table)
    assert design.futility == min(FUTILITY_CANDIDATES)
    # no futility stop: an unchanged check runs to the last look unless it raises a false alarm
    assert table[0]["seeds_no_change"] < base.stages[-1] - 1 < table[-1]["seeds_no_change"]
    chosen = next(r for r in table if r["futility"] == design.futility)
    assert design.efficacy == chosen["efficacy"]


def test_without_a_bound_as_powerful_as_the_fixed_rule_the_most_powerful_is_chosen():
    from keras_rl.check.sequential import choose_futility

    base, null, gross = _choice_inputs()
    design, table = choose_futility(null, [gross], fixed_power=1.01, alpha=0.02, base=base)
    best = max(r["power"] for r in table)
    assert next(r for r in table if r["futility"] == design.futility)["power"] == best
    with pytest.raises(ValueError, match="at least one mutant"):
        choose_futility(null, [], fixed_power=0.5, alpha=0.02, base=base)
