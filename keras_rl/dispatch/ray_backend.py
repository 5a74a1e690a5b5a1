"""The Ray backend of the job runner: seeds as Ray tasks, on this machine or on a cluster.

- ``RayBackend(workers=K)`` starts a local Ray instance for the command (``address="local"``,
  so a stale cluster file in Ray's temp folder is never joined) and shuts it down after.
  Every server it starts listens on loopback only: ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``
  is set before ``ray.init`` (``tests/test_ray.py`` checks the listening sockets).
- ``RayBackend(address="HOST:PORT")`` (or ``RAY_ADDRESS``) runs the same jobs on an existing
  cluster. Ray 2.60 clusters use token authentication: the driver needs the cluster's token
  (``RAY_AUTH_TOKEN``, or the file ``RAY_AUTH_TOKEN_PATH`` names; ``ray start --head``
  writes ``~/.ray/auth_token``). See the README.

Each task runs one seed in a temporary folder of the node it lands on, with one
TensorFlow/torch thread, and returns the folder's files; the driver writes them atomically
under the job's ``out_dir``, so results land where the command ran whether or not the
cluster shares a filesystem (a resumed job ships its folder to the task first). A worker
that dies is retried by Ray (``max_retries``); the seed reruns from scratch and writes the
same ``episodes.csv``. On Ctrl-C or SIGTERM the driver starts no queued seed, tells the
running ones to stop at their next episode end (a stop flag they poll), and writes what
they return: their summaries say ``interrupted``.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.atomic import atomic_write_bytes
from keras_rl.dispatch.jobs import drive, execute, members, say_job_failed, seeds_bar, with_each
from keras_rl.errors import ConfigError, argument
from keras_rl.runs.checkpoint import delete_checkpoints
from keras_rl.runs.signals import sigterm_as_interrupt

MAX_RETRIES = 3
"""How often Ray reruns a seed whose worker died."""


def _pack(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in Path(folder).iterdir() if p.is_file() and not p.name.startswith(".")}


def _seed_task(job, files_in: list[dict[str, bytes]] | None, stop_flag) -> list[dict[str, bytes]] | None:
    """One job (a seed, or a batch of seeds on one seed axis) on a Ray worker. ``files_in``
    None: this node shares the driver's disk (a local instance), so each seed writes its
    folder in place, visible as it runs. Otherwise each seed's folder is made in a
    temporary directory (with the files of a run to resume) and returned whole, one dict
    per seed. A rerun after a dead worker starts the folders afresh (or resumes)."""
    import ray

    def should_stop() -> bool:
        return ray.get(stop_flag.is_set.remote())

    group = members(job)
    resume = group[0].start == "resume"
    node = ray.get_runtime_context().get_node_id()
    if files_in is None:
        execute(
            with_each(job, lambda j: dataclasses.replace(j, start="resume" if resume else "overwrite")),
            progress=False,
            should_stop=should_stop,
        )
        for j in group:
            _record_node(Path(j.out_dir), node)
        return None
    with tempfile.TemporaryDirectory(prefix="keras-rl-seed-") as tmp:
        dirs = [Path(tmp) / f"seed_{j.config.seed}" for j in group]
        for run_dir, files in zip(dirs, files_in):
            run_dir.mkdir()
            for name, data in files.items():
                (run_dir / name).write_bytes(data)
        moved = iter(dirs)
        execute(
            with_each(job, lambda j: dataclasses.replace(j, out_dir=next(moved), start="resume" if resume else "new")),
            progress=False,
            should_stop=should_stop,
        )
        for run_dir in dirs:
            _record_node(run_dir, node)
        return [_pack(run_dir) for run_dir in dirs]


def _record_node(run_dir: Path, node_id: str) -> None:
    """The Ray node a seed ran on, in its summary's provenance."""
    import json

    from keras_rl.atomic import atomic_write_json

    path = run_dir / "summary.json"
    if path.is_file():
        summary = json.loads(path.read_text())
        summary.setdefault("provenance", {})["ray_node_id"] = node_id
        atomic_write_json(path, summary)


class _StopFlag:
    def __init__(self):
        self.value = False

    def set(self) -> None:
        self.value = True

    def is_set(self) -> bool:
        return self.value


def require_ray() -> None:
    """A ConfigError (exit 2) saying how to get Ray, where it is not installed."""
    import importlib.util

    if importlib.util.find_spec("ray") is None:
        raise ConfigError(
            f"{argument('address')} (or $RAY_ADDRESS) runs seeds on a Ray cluster, and Ray is not installed: "
            f"pip install 'keras-rl-repro[ray]' ({argument('workers', 'N')} alone needs no Ray)"
        )


def address_parts(address: str, source: str = "address") -> tuple[str, int] | None:
    """``(host, port)`` of a ``HOST:PORT`` address, None for Ray's own names (``auto``, ``local``,
    ``ray://...``), or a ConfigError naming a malformed one and where it came from; no network."""
    if address in ("auto", "local") or address.startswith("ray://"):
        return None
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit():
        named = source if source.startswith("$") else argument(source)
        raise ConfigError(f"{named} {address!r} is not HOST:PORT (for example 127.0.0.1:6379)")
    return host, int(port)


def check_reachable(address: str, timeout: float = 5.0, source: str = "address") -> None:
    """A ConfigError within ``timeout`` seconds if nothing listens at ``HOST:PORT``, instead of
    Ray's own long retries. ``source`` names where the address came from (the argument
    ``address`` or ``$RAY_ADDRESS``), as the message says."""
    parsed = address_parts(address, source)
    if parsed is None:
        return
    host, port = parsed
    source = source if source.startswith("$") else argument(source)
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise ConfigError(
            f"no Ray cluster answers at {address} (from {source}; {exc}); start one with `ray start --head` "
            "or check the address"
        ) from None


@dataclass
class RayBackend:
    """Seeds as Ray tasks. ``workers``: CPUs of the local instance (and seeds at once);
    ``address``: join that cluster instead (seeds at once = its CPUs)."""

    workers: int = 1
    address: str | None = None
    object_store_mb: int = 128

    def _init(self):
        if self.address:
            import ray

            check_reachable(self.address)
            ray.init(address=self.address, log_to_driver=False, ignore_reinit_error=True)
            return ray, max(1, int(ray.cluster_resources().get("CPU", 1)))
        # Every server on loopback only: the variable, read when Ray's modules are imported (here
        # and in every process the instance starts), makes Ray take 127.0.0.1 as this node's
        # address. Set after Ray was imported it is too late, and Ray then listens on every
        # interface (measured), so that case is refused.
        os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
        import logging

        import ray
        from ray._private import ray_constants

        if ray_constants.ENABLE_RAY_CLUSTER:  # Ray was imported before the variable was set
            raise ConfigError(
                "Ray was imported in this process before RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0 was set, "
                "so a local instance would listen on every interface; set the variable in the "
                "environment before Python starts (tests/conftest.py does)"
            )
        # A new local instance turns token authentication on by itself and says so on every run;
        # the protection stays, only that notice is not shown (setting RAY_AUTH_MODE instead leaves
        # a token-mode variable in this process, and a cluster started later by it hangs on clients
        # without the token: measured).
        logging.getLogger("ray._private.authentication.authentication_token_setup").setLevel(logging.ERROR)
        ray.init(
            address="local",
            num_cpus=self.workers,
            include_dashboard=False,
            log_to_driver=False,
            object_store_memory=self.object_store_mb * 1024 * 1024,
            _node_ip_address="127.0.0.1",
        )
        return ray, self.workers

    def run(self, jobs: list, progress: bool, after_job=None) -> bool:
        ray, slots = self._init()
        try:
            with sigterm_as_interrupt():  # ray.init replaces the driver's SIGTERM handler: take it back
                return self._run(ray, slots, jobs, progress, after_job)
        finally:
            ray.shutdown()

    def _run(self, ray, slots: int, jobs: list, progress: bool, after_job=None) -> bool:
        tasks = _RayWorkers(ray, self.address is not None, seeds_bar(len(jobs)) if progress else None, after_job)
        try:
            interrupted, _ = drive(jobs, slots, tasks)
        finally:
            if tasks.bar is not None:
                tasks.bar.close()
        return interrupted


class _RayWorkers:
    """Ray's side of ``jobs.drive``: each job a task (Ray retries a task whose worker died,
    ``MAX_RETRIES`` times), all sharing one stop flag; on a cluster (``ship``) a resumed job's files
    travel with it and every job's files come back, since the nodes may not share this disk."""

    def __init__(self, ray, ship: bool, bar, after_job):
        self.ray, self.ship, self.bar, self.after_job = ray, ship, bar, after_job
        self.task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_seed_task)
        self.flag = ray.remote(num_cpus=0)(_StopFlag).remote()

    def submit(self, job) -> Any:
        files = [_pack(m.out_dir) if m.start == "resume" else {} for m in members(job)] if self.ship else None
        return self.task.remote(job, files, self.flag)

    def done(self, handles: list, timeout: float | None) -> list:
        return self.ray.wait(handles, num_returns=1 if timeout is not None else len(handles), timeout=timeout)[0]

    def collect(self, ref, job, again) -> bool:
        try:
            files = self.ray.get(ref)
        except self.ray.exceptions.RayTaskError as exc:  # one line, not the worker's coloured traceback
            cause = exc.cause if getattr(exc, "cause", None) is not None else exc
            say_job_failed(job, cause, _plain(str(cause)))
        else:
            if self.ship:
                for member, member_files in zip(members(job), files):
                    _land(member, member_files)
        if self.after_job is not None:
            self.after_job(job)
        if self.bar is not None:
            self.bar.update(1)
        return False

    def stop(self) -> None:
        self.flag.set.remote()  # running seeds stop at their next episode end; queued ones never start

    def poll(self) -> None:
        pass

    def recover(self) -> None:
        pass


def _plain(text: str) -> str:
    """``text`` without terminal colour codes, on one line."""
    import re

    return " ".join(re.sub(r"\x1b\[[0-9;]*m", "", text).split())


def _land(job, files: dict[str, bytes]) -> None:
    """Write a task's folder under the driver's ``out_dir``, each file atomically."""
    import shutil

    out = Path(job.out_dir)
    if job.start == "overwrite" and out.exists():
        shutil.rmtree(out)
    for name, data in files.items():
        atomic_write_bytes(out / name, data)
    if "checkpoint.pkl" not in files:
        delete_checkpoints(out)
