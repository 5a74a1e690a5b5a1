"""Stop signals for the training loop: Ctrl-C (SIGINT) and SIGTERM (what ``timeout``, Slurm,
Kubernetes and ``docker stop`` send) are taken between env steps, never inside TF or torch."""

from __future__ import annotations

import contextlib
import signal
import threading

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_RECEIVED: list[int] = []
"""Every stop signal this process took through the handlers below, in order."""


def stop_exit_code() -> int:
    """The exit code of a command a signal stopped: 128 + its number, as the shell reports a
    process the signal killed (130 for Ctrl-C, 143 for SIGTERM, which ``timeout``, Slurm and
    Kubernetes read); 130 when none was recorded (a KeyboardInterrupt raised by Python)."""
    return 128 + (_RECEIVED[-1] if _RECEIVED else int(signal.SIGINT))


def _record(caught: list[int], signum: int) -> None:
    caught.append(signum)
    _RECEIVED.append(signum)


@contextlib.contextmanager
def stop_signals_as_flag():
    """Inside the block, SIGINT and SIGTERM append their number to the yielded list instead
    of raising or killing the process.

    The training loop checks the list between env steps. A KeyboardInterrupt raised
    asynchronously can land inside TensorFlow's C++ code (e.g. ``tf.constant`` converting
    a numpy array), which turns it into a SystemError: the run would end as an "error"
    instead of "interrupted". Outside the main thread signals cannot be handled, and a
    signal the process was started with ignored (``cmd &`` in a script) stays ignored.
    """
    caught: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield caught
        return
    previous = {}
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            previous[sig] = signal.signal(sig, lambda signum, frame: _record(caught, signum))
    try:
        yield caught
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def stop_signals_deferred(reraise: bool = True):
    """Hold SIGINT/SIGTERM back until the block is done, so a write and its bookkeeping stay
    together. A signal that arrives inside the block is handed, when the block ends, to the
    handler it would have met: an enclosing ``stop_signals_as_flag`` records it (so the
    training loop stops at its next step, as for any other signal), and otherwise it is
    raised as KeyboardInterrupt (``reraise=False``: dropped, for a flush that is the run's
    last act)."""
    caught: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            previous[sig] = signal.signal(sig, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if caught and reraise:
        handler = previous.get(signal.Signals(caught[-1]))
        if callable(handler) and handler is not signal.default_int_handler:
            handler(caught[-1], None)  # an enclosing flag, or sigterm_as_interrupt (which raises)
        else:
            _RECEIVED.append(caught[-1])
            raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_as_interrupt():
    """SIGTERM raises KeyboardInterrupt, as Ctrl-C does (for code outside the episode loop:
    a dispatcher between seeds, ``evaluate``)."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) is signal.SIG_IGN:
        yield
        return

    def _raise(signum, frame):
        _RECEIVED.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, _raise)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def signal_name(caught: list[int]) -> str:
    return signal.Signals(caught[0]).name if caught else "SIGINT"
