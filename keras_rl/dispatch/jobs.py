"""Where seeds are dispatched: ``SeedJob`` records, how a job opens its folders and trains on
its engine, and the execution backends that ``dispatch/backends.train_seeds`` picks from.

- ``InProcess``: one seed after another in this process (one worker: no start-up cost).
- ``RayBackend`` (``ray_backend.py``): seeds as Ray tasks on a local instance or a cluster.

``backends.py`` picks one from ``--workers`` and ``--address``.

A backend only decides where ``execute`` runs; each seed writes its own folder, and the
outcome is read back from disk, so an interrupted worker still reports what it kept.
"""

from __future__ import annotations

import math
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

from keras_rl.errors import ConfigError, RunFolderError, argument
from keras_rl.registry import get_experiment
from keras_rl.runs.checkpoint import CHECKPOINT, checkpoint_batch
from keras_rl.runs.evaluate import EvalSchedule
from keras_rl.runs.files import run_folder_locks
from keras_rl.runs.lifecycle import UNRECORDED_ENGINE
from keras_rl.runs.packed import refuse_packed
from keras_rl.runs.provenance import command_line
from keras_rl.runs.signals import sigterm_as_interrupt
from keras_rl.runs.summary import RunSummary
from keras_rl.train.engine import VECTORISED, get_engine
from keras_rl.train.settings import TrainSettings


@dataclass(frozen=True)
class SeedJob:
    """One seed of one experiment: its typed config (a post's ``ExperimentConfig``, pickled only
    where a process boundary is real: the pool, Ray) and its folder."""

    experiment: str
    config: Any
    out_dir: Path
    start: Literal["new", "overwrite", "resume"] = "new"
    """``overwrite``: the folder is cleared whole first; ``resume``: continue from its checkpoint."""
    checkpoint_every: int = 10
    tensorboard: Path | None = None
    """Write TensorBoard scalars under this folder (one run per seed)."""
    command: str = ""
    """The command line that asked for the job, recorded in its summary (a Ray worker's own
    argv is not it)."""
    evaluation: EvalSchedule | None = None
    """Greedy evaluations during training (``--eval-every``), or none."""
    engine: str = UNRECORDED_ENGINE
    """Which engine trains it (``train/engine.ENGINES``)."""

    @classmethod
    def of(cls, config, out_dir: Path, **options: Any) -> SeedJob:
        options.setdefault("command", command_line())
        return cls(config.experiment, config, Path(out_dir), **options)


@dataclass(frozen=True)
class SeedBatchJob:
    """Several seeds of one config trained together (``--seed-batch``) on one seed axis
    (``train/loop.py``); they start alike (all new, all overwritten, or all resumed)."""

    jobs: tuple[SeedJob, ...]


def members(job) -> tuple[SeedJob, ...]:
    """The seed jobs a job stands for: itself, or a batch's seeds."""
    return job.jobs if isinstance(job, SeedBatchJob) else (job,)


def auto_batch_size(seeds: int, workers: int, cap: int) -> int:
    """``--seed-batch auto``: the batch size that splits ``seeds`` into as few rounds of
    ``workers`` jobs as batches of at most ``cap`` allow, the jobs as even as they can be
    (30 seeds, 2 workers, cap 10: four jobs of 8, 8, 8 and 6, not 10, 10 and 10, whose
    third job would run on one core while the other idles)."""
    if seeds <= 1:
        return 1
    rounds = math.ceil(seeds / (workers * cap))
    return math.ceil(seeds / (rounds * workers))


def batched(jobs: list[SeedJob], seed_batch: int | str, workers: int = 1) -> list:
    """``jobs`` packed into batches of up to ``seed_batch`` seeds (``"auto"``: of the size
    ``auto_batch_size`` gives for each group, with the post's ``SEED_BATCH_CAP`` and
    ``workers`` jobs at once). Only jobs that differ in
    nothing but the seed share a batch (a sweep's grid points never do), and only jobs of
    an experiment and framework with a seed-batched learner (``learners/table.py``), or of the
    vectorised engine (its program is a batch), are packed: the others (post 003's PyTorch
    tutorial on the Gymnasium loop in ``compare``, say) run alone, and so do configs no
    stacked learner covers (``learners/table.NOT_STACKED``) under ``"auto"``; a fixed
    size refuses them with a ConfigError before anything runs. A job
    that resumes joins the batch its checkpoint was written by, whatever ``seed_batch`` is
    now. A group of one is the job itself."""
    from keras_rl.learners.table import STACKED, batch_refusal, seed_batch_cap

    groups: dict[tuple, list[SeedJob]] = {}
    resumed: dict[tuple, list[SeedJob]] = {}
    alone = []
    for job in jobs:
        if job.start == "resume":
            batch = checkpoint_batch(job.out_dir)
            if len(batch) > 1:
                resumed.setdefault((tuple(batch), job.command), []).append(job)
                continue
        seed_axis = (job.experiment, job.config.framework) in STACKED or job.engine in VECTORISED
        if seed_batch == 1 or job.start == "resume" or not seed_axis:
            alone.append(job)
            continue
        refusal = batch_refusal(job.experiment, job.config)
        if refusal is not None:
            if seed_batch != "auto":
                raise ConfigError(
                    f"{argument('seed_batch', seed_batch)} does not cover {Path(job.out_dir).parent}: {refusal}; "
                    f"pass {argument('seed_batch', 'auto')}, which runs such seeds alone, or "
                    f"{argument('seed_batch', 1)}"
                )
            alone.append(job)
            continue
        key = (
            job.experiment,
            job.config.replace(seed=0),  # equal but for the seed
            job.command,
            str(job.tensorboard),
            job.checkpoint_every,
            job.evaluation,
            job.engine,
        )
        groups.setdefault(key, []).append(job)
    out = []
    for group in groups.values():
        size = (
            auto_batch_size(len(group), workers, seed_batch_cap(group[0].experiment, group[0].config.framework))
            if seed_batch == "auto"
            else int(seed_batch)
        )
        for i in range(0, len(group), size):
            chunk = tuple(group[i : i + size])
            out.append(chunk[0] if len(chunk) == 1 else SeedBatchJob(chunk))
    for (batch, _), group in resumed.items():
        have = sorted(j.config.seed for j in group)
        # the seeds of the batch that still hold its checkpoint: a vectorised batch removes those
        # of the seeds it shed, which then resume no more (runs/checkpoint.read_batch_checkpoints)
        folder = Path(group[0].out_dir).parent
        if have != sorted(s for s in batch if (folder / f"seed_{s}" / CHECKPOINT).is_file()):
            raise RunFolderError(
                f"{group[0].out_dir} was checkpointed in a batch of seeds {list(batch)}; resume "
                f"them together (this command resumes {have} of them)"
            )
        out.append(SeedBatchJob(tuple(sorted(group, key=lambda j: list(batch).index(j.config.seed)))))
    return out + alone


@dataclass
class JobsOutcome:
    summaries: list[RunSummary] = field(default_factory=list)
    """What each job's folder says, in job order (jobs that never started are absent)."""
    interrupted: bool = False


def run_job(job, progress: bool = True, position: int = 0, should_stop=None) -> list[RunSummary]:
    """Train a job (a seed, or a batch of seeds) here on its engine (``train/engine.py``): its
    folders locked (a second command writing them is refused) and, for ``overwrite``, cleared
    whole (no weights or ``evaluation.json`` of the old run survive). Returns each seed's summary."""
    group = members(job)
    experiment = get_experiment(group[0].experiment)
    configs = [j.config for j in group]
    first = group[0]
    for j in group:
        refuse_packed(Path(j.out_dir))
    with run_folder_locks(j.out_dir for j in group):
        for j in group:
            if j.start == "overwrite" and Path(j.out_dir).exists():
                shutil.rmtree(j.out_dir)
        settings = TrainSettings(
            progress=progress,
            position=position,
            resume=first.start == "resume",
            checkpoint_every=first.checkpoint_every,
            tensorboard=first.tensorboard,
            command=first.command,
            evaluation=first.evaluation,
        )
        engine = get_engine(first.engine)
        return engine.train(experiment, configs, [j.out_dir for j in group], settings, should_stop=should_stop)


def with_each(job, change):
    """``job`` with ``change`` applied to each of its seeds (a seed, or every seed of a batch)."""
    if isinstance(job, SeedBatchJob):
        return SeedBatchJob(tuple(change(j) for j in job.jobs))
    return change(job)


def seeds_bar(total: int):
    """A backend's progress over its jobs (each seed's episodes have their own bar in process)."""
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="seed", desc="seeds", dynamic_ncols=True)


def say_job_failed(job, error: BaseException, text: str | None = None) -> None:
    """A job whose worker raised: name its seeds that left no summary (a seed whose summary
    records the error is reported from it by the command), on one line."""
    unsaid = [m for m in members(job) if not (Path(m.out_dir) / "summary.json").is_file()]
    if unsaid:
        import sys

        who = ", ".join(f"seed {m.config.seed}" for m in unsaid)
        print(
            f"error: {who} in {Path(unsaid[0].out_dir).parent}: {type(error).__name__}: {text or error}",
            file=sys.stderr,
        )


def job_summary(summaries: list[RunSummary]) -> RunSummary:
    """What a job reports: its first interrupted seed's summary, else its last seed's."""
    return next((s for s in summaries if s.status == "interrupted"), summaries[-1])


def execute(job, progress: bool = True, position: int = 0, should_stop=None) -> RunSummary:
    """Run one job here on its engine (a Ray worker's call); ``job_summary`` of its seeds.
    Drawing ``curve.png`` is the command's job (``train_seeds(..., after_job=...)``): nothing
    a worker imports reaches plotting."""
    return job_summary(run_job(job, progress, position, should_stop))


AfterJob = Callable[["SeedJob | SeedBatchJob"], None]
"""Called in the command's process once a job's folders are written, however the job ended."""


class Backend(Protocol):
    def run(self, jobs: list[SeedJob], progress: bool, after_job: AfterJob | None = None) -> bool:
        """Run the jobs; True if Ctrl-C stopped them (no further job starts then)."""


STOP_WAIT_SECONDS = 300
"""How long a driver waits for its running seeds to stop after Ctrl-C or SIGTERM."""


class Workers(Protocol):
    """What the one dispatch loop (``drive``) asks of a backend's workers (the pool's processes,
    Ray's tasks): start a job, say which started jobs are done, report one, stop them all."""

    def submit(self, job) -> Any:
        """Start ``job``; a handle for it."""

    def done(self, handles: list, timeout: float | None) -> list:
        """Those of ``handles`` that are done within ``timeout`` seconds (None: all of them)."""

    def collect(self, handle, job, again: Callable[[Any], None]) -> bool:
        """Report a finished job (``again(job)`` queues one to start again first); True where
        the backend broke and must be ``recover``ed before anything else starts."""

    def stop(self) -> None:
        """Ask every running job to stop at its next episode end."""

    def poll(self) -> None:
        """Between waits: a progress bar's update, or nothing."""

    def recover(self) -> None:
        """After a break: the backend as new (a broken pool replaced)."""


def drive(jobs: list, slots: int, workers: Workers) -> tuple[bool, int]:
    """The one submit/collect/drain loop of the pool and Ray: up to ``slots`` jobs at once, each
    reported as it ends; on Ctrl-C or SIGTERM no queued job starts, the running ones are asked to
    stop and waited for (``STOP_WAIT_SECONDS`` at most; a second Ctrl-C meanwhile keeps waiting).
    Whether it was interrupted, and how many jobs still ran when it gave up waiting."""
    pending: list = list(jobs)
    running: dict[Any, Any] = {}

    def again(job) -> None:
        pending.insert(0, job)

    def collect(handles) -> bool:
        broke = False
        for handle in handles:
            broke |= workers.collect(handle, running.pop(handle), again)
        return broke

    try:
        while pending or running:
            while pending and len(running) < slots:
                job = pending.pop(0)
                running[workers.submit(job)] = job
            workers.poll()
            if collect(workers.done(list(running), 0.5)):
                collect(workers.done(list(running), None))  # the backend is gone: every job it ran with it
                workers.recover()
    except KeyboardInterrupt:
        workers.stop()
        deadline = time.monotonic() + STOP_WAIT_SECONDS
        while running and time.monotonic() < deadline:
            try:
                collect(workers.done(list(running), 1.0))
            except KeyboardInterrupt:
                continue
        if running:
            print(
                f"warning: {len(running)} jobs did not stop within {STOP_WAIT_SECONDS} s; their folders may not "
                "be written",
                file=sys.stderr,
            )
        return True, len(running)
    return False, 0


class InProcess:
    def run(self, jobs: list[SeedJob], progress: bool, after_job: AfterJob | None = None) -> bool:
        try:
            with sigterm_as_interrupt():  # between seeds too, SIGTERM stops like Ctrl-C
                for job in jobs:
                    try:
                        status = job_summary(run_job(job, progress)).status
                    finally:
                        if after_job is not None:
                            after_job(job)
                    if status == "interrupted":
                        return True
        except KeyboardInterrupt:  # arrived outside a seed's episode loop
            return True
        return False


def read_outcome(jobs: list, interrupted: bool) -> JobsOutcome:
    """What each job's folders hold once the backend has run them (jobs that never started
    are absent; a summary that exists but cannot be read is an error)."""
    summaries = []
    for job in (m for j in jobs for m in members(j)):
        try:
            summaries.append(RunSummary.read(job.out_dir))
        except RunFolderError:
            if (Path(job.out_dir) / "summary.json").exists():
                raise
    return JobsOutcome(summaries, interrupted)
