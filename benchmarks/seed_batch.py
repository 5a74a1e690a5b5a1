"""Seed-batched training against one seed at a time: wall time for the same env steps.

    python benchmarks/seed_batch.py                  # post 000, 8 episodes per seed
    python benchmarks/seed_batch.py --episodes 20 --study-episodes 20

Part 1 (one process, one TensorFlow thread): one solo seed, then S = 2, 4, 8, 10 and 16
seeds in one ``--seed-batch`` run, each seed playing the same episodes (``train_start=200``
so that 7 of every 8 env steps train). It prints the wall time and its ratio to one solo
seed. Part 2 (the 10-seed study as users run it): ``keras-rl reproduce ... --seeds 0-9``
with ``--workers 2`` (Ray, one seed per task) and with ``--workers 2 --seed-batch 5``, as
subprocesses, start-up included.

Only ratios within one run mean much on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import keras_rl  # noqa: E402,F401

OVERRIDES = {"train_start": 200, "stop_at_threshold": False}


def solo_seconds(episodes: int) -> float:
    from keras_rl.registry import get_experiment
    from keras_rl.runs.loop import run_seed

    exp = get_experiment("pendulum")
    config = exp.config_cls.for_variant("faithful", seed=0, episodes=1, **OVERRIDES)
    with tempfile.TemporaryDirectory() as tmp:
        run_seed(exp, config, Path(tmp) / "warm", progress=False)  # import and trace once, untimed
        start = time.perf_counter()
        run_seed(exp, config.replace(episodes=episodes), Path(tmp) / "solo", progress=False)
        return time.perf_counter() - start


def batch_seconds(seeds: int, episodes: int) -> float:
    from keras_rl.registry import get_experiment
    from keras_rl.runs.batched import run_seed_batch

    exp = get_experiment("pendulum")
    configs = [exp.config_cls.for_variant("faithful", seed=s, episodes=episodes, **OVERRIDES) for s in range(seeds)]
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        run_seed_batch(exp, configs, [Path(tmp) / f"seed_{s}" for s in range(seeds)], progress=False)
        return time.perf_counter() - start


def study_seconds(episodes: int, *extra: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "keras_rl", "reproduce", "pendulum", "--seeds", "0-9",
                               "--episodes", str(episodes), "--no-progress", "--set", "train_start=200",
                               "--set", "stop_at_threshold=false", "--out", tmp, "--min-success-rate", "0", *extra],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(proc.stderr[-2000:])
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=8, help="episodes per seed in part 1 (default 8)")
    parser.add_argument("--study-episodes", type=int, default=8, help="episodes per seed in part 2 (default 8)")
    parser.add_argument("--skip-study", action="store_true", help="part 1 only")
    args = parser.parse_args()

    from keras_rl.seeding import configure_tensorflow

    configure_tensorflow(1)
    steps = args.episodes * 200
    solo = solo_seconds(args.episodes)
    print(f"post 000, {args.episodes} episodes ({steps} env steps, {steps - 200} updates) per seed, 1 thread")
    print("| seeds | how | wall s | per seed | wall / one solo seed |")
    print("|---|---|---|---|---|")
    print(f"| 1 | solo | {solo:.2f} | {solo:.2f} | 1.00x |")
    for seeds in (2, 4, 8, 10, 16):
        wall = batch_seconds(seeds, args.episodes)
        print(f"| {seeds} | --seed-batch {seeds} | {wall:.2f} | {wall / seeds:.2f} | {wall / solo:.2f}x |")
    if args.skip_study:
        return
    today = study_seconds(args.study_episodes, "--workers", "2")
    batched = study_seconds(args.study_episodes, "--workers", "2", "--seed-batch", "5")
    print(f"\n10-seed study, {args.study_episodes} episodes per seed, as commands (start-up included):")
    print(f"| --workers 2 | {today:.1f} s | 1.00x |")
    print(f"| --workers 2 --seed-batch 5 | {batched:.1f} s | {today / batched:.2f}x faster |")


if __name__ == "__main__":
    main()
