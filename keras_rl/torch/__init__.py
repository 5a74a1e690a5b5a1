"""PyTorch versions, for the comparison side. Needs the ``torch`` extra (``torch==2.13.0``)."""

from __future__ import annotations

import functools
import io
import os
import sys
from pathlib import Path

from keras_rl.atomic import atomic_write_bytes
from keras_rl.errors import ConfigError, RunFolderError

NO_TORCH = (
    "the torch framework needs PyTorch: pip install 'keras-rl-repro[torch]' (in a checkout: "
    "pip install -e '.[torch]'; pinned torch==2.13.0, the CPU wheel on these machines)"
)


def check_torch() -> None:
    """A ConfigError that says how to install PyTorch where it is missing, or what is wrong with
    ``KERAS_RL_PORTABLE_TORCH`` (``portable_arithmetic``), without importing torch."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        raise ConfigError(NO_TORCH)
    portable_arithmetic()


PORTABLE_SWITCH = "KERAS_RL_PORTABLE_TORCH"
"""Set to 1 before torch is imported: PyTorch's portable arithmetic (``portable_arithmetic``)."""
PORTABLE_CAPS = {"MKL_CBWR": "COMPATIBLE", "ATEN_CPU_CAPABILITY": "avx2"}
"""What the switch sets for torch's kernels, besides the optimizers' fused steps."""


@functools.cache
def portable_arithmetic() -> bool:
    """Whether this process runs PyTorch's portable arithmetic (``KERAS_RL_PORTABLE_TORCH=1``): the
    same bits on every x86 CPU with AVX2, whatever its vendor or its AVX-512 (issue 52 item 7).

    torch's own arithmetic follows the CPU. Its float32 ``sqrt`` (the Adam denominator) is MKL's
    vector math, which refines the CPU's approximate reciprocal square root (``rsqrtps``), whose
    bits each vendor's silicon gives its own way; its matrix products follow MKL's branch for the
    CPU; its element kernels follow ATen's capability. The switch takes MKL's reproducible branch
    (``MKL_CBWR=COMPATIBLE``: one code path on Intel and AMD alike), ATen's AVX2 kernels on every
    host, and the fused Adam/AdamW step of ``torch.optim``, whose square root is the CPU's exact
    one. It changes the bits (the committed runs were made without it) but not what a run
    computes; the replay tests use it where a host has no reference of its own
    (``docs/performance.md``). Read once a process; the run records it (``provenance``)."""
    value = os.environ.get(PORTABLE_SWITCH)
    if value in (None, "", "0"):
        return False
    if value != "1":
        raise ConfigError(f"{PORTABLE_SWITCH} is 1 (portable arithmetic) or unset, not {value!r}")
    clash = [f"{k}={os.environ[k]}" for k, v in PORTABLE_CAPS.items() if os.environ.get(k, v) != v]
    if clash:
        caps = ", ".join(f"{k}={v}" for k, v in PORTABLE_CAPS.items())
        raise ConfigError(f"{PORTABLE_SWITCH}=1 sets {caps} itself; this environment has {', '.join(clash)}")
    if "torch" in sys.modules and any(k not in os.environ for k in PORTABLE_CAPS):
        raise ConfigError(f"{PORTABLE_SWITCH}=1 must be set before torch is imported (its kernels are chosen then)")
    os.environ.update(PORTABLE_CAPS)
    return True


def require_torch():
    """Import torch, or raise an error that says how to install it; under
    ``KERAS_RL_PORTABLE_TORCH=1``, with its caps set first."""
    portable_arithmetic()
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
