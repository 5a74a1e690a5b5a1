"""The compiled engine against the Gymnasium loop: wall time per env step, one seed, one process.

    python benchmarks/engines.py                 # post 000, 40 episodes (8,000 steps), 3 rounds
    python benchmarks/engines.py --episodes 100 --rounds 5
    python benchmarks/engines.py --experiment cartpole --episodes 300 --rounds 1   # post 003
    python benchmarks/engines.py --experiment mountaincar --episodes 30 --rounds 3  # post 001
    python benchmarks/engines.py --markdown      # the table for docs/performance.md
    python benchmarks/engines.py --batch 10      # and the Gymnasium loop's seed batch of 10, per seed

Each round trains post 000's faithful seed 0 for ``--episodes`` episodes on each engine in
turn (interleaved, so a noisy neighbour slows both), through the engine seam
(``train/engine.py``), with training from the first stored batch on (``train_start=64``:
about every step trains, as in the bulk of a real run) and no stop at the threshold. The
steady rate comes from the run's own ``episodes.csv`` (``wall_seconds`` and ``total_steps``
from the end of episode 5 to the last; post 003: from its middle episode on, where its
episodes are long, as in most of a run's steps), so it holds every per-episode cost (the
host's draws, the records) and none of the start-up; start-up is the time to the end of the first episode (building
the networks, tracing, XLA compilation). Medians over the rounds. One TensorFlow thread, as
the CLI runs a seed. Only the ratio, measured in one run, means much on a shared machine.

``--batch S`` adds a third arm in each round: seeds 0..S-1 trained together on the Gymnasium
loop's seed axis (a stacked learner, ``--seed-batch S``), its cost per *seed*-env-step: the
wall time from the moment the last seed passed the steady-rate episode to the run's end,
over the steps all seeds played in it. That is the comparison issue 34's item 5 asks for (a
compiled solo run against today's fastest way to run seeds).
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--experiment", choices=("pendulum", "cartpole", "mountaincar"), default="pendulum")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--markdown", action="store_true", help="print the result as a Markdown table")
    parser.add_argument("--batch", type=int, default=0, metavar="S", help="add a seed batch of S on the Gymnasium loop")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    if args.batch == 1 or args.batch < 0:
        parser.error("--batch must be 0 (none) or at least 2")
    from keras_rl.learners.table import no_stacked_learner

    if args.batch and (why := no_stacked_learner(args.experiment, "keras")):
        parser.error(why)

    from keras_rl.registry import get_experiment
    from keras_rl.train.engine import get_engine
    from keras_rl.train.settings import TrainSettings

    experiment = get_experiment(args.experiment)
    if args.episodes < 10:
        parser.error("--episodes must be at least 10 (the first 5 are left out of the steady rate)")
    changes = {"train_start": 64} if args.experiment == "pendulum" else {}
    config = experiment.config_cls.for_variant(
        "faithful", seed=0, episodes=args.episodes, stop_at_threshold=False, **changes
    )
    first = args.episodes // 2 - 1 if args.experiment == "cartpole" else 4
    from keras_rl.runs.files import read_episodes

    arms = ["gymnasium", "compiled"] + ([f"gymnasium, batch of {args.batch}"] if args.batch else [])
    rates: dict[str, list[float]] = {arm: [] for arm in arms}
    startups: dict[str, list[float]] = {arm: [] for arm in arms}
    root = Path(tempfile.mkdtemp(prefix="engines-"))
    try:
        for r in range(args.rounds):
            for name in rates:
                if name not in ("gymnasium", "compiled"):
                    rate, built = _batch_rate(experiment, config, args.batch, root / f"batch-{r}", first, read_episodes)
                    rates[name].append(rate)
                    startups[name].append(built)
                    print(f"round {r + 1}: {name} {rate:.3f} ms/seed-step", file=sys.stderr)
                    continue
                folder = root / f"{name}-{r}"
                start = time.perf_counter()
                summary = get_engine(name).train(experiment, [config], [folder], TrainSettings(progress=False))[0]
                built = time.perf_counter() - start - summary.wall_seconds  # before the run's clock starts
                rows = read_episodes(folder / "episodes.csv")
                if len(rows) != args.episodes:
                    raise SystemExit(f"{name} played {len(rows)} episodes, not {args.episodes}")
                wall = [row["wall_seconds"] for row in rows]
                played = rows[-1]["total_steps"] - rows[first]["total_steps"]
                rates[name].append(1000 * (wall[-1] - wall[first]) / played)
                startups[name].append(built + wall[0])
                print(f"round {r + 1}: {name} {rates[name][-1]:.3f} ms/step", file=sys.stderr)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    per_step = {name: statistics.median(r) for name, r in rates.items()}
    startup = {name: statistics.median(s) for name, s in startups.items()}
    ratio = per_step["gymnasium"] / per_step["compiled"]
    when = time.strftime("%Y-%m-%d")
    batch = f" --batch {args.batch}" if args.batch else ""
    machine = platform.processor() or platform.machine()
    lines = [
        f"`python benchmarks/engines.py --experiment {args.experiment} --episodes {args.episodes} "
        f"--rounds {args.rounds}{batch} --markdown` ({when}, {machine}, one "
        f"TensorFlow thread; {args.experiment} seed 0, {args.episodes} episodes per run, the steady rate "
        f"after episode {first + 1}, medians of {args.rounds} rounds):",
        "",
        "| engine | ms per (seed-)env step (steady) | start-up to the first episode's end (s) |",
        "|---|---|---|",
        *(f"| {name} | {per_step[name]:.3f} | {startup[name]:.1f} |" for name in rates),
        "",
        f"The compiled engine: **{ratio:.1f}x** the Gymnasium loop's steps per second.",
        *(
            [
                f"Against the Gymnasium loop's batch of {args.batch}: the compiled solo run costs "
                f"**{per_step['compiled'] / per_step[arms[2]]:.2f}x** its time per seed-step "
                "(below 1: the solo compiled run is the cheaper way to run seeds)."
            ]
            if args.batch
            else []
        ),
    ]
    print("\n".join(lines) if args.markdown else f"gymnasium/compiled per-step time: {ratio:.2f}x ({per_step})")


def _batch_rate(experiment, config, seeds: int, folder: Path, first: int, read_episodes) -> tuple[float, float]:
    """ms per seed-env-step of seeds 0..seeds-1 as one seed batch on the Gymnasium loop, and its
    start-up (to the end of its first vector episode)."""
    from keras_rl.train.loop import run_seeds
    from keras_rl.train.settings import TrainSettings

    configs = [config.replace(seed=s) for s in range(seeds)]
    dirs = [folder / f"seed_{s}" for s in range(seeds)]
    start = time.perf_counter()
    summaries = run_seeds(experiment, configs, dirs, TrainSettings(progress=False))
    built = time.perf_counter() - start - max(s.wall_seconds for s in summaries)
    rows = [read_episodes(d / "episodes.csv") for d in dirs]
    since = max(r[first]["wall_seconds"] for r in rows)
    played = 0
    for r in rows:
        before = max((row["total_steps"] for row in r if row["wall_seconds"] <= since), default=0)
        played += r[-1]["total_steps"] - before
    end = max(r[-1]["wall_seconds"] for r in rows)
    return 1000 * (end - since) / played, built + min(r[0]["wall_seconds"] for r in rows)


if __name__ == "__main__":
    main()
