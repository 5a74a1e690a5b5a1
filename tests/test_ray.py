"""The Ray backend and ``keras-rl sweep``, on real local Ray instances (loopback only)."""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from clitools import default_signals, start_cli, wait_for_rows

ray = pytest.importorskip("ray")

from keras_rl.cli import main  # noqa: E402
from keras_rl.runs.files import read_episodes  # noqa: E402

pytestmark = [pytest.mark.ray, pytest.mark.slow]  # local Ray instances and clusters: one xdist process

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


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "s"
    proc = subprocess.run(
        [*CLI, *SWEEP, "--workers", "2", "--out", str(out)], capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr
    assert "4 jobs; 0 already done, 4 to run" in proc.stderr
    assert "median episodes to threshold" in proc.stdout and "None" not in proc.stdout  # #23.9: it printed None
    # token authentication is on, asked for by name: Ray's warning does not print on every run
    assert "Token authentication" not in proc.stderr
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
    assert "Started a local Ray instance" not in proc.stderr  # nothing to run: no Ray started
    assert {p: p.stat().st_mtime_ns for p in sweep_dir.rglob("episodes.csv")} == before


def test_seeds_run_through_ray_equal_the_same_seeds_run_in_process(sweep_dir, tmp_path):
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
    assert summary["provenance"]["ray_node_id"]
    assert summary["command"].startswith("keras-rl sweep pendulum --grid")  # the driver's, not the worker's argv


def test_ray_servers_listen_on_loopback_only():
    from keras_rl.runs.ray_backend import RayBackend

    backend = RayBackend(workers=1)
    ray_module, _ = backend._init()
    try:
        ray_module.get(ray_module.remote(lambda: 1).remote())  # a worker is up too
        mine = _descendants(os.getpid()) | {os.getpid()}
        listening = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout.splitlines()
        ours = [line for line in listening if any(int(p) in mine for p in re.findall(r"pid=(\d+)", line))]
        assert ours, listening  # the check saw Ray's sockets
        for line in ours:
            local = line.split()[3]
            assert local.rsplit(":", 1)[0] in ("127.0.0.1", "[::ffff:127.0.0.1]", "[::1]"), line
    finally:
        ray_module.shutdown()


def _descendants(pid: int) -> set[int]:
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            parents[int(stat.parent.name)] = int(fields[1])
        except (OSError, IndexError, ValueError):
            continue
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def test_two_node_cluster_runs_jobs_on_both_nodes_and_files_land_in_the_drivers_out(tmp_path):
    """Two seed batches (``--seed-batch 2``) and two solo seeds on a 2-node cluster."""
    from ray.cluster_utils import Cluster

    from keras_rl.posts.pendulum import PendulumDDPGConfig
    from keras_rl.runs.jobs import SeedBatchJob, SeedJob, batched, read_outcome
    from keras_rl.runs.ray_backend import RayBackend

    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    cluster = Cluster(
        initialize_head=True,
        head_node_args={"num_cpus": 1, "include_dashboard": False, "object_store_memory": 80 * 1024 * 1024},
    )
    cluster.add_node(num_cpus=1, object_store_memory=80 * 1024 * 1024)
    cluster.wait_for_nodes()
    try:
        config = PendulumDDPGConfig(episodes=2, stop_at_threshold=False, framework="torch")  # Keras's no longer batches
        jobs = [SeedJob.of(config.replace(seed=s), tmp_path / f"seed_{s}") for s in range(6)]
        jobs = batched(jobs[:4], 2) + jobs[4:]
        assert [isinstance(j, SeedBatchJob) for j in jobs] == [True, True, False, False]
        outcome = read_outcome(jobs, RayBackend(address=cluster.address).run(jobs, progress=False))
        assert not outcome.interrupted and [s.status for s in outcome.summaries] == ["completed"] * 6
        nodes = {s.provenance["ray_node_id"] for s in outcome.summaries}
        assert len(nodes) == 2  # the jobs ran on both nodes
        assert [s.provenance.get("seed_batch") for s in outcome.summaries] == [[0, 1]] * 2 + [[2, 3]] * 2 + [None] * 2
        for s in range(6):
            assert len(read_episodes(tmp_path / f"seed_{s}" / "episodes.csv")) == 2
            assert (tmp_path / f"seed_{s}" / "actor.pt").is_file()
    finally:
        ray.shutdown()
        cluster.shutdown()


def test_ctrl_c_during_a_ray_sweep_keeps_episodes_marks_interrupted_and_starts_no_queued_seed(tmp_path):
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
    summary = json.loads((out / "tau=0.001" / "seed_0" / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert summary["episodes_run"] == len(read_episodes(csv_path)) >= 3
    assert not (out / "tau=0.001" / "seed_2").exists()  # queued: never started
    assert (out / "sweep.md").is_file()


def test_a_killed_ray_worker_is_retried_and_its_seed_reruns_to_the_same_csv(tmp_path):
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
    # the uninterrupted run in this process: a seed's bits do not depend on Ray
    # (test_seeds_run_through_ray_equal_the_same_seeds_run_in_process), and no second Ray instance starts
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
            workers = subprocess.run(["pgrep", "-f", "ray::_seed_task"], capture_output=True, text=True).stdout.split()
            mine = _descendants(proc.pid)
            targets = [int(p) for p in workers if int(p) in mine]
            if targets:
                killed = targets[0]
                os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    _, stderr = proc.communicate(timeout=900)
    assert killed is not None, "no Ray worker was found running a seed"
    assert proc.returncode in (0, 1), stderr
    for seed in (0, 1):
        assert rows(tmp_path / "killed" / f"seed_{seed}" / "episodes.csv") == rows(
            tmp_path / "straight" / f"seed_{seed}" / "episodes.csv"
        )


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--grid", "warp=1,2"], "unknown pendulum config field 'warp'"),
        (["--grid", "tau=fast"], "tau expects a float, got 'fast'"),
        (["--grid", "tau=0.1,"], "has an empty value"),
        (["--grid", "tau=0.1,0.10,1e-1"], "gives tau=0.1 more than once"),  # #23.2: it counted one seed as 3
        (["--grid", "tau=5"], "tau must be in (0, 1]"),
        (["--grid", "seed=1,2"], "use --seeds"),
        ([], "needs --grid"),
        (["--grid", "tau=0.1", "--ablate"], "--ablate makes its own grid"),
        (["--grid", "tau=0.1", "--address", "127.0.0.1:1"], "no Ray cluster answers at 127.0.0.1:1"),
        (
            ["--grid", "tau=" + ",".join(f"0.{i:04d}1" for i in range(1, 1002)), "--seeds", "0-9999"],
            "more than 10000; pass --yes",
        ),
    ],
)
def test_bad_sweep_input_exits_2_and_names_the_problem(argv, message, capsys, tmp_path, monkeypatch):
    import ray

    # refused before Ray starts: an unreachable address is named by a bounded socket probe
    # (ray_backend.check_reachable, 5 s), not after Ray's own long retries
    monkeypatch.setattr(ray, "init", lambda *a, **k: pytest.fail("Ray was started for input that is refused"))
    assert main(["sweep", "pendulum", *argv, "--out", str(tmp_path / "s")]) == 2
    assert message in capsys.readouterr().err


def test_ablate_flips_each_quirk_switch_alone():
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig
    from keras_rl.registry import EXPERIMENTS
    from keras_rl.runs.sweep import ablation_grid

    points = ablation_grid(MountainCarDDPGConfig, MountainCarDDPGConfig())
    assert points[0].name == "base" and len(points) == 1 + len(MountainCarDDPGConfig.QUIRKS)
    assert all(len(p.overrides) == 1 for p in points[1:])
    assert "actor_gradient=dpg_intended" in [p.name for p in points]
    for experiment in EXPERIMENTS.values():  # every switch the ledger names is a field
        for field_name in experiment.config_cls.QUIRKS:
            assert hasattr(experiment.config_cls(), field_name)
