"""PyTorch versions, for the comparison side. Needs the ``torch`` extra (``torch==2.13.0``)."""

from __future__ import annotations

import io
from pathlib import Path

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.runs.files import atomic_write_bytes

NO_TORCH = (
    "the torch framework needs PyTorch: pip install 'keras-rl-repro[torch]' (in a checkout: "
    "pip install -e '.[torch]'; pinned torch==2.13.0, the CPU wheel on these machines)"
)


def check_torch() -> None:
    """A ConfigError that says how to install PyTorch where it is missing, without importing it."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        raise ConfigError(NO_TORCH)


def require_torch():
    """Import torch, or raise an error that says how to install it."""
    try:
        import torch
    except ImportError:
        raise ConfigError(NO_TORCH) from None
    return torch


def single_threaded():
    """torch with one intra-op thread, as TensorFlow gets in ``configure_tensorflow``.

    The networks are tiny, and with ``--workers`` processes sharing two cores, torch's
    default thread pool oversubscribes them (measured: 20x slower per step)."""
    torch = require_torch()
    if torch.get_num_threads() != 1:
        torch.set_num_threads(1)
    return torch


def save_state(module, path: Path) -> None:
    """``torch.save(module.state_dict())`` written atomically (temporary name, then rename)."""
    torch = require_torch()
    buf = io.BytesIO()
    torch.save(module.state_dict(), buf)
    atomic_write_bytes(Path(path), buf.getvalue())


def load_state(module, path: Path) -> None:
    """``module.load_state_dict(torch.load(path))`` with a RunFolderError naming a missing or
    damaged file."""
    torch = require_torch()
    path = Path(path)
    if not path.is_file():
        raise RunFolderError(
            f"{path} is missing: weights are not committed, so run `keras-rl reproduce` "
            "for this seed first (it saves them)"
        )
    try:
        module.load_state_dict(torch.load(path, weights_only=True))
    except Exception as exc:  # pickle, zip and shape errors all mean a damaged file here
        raise RunFolderError(f"{path} could not be loaded ({type(exc).__name__}: {exc})") from None
