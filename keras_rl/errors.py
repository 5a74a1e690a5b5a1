"""Errors that name the problem. The CLI prints them and exits non-zero."""


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
