"""``--workers N`` on this machine: seeds in a pool of the standard library's processes, no Ray.

Each job (a seed, or a seed batch) runs in a fresh process (``spawn``: TensorFlow does not
survive ``fork``) of a ``concurrent.futures.ProcessPoolExecutor``, writing its folder in place,
as ``InProcess`` would. On Ctrl-C or SIGTERM the driver starts no queued job, sets a stop flag
that running seeds poll at their next episode end, and waits for them: their summaries say
``interrupted``. The workers ignore SIGINT themselves (a terminal's Ctrl-C reaches the whole
process group), so the flag is the one way they stop. A job that raises is named on the console
and the others go on. A worker that dies (``kill -9``, out of memory) breaks the pool: its jobs,
and the others that were running, start again in a new pool from the beginning (or from their
checkpoint, for a resumed job), at most ``MAX_RETRIES`` times each, once the broken pool's other
workers are killed (``_kill_survivors``); the seeds are functions of
their seed, so they write the same ``episodes.csv``. Ray (``pip install 'keras-rl-repro[ray]'``)
is for ``--address``, a cluster.
"""

from __future__ import annotations

import dataclasses
import sys
from concurrent.futures import ALL_COMPLETED, FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.dispatch.jobs import AfterJob, drive, execute, members, say_job_failed, with_each
from keras_rl.runs.signals import sigterm_as_interrupt

_stop: Any = None
"""The driver's stop flag, in each worker (set by ``_start_worker``)."""

MAX_RETRIES = 3
"""How often a job starts again after its worker died."""


def _start_worker(stop) -> None:
    import signal

    global _stop
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _stop = stop


def _run_job(job) -> None:
    execute(job, progress=False, should_stop=_stop.is_set)


@dataclass
class ProcessPool:
    """Up to ``workers`` jobs at once, each in a process of its own."""

    workers: int

    def run(self, jobs: list, progress: bool, after_job: AfterJob | None = None) -> bool:
        import multiprocessing

        size = max(1, min(self.workers, len(jobs)))
        bar = EpisodesBar(jobs) if progress else None
        pool = _PoolWorkers(multiprocessing.get_context("spawn"), size, bar, after_job)
        try:
            with sigterm_as_interrupt():
                interrupted, _ = drive(jobs, size, pool)
        finally:
            pool.pool.shutdown(wait=not pool.in_flight, cancel_futures=True)
            if pool.bar is not None:
                pool.bar.close()
        return interrupted


class _PoolWorkers:
    """The pool's side of ``jobs.drive``: processes of a ``ProcessPoolExecutor`` that share a stop
    flag; a job whose worker died starts again, at most ``MAX_RETRIES`` times, in a new pool."""

    def __init__(self, context, size: int, bar: EpisodesBar | None, after_job: AfterJob | None):
        self.context, self.size, self.bar, self.after_job = context, size, bar, after_job
        self.stop_flag = context.Event()
        self.retries: dict[int, int] = {}
        self.in_flight: set[Future] = set()
        self.pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.size, mp_context=self.context, initializer=_start_worker, initargs=(self.stop_flag,)
        )

    def submit(self, job) -> Future:
        future = self.pool.submit(_run_job, job)
        self.in_flight.add(future)
        return future

    def done(self, handles: list, timeout: float | None) -> list:
        return list(
            wait(handles, timeout=timeout, return_when=ALL_COMPLETED if timeout is None else FIRST_COMPLETED).done
        )

    def collect(self, future: Future, job, again) -> bool:
        self.in_flight.discard(future)
        error = future.exception()
        broken = isinstance(error, BrokenProcessPool) and not self.stop_flag.is_set()
        if broken:
            key = id(job)
            self.retries[key] = self.retries.get(key, 0) + 1
            if self.retries[key] <= MAX_RETRIES:
                print(
                    f"warning: a worker died running {_seeds(job)}; it starts again "
                    f"({self.retries[key]} of {MAX_RETRIES})",
                    file=sys.stderr,
                )
                retry = _again(job)
                self.retries[id(retry)] = self.retries.pop(key)
                again(retry)
                return True
        if error is not None:
            say_job_failed(job, error)
        if self.after_job is not None:
            self.after_job(job)
        if self.bar is not None:
            self.bar.job_done(job)
        return broken

    def stop(self) -> None:
        self.stop_flag.set()  # running seeds stop at their next episode end; queued ones never start

    def poll(self) -> None:
        if self.bar is not None:
            self.bar.poll()

    def recover(self) -> None:
        _kill_survivors(self.pool)
        self.pool.shutdown(wait=True, cancel_futures=True)
        self.pool = self._new_pool()


def _kill_survivors(pool: ProcessPoolExecutor) -> None:
    """SIGKILL the workers a broken pool still has, before its jobs start again in a new one.
    CPython ends them with SIGTERM, which a worker's training loop takes as "stop after this
    episode" (``runs/signals.py``): a survivor would go on to write its seed's folder as
    interrupted while the job's retry writes the same folder, and the broken pool's shutdown
    waits for it (the likely cause of a run of ``tests/test_pool.py``'s killed-worker test whose
    command printed its last line and never exited). Python 3.11's executor names its workers
    only in ``_processes``; 3.14 adds ``kill_workers()``."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.kill()
            process.join(timeout=30)


def _seeds(job) -> str:
    seeds = [str(m.config.seed) for m in members(job)]
    return f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {', '.join(seeds)}"


def _again(job):
    """A job to start again after its worker died: from its checkpoint if it was resumed, else
    afresh (its folder, partly written, is cleared)."""

    return with_each(job, lambda j: dataclasses.replace(j, start="resume" if j.start == "resume" else "overwrite"))


class EpisodesBar:
    """The pool's progress in episodes (each worker's own bar is off): every seed's budget, and the
    rows its ``episodes.csv`` holds, read every half second; finished seeds in the postfix."""

    def __init__(self, jobs: list):
        from tqdm.auto import tqdm

        self.seeds = [m for job in jobs for m in members(job)]
        total = sum(int(m.config.episodes) for m in self.seeds)
        self.done = 0
        self.bar = tqdm(total=total, unit="ep", desc=f"{len(self.seeds)} seeds", dynamic_ncols=True)

    def poll(self) -> None:
        played = 0
        for m in self.seeds:
            try:
                with open(Path(m.out_dir) / "episodes.csv", "rb") as fh:
                    played += max(0, fh.read().count(b"\n") - 1)
            except OSError:
                continue
        self.bar.n = min(played, self.bar.total)
        self.bar.set_postfix(seeds_done=f"{self.done}/{len(self.seeds)}", refresh=False)
        self.bar.refresh()

    def job_done(self, job) -> None:
        self.done += len(members(job))
        self.poll()

    def close(self) -> None:
        self.poll()
        self.bar.close()
