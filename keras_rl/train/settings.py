"""``TrainSettings``: how a set of seeds trains, apart from what their configs say."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from keras_rl.runs.evaluate import EvalSchedule


@dataclass(frozen=True)
class TrainSettings:
    """Everything an engine needs besides the experiment, the configs and their folders.

    Parsed once where a command reads its flags (``dispatch/options.RunOptions`` and the job's
    start mode), carried in a ``dispatch/jobs.SeedJob`` across a process boundary, and read by the
    engine: no field is forwarded one by one."""

    progress: bool = True
    """A tqdm bar per batch (``--no-progress`` turns it off)."""
    position: int = 0
    """The bar's line, when several run at once."""
    threads: int | None = 1
    """TensorFlow's intra- and inter-op threads (None: TensorFlow's own choice)."""
    resume: bool = False
    """Continue from each folder's checkpoint (``--resume``) instead of starting fresh."""
    checkpoint_every: int = 10
    """Write a checkpoint every N episodes per seed, and when stopped (``--checkpoint-every``)."""
    tensorboard: Path | None = None
    """Also log per-episode scalars under this folder, one TensorBoard run per seed."""
    command: str | None = None
    """The command line to record in each summary (a Ray worker's own argv is not it)."""
    evaluation: EvalSchedule | None = None
    """Greedy evaluations during training (``--eval-every``), or none."""


DEFAULT_SETTINGS = TrainSettings()
"""A fresh run with a progress bar, checkpoints every 10 episodes, nothing else."""
