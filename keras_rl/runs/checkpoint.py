"""Checkpoints for ``--resume``: everything a seed carries from one vector step to the next.

A seed's checkpoint holds its episodes so far, its counters, its metric, where its episode
stands, its env (pickled: mid-episode state and its generators), its agent's parts (replay
buffer, noise and exploration state, loss tally, every generator they own), its slice of
the learner (weights, optimizer state) and the generators outside them (Python's
``random``, NumPy's global RNG). The seeds of a batch write theirs at the same vector step,
which each one records with the batch's seeds (``train/loop.py``). Resuming from it replays the rest of the run
exactly as an uninterrupted run would have played it, so the two ``episodes.csv`` agree
bit for bit (``tests/test_resume.py``). TensorFlow's and Keras' global generators are not
saved: no training step of the three posts draws from them (the only random layer,
post 001's GaussianNoise, is off at learning phase 0; ``learning_phase_training=true``
runs are refused by ``--resume``).

The file is ``checkpoint.pkl`` in the seed folder: a header line, the SHA-256 of the
payload, then the pickled payload, written atomically. A file that fails the check is
refused with a message and nothing in the folder is touched. When a new one is written the
previous one stays as ``checkpoint.prev.pkl``, so a batch killed while its seeds were
writing theirs still has one vector step that every seed holds. Both are deleted when the
batch ends, and never committed (``.gitignore``). It is this project's own pickle: load only
checkpoints you made.
"""

from __future__ import annotations

import hashlib
import os
import pickle
from pathlib import Path
from typing import Any

from keras_rl.atomic import atomic_write_bytes
from keras_rl.errors import RunFolderError, argument

CHECKPOINT = "checkpoint.pkl"
PREVIOUS = "checkpoint.prev.pkl"
MAGIC = b"keras-rl checkpoint 1\n"
VERSION = 3
"""The layout of the payload (``train/life.Checkpoints``, every engine's); 2 kept the loop's
seed-axis state under ``axis`` and named no engine, 1 was the per-episode layout of the solo loop."""


def write_checkpoint(run_dir: Path, state: dict[str, Any]) -> None:
    """``state`` as the folder's checkpoint; the one it replaces becomes ``checkpoint.prev.pkl``."""
    run_dir = Path(run_dir)
    payload = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    tmp = run_dir / f".next-{CHECKPOINT}"
    atomic_write_bytes(tmp, MAGIC + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)
    if (run_dir / CHECKPOINT).is_file():  # linked, then renamed: the folder always holds a current one
        link = run_dir / f".prev-{CHECKPOINT}"
        link.unlink(missing_ok=True)
        os.link(run_dir / CHECKPOINT, link)
        os.replace(link, run_dir / PREVIOUS)
    os.replace(tmp, run_dir / CHECKPOINT)


def checkpoint_batch(run_dir: Path) -> list[int]:
    """The seeds whose batch wrote the folder's checkpoint (one seed for a solo run; none
    where there is no checkpoint)."""
    if not (Path(run_dir) / CHECKPOINT).is_file():
        return []
    return list(read_checkpoint(run_dir).get("batch", []))


def delete_checkpoints(run_dir: Path) -> None:
    for name in (CHECKPOINT, PREVIOUS, f".next-{CHECKPOINT}", f".prev-{CHECKPOINT}"):
        (Path(run_dir) / name).unlink(missing_ok=True)


def read_batch_checkpoints(run_dirs: list[Path], batch: list[int], part: bool = False) -> list[dict[str, Any]]:
    """Each seed's checkpoint of one vector step, the newest that every seed of the batch
    holds (current or previous); a RunFolderError that names the folder otherwise. ``part``:
    the seeds may be part of the batch that wrote them (the vectorised engine's seeds are
    independent of the batch: one killed while its batch shed it resumes alone)."""
    current = [read_checkpoint(d) for d in run_dirs]
    for d, state in zip(run_dirs, current):
        if state.get("version") != VERSION:
            raise RunFolderError(
                f"{Path(d) / CHECKPOINT} was written by an older keras-rl (checkpoint layout "
                f"{state.get('version', 1)}, this one reads {VERSION}); pass {argument('overwrite')} to start again"
            )
        if state["batch"] != batch and not (part and set(batch) <= set(state["batch"])):
            raise RunFolderError(
                f"{Path(d) / CHECKPOINT} belongs to a batch of seeds {state['batch']}, this command "
                f"resumes seeds {batch} together; resume with the same {argument('seeds')} and {argument('seed_batch')}"
            )
    steps = {state["vector_step"] for state in current}
    if len(steps) == 1:
        return current
    older = min(steps)  # killed while writing: the seeds ahead still hold that step as their previous one
    chosen = []
    for d, state in zip(run_dirs, current):
        if state["vector_step"] != older:
            state = read_checkpoint(d, PREVIOUS) if (Path(d) / PREVIOUS).is_file() else {}
        if state.get("vector_step") != older:
            raise RunFolderError(
                f"the checkpoints of seeds {batch} were not written at one vector step and "
                f"{d} holds none of step {older}; pass {argument('overwrite')} to start again"
            )
        chosen.append(state)
    return chosen


def read_checkpoint(run_dir: Path, name: str = CHECKPOINT) -> dict[str, Any]:
    """The checkpoint's state, or a RunFolderError that says why it cannot be used."""
    path = Path(run_dir) / name
    if not path.is_file():
        raise RunFolderError(
            f"{run_dir} has no {CHECKPOINT} to resume from (a run writes one every "
            f"{argument('checkpoint_every')} episodes and when it is stopped); pass "
            f"{argument('overwrite')} to start again"
        )
    data = path.read_bytes()
    digest_end = len(MAGIC) + 64
    if not data.startswith(MAGIC) or data[digest_end : digest_end + 1] != b"\n":
        raise RunFolderError(f"{path} is not a keras-rl checkpoint (bad header); the run folder is left as it is")
    payload = data[digest_end + 1 :]
    if hashlib.sha256(payload).hexdigest().encode() != data[len(MAGIC) : digest_end]:
        raise RunFolderError(
            f"{path} is corrupt (checksum mismatch: truncated or damaged); the run folder is left as it is"
        )
    try:
        return pickle.loads(payload)
    except Exception as exc:  # a checksum-valid file from an incompatible version
        raise RunFolderError(f"{path} could not be read ({type(exc).__name__}: {exc})") from None
