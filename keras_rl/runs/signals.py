"""Ctrl-C handling for the training loop: taken between env steps, never inside TF or torch."""

from __future__ import annotations

import contextlib
import signal
import threading


@contextlib.contextmanager
def sigint_as_flag():
    """Inside the block, Ctrl-C appends to the yielded list instead of raising.

    The training loop checks the list between env steps. A KeyboardInterrupt raised
    asynchronously can land inside TensorFlow's C++ code (e.g. ``tf.constant`` converting
    a numpy array), which turns it into a SystemError: the run would end as an "error"
    instead of "interrupted". Outside the main thread signals cannot be handled, and a
    SIGINT the process was started with ignored (``cmd &`` in a script) stays ignored.
    """
    caught: list[int] = []
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        yield caught
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def sigint_deferred(reraise: bool = True):
    """Hold Ctrl-C back until the block is done, so a write and its bookkeeping stay together.

    A SIGINT that arrives inside the block is remembered and raised as KeyboardInterrupt
    when the block ends (``reraise=False``: dropped, for a flush that is the run's last act).
    """
    with sigint_as_flag() as caught:
        yield
    if caught and reraise:
        raise KeyboardInterrupt
