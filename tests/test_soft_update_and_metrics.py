import keras
import numpy as np
import pytest

from keras_rl.learners.common import soft_update
from keras_rl.metrics import GoalShare, PostEMA, RollingMean


def test_soft_update_mixes_by_tau():
    target = [keras.Variable(np.array([1.0, 2.0])), keras.Variable(np.array([[0.0]]))]
    source = [keras.Variable(np.array([3.0, -2.0])), keras.Variable(np.array([[10.0]]))]
    soft_update(target, source, 0.25)
    np.testing.assert_allclose(target[0].numpy(), [1.5, 1.0])
    np.testing.assert_allclose(target[1].numpy(), [[2.5]])
    np.testing.assert_allclose(source[0].numpy(), [3.0, -2.0])  # the source is untouched


def test_soft_update_tau_one_is_a_hard_copy():
    target = [keras.Variable(np.array([1.0, 2.0]))]
    source = [keras.Variable(np.array([7.0, 8.0]))]
    soft_update(target, source, 1.0)
    np.testing.assert_array_equal(target[0].numpy(), [7.0, 8.0])


def test_soft_update_refuses_mismatched_lists():
    with pytest.raises(ValueError):
        soft_update([keras.Variable(1.0)], [keras.Variable(1.0), keras.Variable(2.0)], 0.5)


def test_post_ema_starts_at_first_score_then_mixes_0_9_0_1():
    ema = PostEMA(0.9)
    assert ema.update(-1200.0) == -1200.0
    assert ema.update(-200.0) == pytest.approx(0.9 * -1200 + 0.1 * -200)  # -1100
    assert ema.update(-100.0) == pytest.approx(0.9 * -1100 + 0.1 * -100)  # -1000


def test_post_ema_restarts_when_it_is_exactly_zero():
    # `if score_avg != 0 else score`: 0 doubles as "not started".
    ema = PostEMA(0.9)
    ema.update(0.0)
    assert ema.update(-50.0) == -50.0


def test_threshold_comparisons_strict_and_inclusive():
    assert not PostEMA().passes(-300.0, -300.0) and PostEMA().passes(-299.9, -300.0)  # score_avg > -300
    assert RollingMean().passes(475.0, 475.0)  # CartPole: reaching 475
    assert GoalShare().passes(0.5, 0.5)
    assert not RollingMean().passes(float("nan"), 0.0)


def test_return_spread_is_infinite_until_the_window_fills_then_max_minus_min():
    from keras_rl.metrics import ReturnSpread

    m = ReturnSpread(3)
    assert m.update(-99.0) == float("inf") and not m.passes(float("inf"), 2.0)
    m.update(-98.0)
    assert m.update(-99.5) == pytest.approx(1.5) and m.passes(1.5, 2.0)
    assert m.update(-90.0) == pytest.approx(9.5) and not m.passes(9.5, 2.0)


def test_goal_share_counts_positive_returns_over_the_window():
    m = GoalShare(4)
    values = [m.update(s) for s in (-99.0, 93.0, -1.0, 90.0, 95.0)]
    assert values == [0.0, 0.25, 0.25, 0.5, 0.75]
