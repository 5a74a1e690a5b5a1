"""``--workers N`` on one machine: seeds in the standard library's process pool
(``dispatch/pool_backend.py``), no Ray; and ``keras-rl sweep`` through it."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from clitools import default_signals, descendants, start_cli, wait_for_rows

from keras_rl.runs.files import read_episodes

pytestmark = pytest.mark.slow

CLI = [sys.executable, "-m", "keras_rl"]
# Pendulum for 3 episodes trains nothing (train_start is 1000 steps), so a job costs seconds;
# with the EMA threshold at -1300 some seeds pass and some do not, so the statistics have work.
SWEEP = [
    "sweep",
    "pendulum",
    "--grid",
    "noise_sigma=0.2,0.6",
    "--seeds",
    "0-1",
    "--episodes",
    "3",
    "--set",
    "threshold=-1300",
    "--set",
    "stop_at_threshold=false",
    "--no-progress",
]


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


def test_workers_on_one_machine_need_no_ray():
    """``--workers 2`` picks the process pool; only ``--address`` asks for Ray, and says how to get it."""
    from keras_rl.dispatch.backends import backend_for
    from keras_rl.dispatch.jobs import InProcess
    from keras_rl.dispatch.pool_backend import ProcessPool

    assert backend_for(2, 4) == ProcessPool(workers=2)
    assert isinstance(backend_for(2, 1), InProcess) and isinstance(backend_for(1, 4), InProcess)
    probe = subprocess.run(
        [
            sys.executable,
            "-c",
            "import keras_rl.dispatch.backends as b, sys; b.backend_for(2, 4); print('ray' in sys.modules)",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert probe.stdout.strip() == "False", probe.stderr


def test_address_without_ray_says_how_to_get_it(monkeypatch):
    import importlib.util

    from keras_rl.dispatch.backends import backend_for
    from keras_rl.errors import ConfigError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a))
    with pytest.raises(ConfigError, match=r"pip install 'keras-rl-repro\[ray\]'"):
        backend_for(2, 4, address="127.0.0.1:6379")


def _pool_workers(pid: int) -> list[int]:
    """The pool's worker processes under ``pid`` (spawned, so their command line says so)."""
    found = []
    for child in descendants(pid):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmdline:
            found.append(child)
    return found


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "s"
    proc = subprocess.run(
        [*CLI, *SWEEP, "--workers", "2", "--out", str(out)], capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr
    assert "4 jobs; 0 already done, 4 to run" in proc.stderr
    assert "median episodes to threshold" in proc.stdout and "None" not in proc.stdout  # #23.9: it printed None
    # issue 54 item 12: what it reused and trained (above), where it wrote, and no Markdown on the terminal
    assert f"report: {out / 'sweep.md'}" in proc.stdout and "**" not in proc.stdout + proc.stderr
    assert "Ray" not in proc.stderr  # no Ray instance: the process pool
    return out


def test_sweep_folders_are_well_formed_and_its_numbers_recompute_from_the_csvs(sweep_dir):
    from keras_rl.report.stats import fisher_exact, mann_whitney, median_difference_ci, success_difference_ci

    result = json.loads((sweep_dir / "sweep.json").read_text())
    assert [p["point"] for p in result["points"]] == ["noise_sigma=0.2", "noise_sigma=0.6"]
    assert result["baseline"] == "noise_sigma=0.2"
    reached = {}
    for point in ("noise_sigma=0.2", "noise_sigma=0.6"):
        for seed in (0, 1):
            seed_dir = sweep_dir / point / f"seed_{seed}"
            for name in ("config.json", "episodes.csv", "summary.json", "curve.png", "actor.weights.h5"):
                assert (seed_dir / name).is_file(), (seed_dir, name)
            config = json.loads((seed_dir / "config.json").read_text())
            assert config["noise_sigma"] == float(point.split("=")[1]) and config["seed"] == seed
            metric = [r["metric"] for r in read_episodes(seed_dir / "episodes.csv")]
            reached[point, seed] = next((i + 1 for i, m in enumerate(metric) if m > -1300), None)
        assert (sweep_dir / point / "summary.md").is_file() and (sweep_dir / point / "curves.png").is_file()
    assert any(v is not None for v in reached.values()) and any(v is None for v in reached.values())
    by_point = {p["point"]: p for p in result["points"]}
    for point in by_point:
        hits = [reached[point, s] for s in (0, 1) if reached[point, s] is not None]
        assert by_point[point]["episodes_to_threshold"] == hits
        assert by_point[point]["successes"] == len(hits)
        assert by_point[point]["median"] == (float(np.median(hits)) if hits else None)
    other, base = by_point["noise_sigma=0.6"], by_point["noise_sigma=0.2"]
    assert other["fisher_p"] == pytest.approx(fisher_exact(other["successes"], 2, base["successes"], 2))
    rate = success_difference_ci(other["successes"], 2, base["successes"], 2)
    assert [other["success_difference"][k] for k in ("estimate", "low", "high")] == pytest.approx(
        [rate.estimate, rate.low, rate.high]
    )
    a, b = other["episodes_to_threshold"], base["episodes_to_threshold"]
    if a and b:
        diff = median_difference_ci(a, b, np.random.default_rng(0))
        assert other["median_difference"]["estimate"] == pytest.approx(diff.estimate)
        assert other["mann_whitney_p"] == pytest.approx(mann_whitney(a, b)[1])
    table = (sweep_dir / "sweep.md").read_text()
    assert f"| `noise_sigma=0.6` | {other['successes']}/2" in table and "(baseline)" in table
    assert "At 2 seeds a point only effects large enough" in table  # #23.9: it said 10 whatever n was
    assert "](sweep.png)" in table and (sweep_dir / "sweep.png").read_bytes()[:4] == b"\x89PNG"  # #23.15


def test_a_second_run_of_the_same_sweep_skips_every_job(sweep_dir):
    before = {p: p.stat().st_mtime_ns for p in sweep_dir.rglob("episodes.csv")}
    proc = subprocess.run(
        [*CLI, *SWEEP, "--workers", "2", "--out", str(sweep_dir)], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    assert "4 jobs; 4 already done, 0 to run" in proc.stderr
    assert {p: p.stat().st_mtime_ns for p in sweep_dir.rglob("episodes.csv")} == before


def test_seeds_run_in_the_pool_equal_the_same_seeds_run_in_process(sweep_dir, tmp_path):
    proc = subprocess.run(
        [
            *CLI,
            "reproduce",
            "pendulum",
            "--seeds",
            "0-1",
            "--episodes",
            "3",
            "--set",
            "noise_sigma=0.6",
            "--set",
            "threshold=-1300",
            "--set",
            "stop_at_threshold=false",
            "--no-progress",
            "--engine",
            "gymnasium",  # the sweep's engine: compare the same loop in two backends
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode in (0, 1), proc.stderr
    for seed in (0, 1):
        assert rows(tmp_path / f"seed_{seed}" / "episodes.csv") == rows(
            sweep_dir / "noise_sigma=0.6" / f"seed_{seed}" / "episodes.csv"
        )
    summary = json.loads((sweep_dir / "noise_sigma=0.6" / "seed_0" / "summary.json").read_text())
    assert summary["command"].startswith("keras-rl sweep pendulum --grid")  # the driver's, not the worker's argv


def test_ctrl_c_during_a_pooled_sweep_keeps_episodes_marks_interrupted_and_starts_no_queued_seed(tmp_path):
    out = tmp_path / "s"
    proc = subprocess.Popen(
        [
            *CLI,
            "sweep",
            "pendulum",
            "--grid",
            "tau=0.001",
            "--seeds",
            "0-2",
            "--workers",
            "2",
            "--set",
            "stop_at_threshold=false",
            "--no-progress",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=default_signals,
    )
    csv_path = out / "tau=0.001" / "seed_0" / "episodes.csv"
    wait_for_rows(proc, csv_path, 3, poll=0.1)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
    _, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr
    summary = json.loads((out / "tau=0.001" / "seed_0" / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["finished"] is False
    assert summary["episodes_run"] == len(read_episodes(csv_path)) >= 3
    assert not list((out / "tau=0.001" / "seed_0").glob(".tmp-*"))  # no half-written temporary files
    assert not (out / "tau=0.001" / "seed_2").exists()  # queued: never started
    assert (out / "sweep.md").is_file()


def test_a_killed_pool_worker_is_retried_and_its_seed_reruns_to_the_same_csv(tmp_path):
    args = [
        "reproduce",
        "pendulum",
        "--seeds",
        "0-1",
        "--workers",
        "2",
        "--episodes",
        "8",
        "--set",
        "train_start=400",
        "--set",
        "stop_at_threshold=false",
        "--no-progress",
    ]
    # the uninterrupted run in one process: a seed's bits do not depend on the process
    # (test_seeds_run_in_the_pool_equal_the_same_seeds_run_in_process)
    in_process = [a if a != "2" or args[i - 1] != "--workers" else "1" for i, a in enumerate(args)]
    straight = subprocess.run(
        [*CLI, *in_process, "--out", str(tmp_path / "straight")], capture_output=True, text=True, timeout=900
    )
    assert straight.returncode in (0, 1), straight.stderr
    proc = start_cli(*args, "--out", str(tmp_path / "killed"))
    csv_path = tmp_path / "killed" / "seed_0" / "episodes.csv"
    deadline, killed = time.monotonic() + 300, None
    while time.monotonic() < deadline and proc.poll() is None and killed is None:
        if csv_path.is_file() and len(csv_path.read_text().splitlines()) >= 4:
            targets = _pool_workers(proc.pid)
            if targets:
                killed = targets[0]
                os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    _, stderr = proc.communicate(timeout=900)
    assert killed is not None, "no pool worker was found running a seed"
    assert proc.returncode in (0, 1), stderr
    assert "a worker died running" in stderr
    for seed in (0, 1):
        assert rows(tmp_path / "killed" / f"seed_{seed}" / "episodes.csv") == rows(
            tmp_path / "straight" / f"seed_{seed}" / "episodes.csv"
        )


def test_ray_is_an_extra_not_a_dependency():
    """``pip install .`` installs no Ray; ``.[ray]`` does (setup.cfg)."""
    import configparser

    setup = configparser.ConfigParser()
    setup.read(Path(__file__).resolve().parents[1] / "setup.cfg")
    required = [line.strip() for line in setup["options"]["install_requires"].splitlines() if line.strip()]
    assert not [r for r in required if r.lower().startswith("ray")], required
    assert setup["options.extras_require"]["ray"].strip().startswith("ray==")


def test_the_pools_progress_counts_episodes_from_the_seeds_files(tmp_path):
    """Under --workers the bar said "0/2" seeds for over a minute: it counts the episodes each
    seed's episodes.csv holds, out of every seed's budget."""
    from keras_rl.dispatch.jobs import SeedJob
    from keras_rl.dispatch.pool_backend import EpisodesBar
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    jobs = [SeedJob.of(PendulumDDPGConfig(seed=s, episodes=10), tmp_path / f"seed_{s}") for s in (0, 1)]
    (tmp_path / "seed_0").mkdir()
    (tmp_path / "seed_0" / "episodes.csv").write_text("episode,score\n1,-1\n2,-1\n3,-1\n")
    bar = EpisodesBar(jobs)
    bar.poll()
    assert (bar.bar.n, bar.bar.total) == (3, 20)
    bar.job_done(jobs[0])
    assert bar.done == 1 and "1/2" in str(bar.bar.postfix)
    bar.close()


def test_a_broken_pools_surviving_workers_are_killed_before_its_jobs_start_again():
    """CPython ends a broken pool's other workers with SIGTERM, which a worker's training loop
    takes as "stop after this episode": ``_kill_survivors`` kills them, so no survivor writes a
    seed folder that the job's retry is writing. Two workers that ignore SIGTERM, each asleep in
    a job; one is killed: the other outlives the pool's SIGTERM, then not ``_kill_survivors``."""
    import functools
    import multiprocessing
    import multiprocessing.connection
    from concurrent.futures import ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    from keras_rl.dispatch.pool_backend import _kill_survivors

    pool = ProcessPoolExecutor(
        2,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=functools.partial(signal.signal, signal.SIGTERM, signal.SIG_IGN),
    )
    try:
        futures = [pool.submit(time.sleep, 300) for _ in range(2)]
        deadline = time.monotonic() + 120
        while not (all(f.running() for f in futures) and pool._call_queue.empty()):  # both asleep in a job
            assert time.monotonic() < deadline, "the pool's workers did not take their jobs"
            time.sleep(0.1)
        time.sleep(0.5)
        first, second = list(pool._processes.values())
        os.kill(first.pid, signal.SIGKILL)
        done, _ = wait(futures, timeout=120)
        assert len(done) == 2 and all(isinstance(f.exception(), BrokenProcessPool) for f in futures)
        time.sleep(1)
        assert second.is_alive()  # the pool's SIGTERM did not end it
        _kill_survivors(pool)
        # ended: its sentinel is ready. Not ``is_alive()``: the pool's manager thread is blocked in
        # ``join`` on it and may reap it first, and ``is_alive`` reads True until that thread has
        # stored the exit code (a CI run on 2026-11-28 caught that window)
        assert multiprocessing.connection.wait([second.sentinel], timeout=30)
    finally:
        for process in list((pool._processes or {}).values()):
            process.kill()
        pool.shutdown(wait=True, cancel_futures=True)


def test_the_one_dispatch_loop_refills_requeues_recovers_and_drains(monkeypatch):
    """``dispatch/jobs.drive``, which the pool and Ray share (issue 71, item 4), on fake workers:
    at most ``slots`` jobs at once, a job handed back by ``again`` starts first, a break is
    recovered from, and Ctrl-C stops the workers and drains what runs."""
    from keras_rl.dispatch import jobs

    class Fake:
        def __init__(self, interrupt_after: int | None = None):
            self.log, self.started, self.at_once, self.polls = [], 0, 0, 0
            self.interrupt_after, self.broke = interrupt_after, False

        def submit(self, job):
            self.started += 1
            self.log.append(("start", job))
            return job

        def done(self, handles, timeout):
            self.at_once = max(self.at_once, len(handles))
            return list(handles) if timeout is None else handles[:1]

        def collect(self, handle, job, again):
            self.log.append(("end", job))
            if job == "b" and not self.broke:  # its worker died: it and the pool start again
                self.broke = True
                again("b")
                return True
            return False

        def stop(self):
            self.log.append(("stop", None))

        def poll(self):
            self.polls += 1
            if self.interrupt_after is not None and self.polls > self.interrupt_after:
                raise KeyboardInterrupt

        def recover(self):
            self.log.append(("recover", None))

    fake = Fake()
    assert jobs.drive(["a", "b", "c", "d"], 2, fake) == (False, 0)
    assert fake.at_once == 2 and [j for e, j in fake.log if e == "end"] == ["a", "b", "c", "b", "d"]
    assert fake.log.index(("recover", None)) < fake.log.index(("start", "d"))  # recovered before more start
    stopped = Fake(interrupt_after=1)
    assert jobs.drive(["a", "b", "c", "d"], 2, stopped) == (True, 0)
    assert ("stop", None) in stopped.log and ("start", "d") not in stopped.log  # queued jobs never start
