"""Where the time goes per vector step of a seed-batched run (and of a solo run).

    python benchmarks/seed_batch_profile.py --experiment mountaincar --seeds 10 --episodes 5
    python benchmarks/seed_batch_profile.py --experiment pendulum --seeds 1 --episodes 20

(Posts 000 and 003's Keras learners no longer batch, issue 34: ``--seeds 1`` profiles their
solo loop; post 003's batch profile in docs/performance.md was measured before, at 97a22fc0.)

Runs one batch of S seeds (S=1: the solo loop) under cProfile, after an untimed warm-up
run that compiles the learner's steps, and splits the wall time into the parts of a vector
step: the compiled learner call (train + act, one per vector step), the S env steps, the
replay buffers (store and sample), exploration, the per-episode records (CSV, summary.json
with fsync), and the rest (the loop's own Python). cProfile adds its own overhead to the
Python parts, so read the shares, not the absolute times.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import keras_rl  # noqa: E402,F401

PARTS = {  # part -> (file suffix, function name) whose cumulative time counts for it
    "learner call (compiled train + act)": [("atomic_function.py", "call_flat")],
    "env steps": [],  # the outermost wrapper's step, found at run time
    "replay buffer (store, sample)": [
        ("buffers.py", "add_rows"),
        ("buffers.py", "sample_rows"),
        ("transitions.py", "rows"),
    ],
    "exploration": [("explorers.py", "__call__")],
    "episode records (CSV, summary.json)": [("loop.py", "record_episode"), ("summary.py", "write")],
    "tensor conversion in and out": [("constant_op.py", "constant"), ("tensor.py", "numpy")],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--experiment", choices=["pendulum", "cartpole", "mountaincar"], default="mountaincar")
    parser.add_argument("--seeds", type=int, default=10, help="seeds in the batch (1: the solo loop)")
    parser.add_argument("--episodes", type=int, default=5)
    args = parser.parse_args()

    from keras_rl.registry import get_experiment
    from keras_rl.seeding import configure_tensorflow
    from keras_rl.train.loop import run_seed
    from keras_rl.train.loop import run_seeds as run_seed_batch
    from keras_rl.train.settings import TrainSettings

    configure_tensorflow(1)
    exp = get_experiment(args.experiment)
    configs = [exp.config_cls.for_variant("faithful", seed=s, episodes=args.episodes) for s in range(args.seeds)]
    tmp = Path(tempfile.mkdtemp())
    warm = [c.replace(episodes=min(args.episodes, 15)) for c in configs]
    if args.seeds == 1:
        run_seed(exp, warm[0], tmp / "warm", TrainSettings(progress=False))
    else:
        run_seed_batch(exp, warm, [tmp / "warm" / f"seed_{c.seed}" for c in warm], TrainSettings(progress=False))
    profile = cProfile.Profile()
    start = time.perf_counter()
    profile.enable()
    if args.seeds == 1:
        summaries = [run_seed(exp, configs[0], tmp / "solo", TrainSettings(progress=False))]
    else:
        summaries = run_seed_batch(
            exp, configs, [tmp / f"seed_{c.seed}" for c in configs], TrainSettings(progress=False)
        )
    profile.disable()
    wall = time.perf_counter() - start
    vector_steps = max(s.total_steps for s in summaries)
    env = exp.make_env(configs[0])
    outer = type(env).step.__code__
    env.close()
    stats = pstats.Stats(profile).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}
    total = sum(v[2] for v in stats.values())
    print(
        f"{args.experiment}, {args.seeds} seed(s), {args.episodes} episodes each: {wall:.2f} s wall "
        f"({total:.2f} s under cProfile), {vector_steps} vector steps"
    )
    print("| part | share | ms per vector step |")
    print("|---|---|---|")
    counted = 0.0
    for part, keys in PARTS.items():
        seconds = sum(
            v[3]
            for (file, line, name), v in stats.items()
            if any(file.endswith(f) and name == n for f, n in keys)
            or (part == "env steps" and (file, line) == (outer.co_filename, outer.co_firstlineno))
        )
        counted += seconds
        print(f"| {part} | {seconds / total:.0%} | {seconds / vector_steps * 1000:.3f} |")
    rest = total - counted
    print(f"| the rest (the loop's own Python) | {rest / total:.0%} | {rest / vector_steps * 1000:.3f} |")


if __name__ == "__main__":
    main()
