"""Which backend runs a command's seeds: in-process, a pool of processes, or a Ray cluster."""

from __future__ import annotations

from typing import TYPE_CHECKING

from keras_rl.dispatch import jobs as dispatch
from keras_rl.dispatch.jobs import AfterJob, Backend, InProcess, JobsOutcome

if TYPE_CHECKING:
    from keras_rl.dispatch.options import RunOptions


def backend_for(workers: int, jobs: int, address: str | None = None) -> Backend:
    """In-process for one worker (no start-up cost); the standard library's process pool for
    ``--workers N`` on this machine (``dispatch/pool_backend.py``); Ray for a cluster at ``address``
    (the ``ray`` extra)."""
    if address is None:
        if workers <= 1 or jobs <= 1:
            return InProcess()
        from keras_rl.dispatch.pool_backend import ProcessPool

        return ProcessPool(workers=workers)
    from keras_rl.dispatch.ray_backend import RayBackend, require_ray

    require_ray()
    return RayBackend(workers=workers, address=address)


def train_seeds(jobs: list, options: RunOptions, after_job: AfterJob | None = None, pack: bool = True) -> JobsOutcome:
    """The one way every command trains its seeds: pack them into seed batches (``--seed-batch``;
    ``pack=False``: the caller packed them, as ``check`` does per rule), pick the backend
    (``--workers``, ``--address``), run, and read back what each folder holds. The caller says
    what a Ctrl-C means for it (``JobsOutcome.interrupted``)."""
    if pack:
        jobs = dispatch.batched(jobs, options.seed_batch, options.workers)
    backend = backend_for(options.workers, len(jobs), options.address)  # a global, read at call time: tests replace it
    interrupted = backend.run(jobs, options.progress, after_job) if jobs else False
    return dispatch.read_outcome(jobs, interrupted)
