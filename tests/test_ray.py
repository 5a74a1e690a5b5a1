"""The Ray backend and ``keras-rl sweep``, on real local Ray instances (loopback only)."""

from __future__ import annotations

import os
import re
import subprocess

import pytest
from clitools import descendants

ray = pytest.importorskip("ray")

from keras_rl.cli import main  # noqa: E402
from keras_rl.runs.files import read_episodes  # noqa: E402

pytestmark = [pytest.mark.ray, pytest.mark.slow]  # local Ray instances and clusters: one xdist process


def test_ray_servers_listen_on_loopback_only():
    from keras_rl.dispatch.ray_backend import RayBackend

    backend = RayBackend(workers=1)
    ray_module, _ = backend._init()
    try:
        ray_module.get(ray_module.remote(lambda: 1).remote())  # a worker is up too
        mine = descendants(os.getpid()) | {os.getpid()}
        listening = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout.splitlines()
        ours = [line for line in listening if any(int(p) in mine for p in re.findall(r"pid=(\d+)", line))]
        assert ours, listening  # the check saw Ray's sockets
        for line in ours:
            local = line.split()[3]
            assert local.rsplit(":", 1)[0] in ("127.0.0.1", "[::ffff:127.0.0.1]", "[::1]"), line
    finally:
        ray_module.shutdown()


@pytest.fixture(scope="module")
def two_node_cluster():
    """A local two-node Ray cluster on loopback, started once for the tests that need one."""
    from ray.cluster_utils import Cluster

    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    cluster = Cluster(
        initialize_head=True,
        head_node_args={"num_cpus": 1, "include_dashboard": False, "object_store_memory": 80 * 1024 * 1024},
    )
    cluster.add_node(num_cpus=1, object_store_memory=80 * 1024 * 1024)
    cluster.wait_for_nodes()
    try:
        yield cluster
    finally:
        ray.shutdown()
        cluster.shutdown()


def test_two_node_cluster_runs_jobs_on_both_nodes_and_files_land_in_the_drivers_out(tmp_path, two_node_cluster):
    """Two seed batches (``--seed-batch 2``) and two solo seeds on a 2-node cluster."""
    from keras_rl.dispatch.jobs import SeedBatchJob, SeedJob, batched, read_outcome
    from keras_rl.dispatch.ray_backend import RayBackend
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    cluster = two_node_cluster
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
        ray.shutdown()  # this driver's connection; the cluster stays for the module


def test_committed_seeds_rerun_on_a_two_node_cluster_to_their_committed_bits(tmp_path, two_node_cluster):
    """``python -m maintainers audit --address ADDR`` (the reruns of ``manifest --regenerate``, one
    function): a drawn seed of a committed set reruns through the cluster (their summaries name a
    Ray node) and agrees with the committed run bit for bit."""
    import json
    import sys

    # the reruns are subprocesses: each connects to the cluster itself
    out = tmp_path / "audit"
    sets = ["checks/pendulum/mutants/tau_x10"]  # about 2 s a seed
    command = [sys.executable, "-m", "maintainers", "audit", "--sets", *sets, "--out", str(out)]
    command += ["--workers", "2", "--address", two_node_cluster.address]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    results = json.loads((out / "audit.json").read_text())["results"]
    assert [r["set"] for r in results] == sorted(sets)
    for r in results:
        ((seed, verdict),) = r["by_seed"].items()
        assert verdict["verdict"] == "same bits", r
        summary = json.loads((out / r["set"] / f"seed_{seed}" / "summary.json").read_text())
        assert summary["provenance"].get("ray_node_id")  # trained through the cluster


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
    from keras_rl.dispatch.sweep import ablation_grid
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig
    from keras_rl.registry import EXPERIMENTS

    points = ablation_grid(MountainCarDDPGConfig, MountainCarDDPGConfig())
    assert points[0].name == "base" and len(points) == 1 + len(MountainCarDDPGConfig.QUIRKS)
    assert all(len(p.overrides) == 1 for p in points[1:])
    assert "actor_gradient=dpg_intended" in [p.name for p in points]
    for experiment in EXPERIMENTS.values():  # every switch the ledger names is a field
        for field_name in experiment.config_cls.QUIRKS:
            assert hasattr(experiment.config_cls(), field_name)
