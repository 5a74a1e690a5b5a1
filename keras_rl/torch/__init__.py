"""PyTorch versions, for the comparison side. Needs the ``torch`` extra (``torch==2.13.0``)."""

from __future__ import annotations

from keras_rl.errors import ConfigError


def require_torch():
    """Import torch, or raise an error that says how to install it."""
    try:
        import torch
    except ImportError:
        raise ConfigError("the torch framework needs PyTorch: pip install -e '.[torch]' "
                          "(pinned torch==2.13.0, the CPU wheel on these machines)") from None
    return torch
