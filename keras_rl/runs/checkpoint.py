"""Checkpoints for ``--resume``: everything a run carries across an episode boundary.

A checkpoint holds the episodes so far, the counters, the metric, the agent's state
(weights, optimizer state, replay buffer, noise and exploration state, every generator it
owns) and the generators outside it (the env's ``np_random`` and its action space's,
Python's ``random``, NumPy's global RNG). Resuming from it replays the rest of the run
exactly as an uninterrupted run would have played it, so the two ``episodes.csv`` agree
bit for bit (``tests/test_resume.py``). TensorFlow's and Keras' global generators are not
saved: no training step of the three posts draws from them (the only random layer,
post 001's GaussianNoise, is off at learning phase 0; ``learning_phase_training=true``
runs are refused by ``--resume``).

The file is ``checkpoint.pkl`` in the seed folder: a header line, the SHA-256 of the
payload, then the pickled payload, written atomically. A file that fails the check is
refused with a message and nothing in the folder is touched. It is deleted when the run
completes, and never committed (``.gitignore``). It is this project's own pickle: load only
checkpoints you made.
"""

from __future__ import annotations

import hashlib
import pickle
from pathlib import Path
from typing import Any

from keras_rl.errors import RunFolderError
from keras_rl.runs.files import atomic_write_bytes

CHECKPOINT = "checkpoint.pkl"
MAGIC = b"keras-rl checkpoint 1\n"


def write_checkpoint(run_dir: Path, state: dict[str, Any]) -> None:
    payload = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    atomic_write_bytes(Path(run_dir) / CHECKPOINT, MAGIC + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)


def read_checkpoint(run_dir: Path) -> dict[str, Any]:
    """The checkpoint's state, or a RunFolderError that says why it cannot be used."""
    path = Path(run_dir) / CHECKPOINT
    if not path.is_file():
        raise RunFolderError(f"{run_dir} has no {CHECKPOINT} to resume from (a run writes one every "
                             "--checkpoint-every episodes and when it is stopped); pass --overwrite to start again")
    data = path.read_bytes()
    digest_end = len(MAGIC) + 64
    if not data.startswith(MAGIC) or data[digest_end:digest_end + 1] != b"\n":
        raise RunFolderError(f"{path} is not a keras-rl checkpoint (bad header); the run folder is left as it is")
    payload = data[digest_end + 1:]
    if hashlib.sha256(payload).hexdigest().encode() != data[len(MAGIC):digest_end]:
        raise RunFolderError(f"{path} is corrupt (checksum mismatch: truncated or damaged); "
                             "the run folder is left as it is")
    try:
        return pickle.loads(payload)
    except Exception as exc:  # a checksum-valid file from an incompatible version
        raise RunFolderError(f"{path} could not be read ({type(exc).__name__}: {exc})") from None
