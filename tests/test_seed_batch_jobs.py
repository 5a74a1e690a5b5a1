"""--seed-batch on reproduce, compare and sweep (keras_rl/dispatch/jobs.py): which jobs share a batch,
how auto sizes batches, and what runs alone or is refused."""

from __future__ import annotations

import pytest


def test_only_jobs_that_differ_in_the_seed_share_a_batch(tmp_path):
    from keras_rl.dispatch.jobs import SeedBatchJob, SeedJob, batched
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig

    def job(seed, framework="keras", gamma=0.99, start="new"):
        config = MountainCarDDPGConfig(seed=seed, framework=framework, gamma=gamma)
        return SeedJob.of(config, tmp_path / f"{framework}-{gamma}" / f"seed_{seed}", start=start, command="x")

    jobs = [job(s, gamma=g) for g in (0.99, 0.9) for s in range(3)] + [job(0, "torch"), job(7, start="resume")]
    packed = batched(jobs, 2)
    batches = [[j.config.seed for j in b.jobs] for b in packed if isinstance(b, SeedBatchJob)]
    assert batches == [[0, 1], [0, 1]]  # one per grid point; seed 2 of each point alone
    alone = [(j.config.framework, j.config.gamma, j.config.seed) for j in packed if not isinstance(j, SeedBatchJob)]
    assert sorted(alone) == [("keras", 0.9, 2), ("keras", 0.99, 2), ("keras", 0.99, 7), ("torch", 0.99, 0)]
    assert batched(jobs, 1) == jobs


@pytest.mark.parametrize(
    "seeds, workers, cap, size",
    [(30, 2, 10, 8), (30, 2, 16, 15), (10, 1, 10, 10), (10, 2, 10, 5), (11, 1, 10, 6), (1, 2, 10, 1), (40, 2, 10, 10)],
)
def test_auto_batches_are_as_even_as_the_cap_and_the_workers_allow(seeds, workers, cap, size):
    import math

    from keras_rl.dispatch.jobs import auto_batch_size

    got = auto_batch_size(seeds, workers, cap)
    assert got == size and got <= cap
    jobs = math.ceil(seeds / got)
    assert math.ceil(jobs / workers) == math.ceil(seeds / (workers * cap))  # no more rounds than the cap forces


def test_seed_batch_auto_packs_each_post_by_its_cap(tmp_path, monkeypatch):
    from keras_rl.dispatch.jobs import SeedBatchJob, SeedJob, batched
    from keras_rl.learners import table
    from keras_rl.learners.table import SEED_BATCH_CAP, seed_batch_cap
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig

    jobs = [SeedJob.of(MountainCarDDPGConfig(seed=s), tmp_path / f"seed_{s}", command="x") for s in range(30)]
    assert seed_batch_cap("mountaincar", "keras") == SEED_BATCH_CAP[("mountaincar", "keras")] == 16
    assert [len(b.jobs) for b in batched(jobs, "auto", workers=2)] == [15, 15]
    monkeypatch.setitem(table.SEED_BATCH_CAP, ("mountaincar", "keras"), 10)
    packed = batched(jobs, "auto", workers=2)
    assert [len(b.jobs) for b in packed if isinstance(b, SeedBatchJob)] == [8, 8, 8, 6]
    assert seed_batch_cap("cartpole", "torch") == 1  # the tutorial's code: one seed per run
    torch = [SeedJob.of(CartPoleDQNConfig(seed=s, framework="torch"), tmp_path / f"t{s}", command="x") for s in (0, 1)]
    assert batched(torch, "auto", workers=2) == torch


def test_a_config_no_stacked_learner_covers_runs_alone_under_auto_and_is_refused_under_a_fixed_size(tmp_path):
    """Post 001 with its learning phase on has no stacked learner. ``sweep --ablate --seed-batch
    auto`` once sent its seeds to the stacked learner, which refused each batch at run time;
    now ``auto`` runs them alone beside the other grid points' batches, and a fixed size
    refuses them before anything runs."""
    from keras_rl.dispatch.jobs import SeedBatchJob, SeedJob, batched
    from keras_rl.errors import ConfigError
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig

    def jobs(point, **overrides):
        config = MountainCarDDPGConfig.for_variant("faithful", **overrides)
        return [SeedJob.of(config.replace(seed=s), tmp_path / point / f"seed_{s}", command="x") for s in range(4)]

    phase, base = jobs("learning_phase_training=true", learning_phase_training=True), jobs("base")
    packed = batched(phase + base, "auto")
    assert [j for j in packed if not isinstance(j, SeedBatchJob)] == phase  # each alone
    assert [[m.config.seed for m in j.jobs] for j in packed if isinstance(j, SeedBatchJob)] == [[0, 1, 2, 3]]
    with pytest.raises(ConfigError, match="seed_batch=2 does not cover .*learning_phase_training=true"):
        batched(base + phase, 2)
    assert batched(phase, 1) == phase


@pytest.mark.slow
def test_seed_batch_on_sweep_runs_each_grid_point_as_a_batch_and_refuses_what_it_cannot_do(tmp_path):
    import json
    import subprocess
    import sys

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "keras_rl", *args], capture_output=True, text=True, timeout=600)

    bad = cli(
        "reproduce",
        "cartpole",
        "--framework",
        "torch",
        "--seeds",
        "0-1",
        "--seed-batch",
        "2",
        "--dry-run",
        "--out",
        str(tmp_path / "tutorial"),
    )
    assert bad.returncode == 2 and "--seed-batch has no torch learner for cartpole" in bad.stderr, bad.stderr
    tutorial = cli(  # auto: where nothing batches, each seed runs alone
        "reproduce", "cartpole", "--framework", "torch", "--seeds", "0-1", "--seed-batch", "auto", "--dry-run",
        "--out", str(tmp_path / "tutorial"),
    )  # fmt: skip
    assert tutorial.returncode == 0, tutorial.stderr
    out = tmp_path / "sweep"
    proc = cli(
        "sweep",
        "pendulum",
        "--framework",
        "torch",
        "--grid",
        "gamma=0.99,0.9",
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--seed-batch",
        "auto",  # two seeds, one worker: one batch of both per grid point
        "--no-progress",
        "--out",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for point in ("gamma=0.99", "gamma=0.9"):
        for seed in (0, 1):
            summary = json.loads((out / point / f"seed_{seed}" / "summary.json").read_text())
            assert summary["status"] == "completed" and summary["episodes_run"] == 3
            assert summary["provenance"]["seed_batch"] == [0, 1]
    again = cli(
        "sweep",
        "pendulum",
        "--framework",
        "torch",
        "--grid",
        "gamma=0.99,0.9",
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--seed-batch",
        "2",
        "--no-progress",
        "--out",
        str(out),
    )
    assert again.returncode == 0 and "4 already done, 0 to run" in again.stderr, again.stderr[-2000:]


def test_a_retired_stacked_learner_is_refused_with_its_reason_and_auto_runs_its_seeds_alone(tmp_path):
    """Posts 000 and 003's Keras learners were retired for the compiled engine (issue 34):
    ``--seed-batch S`` refuses them before anything runs, naming why and what to run instead;
    ``auto`` runs each seed alone, as where nothing batches; post 000's PyTorch port still batches."""
    import subprocess
    import sys

    from keras_rl.dispatch.jobs import SeedBatchJob, SeedJob, batched
    from keras_rl.learners.table import RETIRED, STACKED, seed_batch_cap
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    for post in ("pendulum", "cartpole"):
        assert (post, "keras") in RETIRED and (post, "keras") not in STACKED
        out = tmp_path / post
        proc = subprocess.run(
            [sys.executable, "-m", "keras_rl", "reproduce", post, "--seeds", "0-1", "--seed-batch", "2",
             "--dry-run", "--out", str(out)],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        assert proc.returncode == 2, proc.stderr
        assert "retired" in proc.stderr and "--engine compiled" in proc.stderr and "Traceback" not in proc.stderr
        assert f"post {'000' if post == 'pendulum' else '003'}" in proc.stderr
        assert not out.exists()
    assert seed_batch_cap("cartpole", "keras") == 1
    assert seed_batch_cap("pendulum", "keras") == 1 and seed_batch_cap("pendulum", "torch") > 1
    jobs = [SeedJob.of(PendulumDDPGConfig(seed=s), tmp_path / f"seed_{s}", command="x") for s in range(4)]
    assert batched(jobs, "auto", workers=2) == jobs
    ported = [
        SeedJob.of(PendulumDDPGConfig(seed=s, framework="torch"), tmp_path / f"t{s}", command="x") for s in range(4)
    ]
    assert all(isinstance(j, SeedBatchJob) for j in batched(ported, 2))
