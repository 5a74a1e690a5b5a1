"""Seed-batched training against one seed at a time: wall time for the same env steps.

    python benchmarks/seed_batch.py                          # post 001, 4 episodes (999 steps) per seed
    python benchmarks/seed_batch.py --experiment pendulum --framework torch  # post 000's port, 8 episodes
    python benchmarks/seed_batch.py --table                  # the targets table of issue #18, all posts

Part 1 (one process, one TensorFlow thread): one solo seed, then S = 2, 4, 8, 10 and 16
seeds in one ``--seed-batch`` run, every seed playing its own episodes. The ratio is the
batch's wall time to one solo seed's wall time for the same env steps per seed: post 000's
episodes are all 200 steps (``train_start=200``, so 7 of every 8 env steps train); post
003's vary, so the solo seed's time per env step is scaled to the batch's vector steps (its
longest seed). Part 2: the compiled learner call alone, per vector step, at S = 1 .. 16,
for what a finished seed costs while it is masked. Part 3 (the 10-seed
study as users run it): ``keras-rl reproduce ... --seeds 0-9`` with ``--workers 2`` (Ray,
one seed per task) and with ``--workers 2 --seed-batch 5``, as subprocesses, start-up
included.

``--table`` measures, for every post and PyTorch port that batches, 10 seeds in one process
against one solo seed (part 1 at S=10 only) and a 30-seed study as commands (``--workers 2``
against ``--workers 2 --seed-batch auto``), and prints them beside the targets.

Posts 000 and 003's Keras learners no longer batch (issue 34 retired them:
``learners/table.RETIRED``); their rows here were measured before, at the commits
docs/performance.md names.

Only ratios within one run mean much on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import keras_rl  # noqa: E402,F401

OVERRIDES = {"pendulum": {"train_start": 200, "stop_at_threshold": False}, "cartpole": {}, "mountaincar": {}}
POST = {"pendulum": "000", "mountaincar": "001", "cartpole": "003"}
DEFAULT_EPISODES = {"pendulum": 8, "cartpole": 250, "mountaincar": 4}


FRAMEWORK = ["keras"]
"""--framework: keras, or torch for the PyTorch ports of posts 000 and 001."""


def _configs(experiment: str, seeds, episodes: int):
    from keras_rl.registry import get_experiment

    exp = get_experiment(experiment)
    return exp, [
        exp.config_cls.for_variant(
            "faithful", seed=s, episodes=episodes, framework=FRAMEWORK[0], **OVERRIDES[experiment]
        )
        for s in seeds
    ]


def solo_seconds(experiment: str, episodes: int) -> tuple[float, int]:
    """One solo seed's wall time and env steps (seed 0)."""
    from keras_rl.train.loop import run_seed
    from keras_rl.train.settings import TrainSettings

    exp, (config,) = _configs(experiment, [0], episodes)
    with tempfile.TemporaryDirectory() as tmp:
        run_seed(
            exp, config.replace(episodes=1), Path(tmp) / "warm", TrainSettings(progress=False)
        )  # import, trace: untimed
        start = time.perf_counter()
        summary = run_seed(exp, config, Path(tmp) / "solo", TrainSettings(progress=False))
        return time.perf_counter() - start, summary.total_steps


def batch_seconds(experiment: str, seeds: int, episodes: int) -> tuple[float, int]:
    """A batch's wall time and vector steps (its longest seed's env steps)."""
    from keras_rl.train.loop import run_seeds as run_seed_batch
    from keras_rl.train.settings import TrainSettings

    exp, configs = _configs(experiment, range(seeds), episodes)
    with tempfile.TemporaryDirectory() as tmp:
        dirs = [Path(tmp) / f"seed_{s}" for s in range(seeds)]
        start = time.perf_counter()
        summaries = run_seed_batch(exp, configs, dirs, TrainSettings(progress=False))
        return time.perf_counter() - start, max(s.total_steps for s in summaries)


def learner_call_ms(experiment: str, seeds: int, calls: int = 300) -> float:
    """The compiled train-and-act call alone, per vector step, in ms (post-warm-up)."""
    import numpy as np

    from keras_rl.learners.table import stacked_implementation
    from keras_rl.registry import get_experiment

    exp, configs = _configs(experiment, range(seeds), 1)
    env = get_experiment(experiment).make_env(configs[0])
    spec = exp.env_spec(env)
    env.close()
    learner = stacked_implementation(experiment, FRAMEWORK[0]).load()(configs, spec)
    layout = learner.layout if hasattr(learner, "layout") else learner.learner.layout
    batch = configs[0].batch_size
    rows = np.random.default_rng(0).uniform(0, 1, (seeds, batch, layout.width)).astype(np.float32)
    states = rows[:, 0, : layout.obs_dim]
    for _ in range(5):
        learner.train_and_act(rows, states)
    start = time.perf_counter()
    for _ in range(calls):
        learner.train_and_act(rows, states)
    return (time.perf_counter() - start) / calls * 1000


def study_seconds(experiment: str, episodes: int, *extra: str, seeds: int = 10) -> float:
    sets = [a for k, v in OVERRIDES[experiment].items() for a in ("--set", f"{k}={json.dumps(v)}")]
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "keras_rl",
                "reproduce",
                experiment,
                "--framework",
                FRAMEWORK[0],
                "--seeds",
                f"0-{seeds - 1}",
                "--episodes",
                str(episodes),
                "--no-progress",
                *sets,
                "--out",
                tmp,
                "--min-success-rate",
                "0",
                *extra,
            ],
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0:
            raise SystemExit(proc.stderr[-2000:])
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--experiment", choices=sorted(OVERRIDES), default=None, help="default mountaincar")
    parser.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="episodes per seed in part 1 (default 8 for pendulum, 250 for cartpole)",
    )
    parser.add_argument(
        "--study-episodes", type=int, default=None, help="episodes per seed in part 3 (default: as --episodes)"
    )
    parser.add_argument(
        "--framework",
        choices=("keras", "torch"),
        default=None,
        help="torch: the PyTorch ports (pendulum, mountaincar)",
    )
    parser.add_argument("--skip-study", action="store_true", help="parts 1 and 2 only")
    parser.add_argument("--study-only", action="store_true", help="part 3 only")
    parser.add_argument(
        "--table",
        action="store_true",
        help="the targets table for every batching post (only --experiment's rows, and only "
        "--framework's, when given; ignores the other options)",
    )
    args = parser.parse_args()
    if args.table:
        from keras_rl.seeding import configure_tensorflow

        configure_tensorflow(1)
        return targets_table(args.experiment, args.framework)
    name = args.experiment or "mountaincar"
    FRAMEWORK[0] = args.framework or "keras"
    from keras_rl.learners.table import no_stacked_learner

    if why := no_stacked_learner(name, FRAMEWORK[0]):
        parser.error(why)
    episodes = args.episodes or DEFAULT_EPISODES[name]

    from keras_rl.seeding import configure_tensorflow

    configure_tensorflow(1)
    if not args.study_only:
        parts_1_and_2(name, episodes)
    if args.skip_study:
        return
    study = args.study_episodes or episodes
    today = study_seconds(name, study, "--workers", "2")
    batched = study_seconds(name, study, "--workers", "2", "--seed-batch", "5")
    print(f"\n10-seed study, {study} episodes per seed, as commands (start-up included):")
    print(f"| --workers 2 | {today:.1f} s | 1.00x |")
    print(f"| --workers 2 --seed-batch 5 | {batched:.1f} s | {today / batched:.2f}x faster |")


TARGETS = [  # (experiment, framework, 10 seeds in one process against one solo seed: before #18, target)
    ("mountaincar", "keras", "not batched", 3.0),
    ("pendulum", "torch", "not batched", 4.0),
    ("mountaincar", "torch", "not batched", None),
]
STUDY_SEEDS, STUDY_TARGET = 30, 2.0


def study_batch(name: str) -> int:
    """The batch size ``--seed-batch auto`` gives the 30-seed study on 2 workers."""
    from keras_rl.dispatch.jobs import auto_batch_size
    from keras_rl.learners.table import seed_batch_cap

    return auto_batch_size(STUDY_SEEDS, 2, seed_batch_cap(name, FRAMEWORK[0]))


def targets_table(only: str | None = None, framework_only: str | None = None) -> None:
    """Issue #18's speed table: every row measured in this run, beside its target."""
    rows = []
    for name, framework, before, target in TARGETS:
        if (only and name != only) or (framework_only and framework != framework_only):
            continue
        FRAMEWORK[0] = framework
        episodes = DEFAULT_EPISODES[name]
        solo, solo_steps = solo_seconds(name, episodes)
        wall, steps = batch_seconds(name, 10, episodes)
        ratio = wall / (solo / solo_steps * steps)
        today = study_seconds(name, episodes, "--workers", "2", seeds=STUDY_SEEDS)
        batched = study_seconds(name, episodes, "--workers", "2", "--seed-batch", "auto", seeds=STUDY_SEEDS)
        rows.append((name, framework, before, target, ratio, today, batched))
        print(
            f"measured {name} ({framework}): 10 seeds {ratio:.2f}x one solo seed; {STUDY_SEEDS}-seed study "
            f"{today:.0f} s solo, {batched:.0f} s batched",
            flush=True,
        )
    post = {"pendulum": "post 000", "cartpole": "post 003", "mountaincar": "post 001"}
    print(f"\n{episodes_note()}")
    print("| what | before | target | measured | met |")
    print("|---|---|---|---|---|")
    for name, framework, before, target, ratio, _, _ in rows:
        port = " (PyTorch port)" if framework == "torch" else ""
        what = f"{post[name]}{port}, 10 seeds in one process against one solo seed"
        met = "n/a" if target is None else "yes" if ratio <= target else "no"
        print(f"| {what} | {before} | {'-' if target is None else f'at most {target:g}x'} | {ratio:.2f}x | {met} |")
    for name, framework, _, _, _, today, batched in rows:
        FRAMEWORK[0] = framework
        what = (
            f"{post[name]}{' (PyTorch port)' if framework == 'torch' else ''}, a {STUDY_SEEDS}-seed study, "
            f"`--workers 2 --seed-batch auto` (batches of {study_batch(name)}) against `--workers 2`"
        )
        speedup = today / batched
        print(
            f"| {what} | - | at least {STUDY_TARGET:g}x faster | {speedup:.2f}x faster ({today:.0f} s -> "
            f"{batched:.0f} s) | {'yes' if speedup >= STUDY_TARGET else 'no'} |"
        )


def episodes_note() -> str:
    return (
        "Episodes per seed: "
        + ", ".join(f"{n} {e}" for n, e in DEFAULT_EPISODES.items())
        + " (post 000 trains from step 200 on here, and never stops at its threshold). Study times are whole "
        "commands, start-up included."
    )


def parts_1_and_2(name: str, episodes: int) -> None:
    solo, solo_steps = solo_seconds(name, episodes)
    per_step = solo / solo_steps
    print(
        f"{name} (post {POST[name]}, {FRAMEWORK[0]}), {episodes} episodes per seed, 1 thread; "
        f"one solo seed: {solo:.2f} s for {solo_steps} env steps ({per_step * 1000:.2f} ms per step)"
    )
    print("| seeds | how | wall s | vector steps | wall / one solo seed over as many steps |")
    print("|---|---|---|---|---|")
    print(f"| 1 | solo | {solo:.2f} | {solo_steps} | 1.00x |")
    for seeds in (2, 4, 8, 10, 16):
        wall, steps = batch_seconds(name, seeds, episodes)
        print(f"| {seeds} | --seed-batch {seeds} | {wall:.2f} | {steps} | {wall / (per_step * steps):.2f}x |")

    print("\nThe compiled train-and-act call alone, per vector step")
    print("| seeds in the call | ms per call | ms per seed |")
    print("|---|---|---|")
    for seeds in (1, 2, 4, 5, 8, 10, 16):
        ms = learner_call_ms(name, seeds)
        print(f"| {seeds} | {ms:.3f} | {ms / seeds:.3f} |")


if __name__ == "__main__":
    main()
