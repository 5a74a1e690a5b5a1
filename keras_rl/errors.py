"""Errors that name the problem. The CLI prints them and exits non-zero.

A message names an argument with ``argument``: as the library's parameter or field
(``workers``, ``seed_batch=4``, ``overwrite=True``), which is what ``keras_rl.api`` takes, and
as its command-line flag (``--workers``, ``--seed-batch 4``, ``--overwrite``) while a command
runs (``as_flags``, which ``cli.main`` sets). The library never writes a flag itself.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

_AS_FLAGS: ContextVar[bool] = ContextVar("keras_rl_as_flags", default=False)


def argument(name: str, value: object = None) -> str:
    """``name`` (a parameter of ``keras_rl.api`` or a config field) as a message says it: ``name``
    or ``name=value`` from Python, ``--name`` or ``--name value`` from a command line (``True``
    is a switch's value: ``overwrite=True``, ``--overwrite``)."""
    if _AS_FLAGS.get():
        flag = "--" + name.replace("_", "-")
        return flag if value is None or value is True else f"{flag} {value}"
    return name if value is None else f"{name}={value}"


@contextmanager
def as_flags() -> Iterator[None]:
    """Within it, ``argument`` names flags: the command line's wording of the library's messages."""
    token = _AS_FLAGS.set(True)
    try:
        yield
    finally:
        _AS_FLAGS.reset(token)


class KerasRLError(Exception):
    """Base class: a user-facing error with a message that says what is wrong."""


class ConfigError(KerasRLError, ValueError):
    """A configuration value is out of range or of the wrong kind."""


class EnvironmentMismatchError(KerasRLError, TypeError):
    """The environment does not fit the algorithm (e.g. a Discrete action space for DDPG)."""


class RunFolderError(KerasRLError, FileNotFoundError):
    """A run folder is missing, incomplete or corrupt."""


class NonFiniteLossError(KerasRLError, FloatingPointError):
    """A training loss became NaN or infinite; the run stops and keeps what it wrote."""


class NoVerdictError(KerasRLError):
    """``check`` could not decide: a fresh seed crashed or left no summary (exit 3, not 1 or 2)."""
