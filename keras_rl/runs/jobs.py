"""Where seeds are dispatched: ``SeedJob`` records and the one ``run_jobs`` that ``reproduce``
and ``compare`` both call, with the execution backend as a parameter.

- ``InProcess``: one seed after another in this process (one worker: no start-up cost).
- ``ProcessPool``: at most ``workers`` spawned processes, one seed each.

A backend only decides where ``execute`` runs; each seed writes its own folder, and the
outcome is read back from disk, so an interrupted worker still reports what it kept.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import signal
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

from keras_rl.errors import RunFolderError
from keras_rl.registry import get_experiment
from keras_rl.report.plots import plot_seed_curve
from keras_rl.runs.loop import run_seed
from keras_rl.runs.signals import sigterm_as_interrupt
from keras_rl.runs.summary import RunSummary

EXIT_INTERRUPTED = 130


@dataclass(frozen=True)
class SeedJob:
    """One seed of one experiment: its full config (``config.to_dict()``) and its folder."""

    experiment: str
    config: dict[str, Any]
    out_dir: Path
    start: Literal["new", "overwrite", "resume"] = "new"
    """``overwrite``: the folder is cleared whole first; ``resume``: continue from its checkpoint."""
    checkpoint_every: int = 10
    tensorboard: Path | None = None
    """Write TensorBoard scalars under this folder (one run per seed)."""

    @classmethod
    def of(cls, config, out_dir: Path, **options: Any) -> "SeedJob":
        return cls(config.experiment, config.to_dict(), Path(out_dir), **options)


@dataclass
class JobsOutcome:
    summaries: list[RunSummary] = field(default_factory=list)
    """What each job's folder says, in job order (jobs that never started are absent)."""
    interrupted: bool = False


def execute(job: SeedJob, progress: bool = True, position: int = 0) -> RunSummary:
    """Run one job here and draw its ``curve.png`` (whatever the run's end)."""
    experiment = get_experiment(job.experiment)
    config = experiment.config_cls.from_dict(job.config)
    if job.start == "overwrite" and Path(job.out_dir).exists():
        shutil.rmtree(job.out_dir)  # whole: no weights or evaluation.json of the old run survive
    try:
        return run_seed(experiment, config, job.out_dir, progress=progress, position=position,
                        resume=job.start == "resume", checkpoint_every=job.checkpoint_every,
                        tensorboard=job.tensorboard)
    finally:
        try:
            plot_seed_curve(job.out_dir, experiment, config)
        except OSError as exc:  # a full disk: the run's own files and summary are what count
            print(f"warning: could not draw {Path(job.out_dir) / 'curve.png'}: {exc}", file=sys.stderr)


class Backend(Protocol):
    def run(self, jobs: list[SeedJob], progress: bool) -> bool:
        """Run the jobs; True if Ctrl-C stopped them (no further job starts then)."""


class InProcess:
    def run(self, jobs: list[SeedJob], progress: bool) -> bool:
        try:
            with sigterm_as_interrupt():  # between seeds too, SIGTERM stops like Ctrl-C
                for job in jobs:
                    if execute(job, progress).status == "interrupted":
                        return True
        except KeyboardInterrupt:  # arrived outside a seed's episode loop
            return True
        return False


def _worker(job: SeedJob, progress: bool, position: int) -> None:
    if execute(job, progress, position).status == "interrupted":
        raise SystemExit(EXIT_INTERRUPTED)


@dataclass
class ProcessPool:
    """Seeds in at most ``workers`` spawned processes (TensorFlow is not fork-safe).

    On Ctrl-C no further seed starts; running seeds get SIGINT (a terminal sends it to them
    as well), write their partial results, and are waited for."""

    workers: int

    def run(self, jobs: list[SeedJob], progress: bool) -> bool:
        ctx = multiprocessing.get_context("spawn")
        pending, running = list(enumerate(jobs)), []
        try:
            with sigterm_as_interrupt():  # SIGTERM to the dispatcher stops the seeds like Ctrl-C
                while pending or running:
                    while pending and len(running) < self.workers:
                        i, job = pending.pop(0)
                        proc = ctx.Process(target=_worker, args=(job, progress, i % self.workers))
                        proc.start()
                        running.append(proc)
                    running[0].join(timeout=0.5)
                    for proc in [p for p in running if not p.is_alive()]:
                        running.remove(proc)
                        if proc.exitcode == EXIT_INTERRUPTED:  # a seed was stopped: start no other
                            raise KeyboardInterrupt
        except KeyboardInterrupt:
            _stop(running)
            return True
        return False


def _stop(running: list) -> None:
    """A terminal's Ctrl-C reached the workers too; give them a moment to flush, and
    interrupt only those that did not hear it (SIGINT sent to this process alone)."""
    try:
        for proc in running:
            proc.join(timeout=2.0)
    except KeyboardInterrupt:
        pass
    for proc in running:
        if proc.is_alive():
            os.kill(proc.pid, signal.SIGINT)
    for proc in running:
        while proc.is_alive():
            try:
                proc.join()
            except KeyboardInterrupt:  # a second Ctrl-C while the seeds flush: keep waiting
                pass


def backend_for(workers: int, jobs: int) -> Backend:
    """In-process for one worker or one job (no start-up cost); a process pool otherwise."""
    return InProcess() if workers <= 1 or jobs <= 1 else ProcessPool(workers)


def run_jobs(jobs: list[SeedJob], backend: Backend, progress: bool = True) -> JobsOutcome:
    """Run ``jobs`` on ``backend`` and read back what each folder holds."""
    interrupted = backend.run(jobs, progress) if jobs else False
    summaries = []
    for job in jobs:
        try:
            summaries.append(RunSummary.read(job.out_dir))
        except RunFolderError:
            if (Path(job.out_dir) / "summary.json").exists():
                raise
    return JobsOutcome(summaries, interrupted)
