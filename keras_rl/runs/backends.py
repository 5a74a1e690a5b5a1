"""Which backend runs a command's seeds: in-process, or Ray (local or a cluster)."""

from __future__ import annotations

from keras_rl.runs.jobs import Backend, InProcess


def backend_for(workers: int, jobs: int, address: str | None = None) -> Backend:
    """In-process for one worker and no cluster (no start-up cost); Ray otherwise: a local
    instance of ``workers`` CPUs, or the cluster at ``address``."""
    if address is None and (workers <= 1 or jobs <= 1):
        return InProcess()
    from keras_rl.runs.ray_backend import RayBackend

    return RayBackend(workers=workers, address=address)
