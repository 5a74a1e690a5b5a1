"""Stop signals (``keras_rl/runs/signals.py``): a signal held back by a deferred write
reaches whatever handler it would have met."""

from __future__ import annotations

import os
import signal

import pytest

from keras_rl.runs.signals import stop_signals_as_flag, stop_signals_deferred


@pytest.fixture(autouse=True)
def default_stop_handlers():
    """A process started in the background by a script (``cmd &``) inherits SIGINT ignored, and
    these handlers leave an ignored signal ignored by design; the tests need Python's defaults."""
    previous = {sig: signal.signal(sig, handler) for sig, handler in STARTING_HANDLERS.items()}
    yield
    for sig, handler in previous.items():
        signal.signal(sig, handler)


STARTING_HANDLERS = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}


def test_a_signal_during_a_deferred_write_inside_the_loop_sets_the_loops_flag():
    """A Ctrl-C that landed while an episode row was being written raised KeyboardInterrupt
    inside the training loop, which then marked the seed "error", not "interrupted"."""
    with stop_signals_as_flag() as caught:
        with stop_signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
        assert caught == [signal.SIGINT]  # recorded for the loop; nothing raised


def test_outside_the_loop_a_deferred_signal_is_raised_when_the_block_ends():
    with pytest.raises(KeyboardInterrupt):
        with stop_signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)


def test_a_final_flush_drops_the_signal():
    with stop_signals_deferred(reraise=False):
        os.kill(os.getpid(), signal.SIGINT)
