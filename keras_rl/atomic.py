"""Atomic writes: every file the project writes goes through ``atomic_replace`` (a temporary file
beside it, fsynced and renamed over it), so a stop or a full disk never leaves half a file. It
imports nothing of the project, so that any layer may write (a learner's weights, a run's records,
a report)."""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_FILE_MODE = 0o666 & ~_umask()


def atomic_replace(path: Path, write: Callable[[Path], object]) -> None:
    """The one atomic writer: ``write`` fills a temporary file beside ``path`` (its name ends
    with ``path``'s, as Keras's ``save_weights`` wants), which is fsynced and renamed over
    ``path``. The file gets the usual permissions (``0666`` less the umask), like any other
    file the user writes. A failure leaves ``path`` as it was, and names it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=f"-{path.name}")
    os.close(fd)
    try:
        write(Path(tmp))
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except OSError as exc:  # a full disk: the message names the file it could not write
        Path(tmp).unlink(missing_ok=True)
        if str(path) in str(exc):
            raise
        raise OSError(exc.errno, f"could not write {path}: {exc.strerror or exc}") from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """``data`` into ``path``, atomically (``atomic_replace``)."""
    atomic_replace(path, lambda tmp: tmp.write_bytes(data))


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def finite_or_none(value: Any) -> Any:
    """JSON has no NaN or Infinity: non-finite floats become null, everywhere in ``value``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    return value


def atomic_write_json(path: Path, obj: Any) -> None:
    """Valid JSON only: non-finite floats are written as null."""
    atomic_write_text(path, json.dumps(finite_or_none(obj), indent=2, allow_nan=False) + "\n")
