"""A whole study, timed as a user runs it: N seeds of a post through the CLI, on each way of
running seeds, interleaved, in one run (issue 34's "30-seed study with --workers 2" row).

    python benchmarks/study.py                                  # post 001, seeds 0-29, --workers 2, 2 rounds
    python benchmarks/study.py --episodes 200 --rounds 1
    python benchmarks/study.py --markdown                       # the table for docs/performance.md
    python benchmarks/study.py --framework torch --experiment cartpole --rounds 1   # issue 53 item 3

The arms, each a ``keras-rl reproduce`` command into a fresh temporary folder. In Keras (the
default), a new engine against the fastest way before it (issue 34):

- ``compiled``: ``--engine compiled`` (one XLA program per config, kept across a worker's seeds);
- ``seed-batch auto``: the Gymnasium loop with ``--seed-batch auto`` (stacked learners), the
  fastest way the project had before the compiled engine. Posts 000 and 003's stacked learners
  are retired (issue 34), so their studies are refused; their figures in docs/performance.md
  were measured before, at 97a22fc0.

In PyTorch (``--framework torch``, post 003 only), issue 53's 30-seed study:

- ``vectorised``: ``--engine vectorised-compiled --seed-batch 8``, eight seeds in one compiled
  program, as the certification ran them; every round compiles into a fresh inductor cache
  (``TORCHINDUCTOR_CACHE_DIR``), as a new user's first study does;
- ``tutorial``: ``--engine gymnasium``, the tutorial's own code, seed by seed.

Every arm runs the same seeds, episodes and workers; the rounds alternate the arms, so a
noisy neighbour slows both. The wall time is the whole command's: Python and TensorFlow
start-up, Ray's start (``--workers 2``), tracing and compilation, training and the records.
Only the ratio, measured in one run, means much on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date

ARMS = {  # per framework: the new way first, then the one it is measured against
    "keras": {
        "compiled": ["--engine", "compiled"],
        "seed-batch auto": ["--engine", "gymnasium", "--seed-batch", "auto"],
    },
    "torch": {
        "vectorised": ["--framework", "torch", "--engine", "vectorised-compiled", "--seed-batch", "8"],
        "tutorial": ["--framework", "torch", "--engine", "gymnasium"],
    },
}


def command(experiment: str, seeds: str, workers: int, episodes: int | None, arm: list[str], out: str) -> list[str]:
    budget = ["--episodes", str(episodes)] if episodes else []
    return [
        *("keras-rl", "reproduce", experiment, "--seeds", seeds, "--workers", str(workers)),
        *budget,
        *arm,
        *("--no-progress", "--min-success-rate", "0", "--out", out),
    ]


def timed(argv: list[str], scratch: str) -> float:
    """The command's wall time; torch compiles into a cache under ``scratch``, fresh each time."""
    env = {**os.environ, "TORCHINDUCTOR_CACHE_DIR": os.path.join(scratch, "inductor-cache")}
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "keras_rl", *argv[1:]],
        capture_output=True,
        text=True,
        timeout=3 * 3600,
        check=False,
        env=env,
    )
    if proc.returncode not in (0, 1):  # 1: a seed missed the threshold, which a study may see
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--experiment", choices=("pendulum", "cartpole", "mountaincar"), default="mountaincar")
    parser.add_argument("--framework", choices=tuple(ARMS), default="keras")
    parser.add_argument("--seeds", default="0-29")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--episodes", type=int, default=None, help="a smaller budget (default: the post's)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--markdown", action="store_true", help="print the result as a Markdown table")
    args = parser.parse_args()
    if args.rounds < 1 or args.workers < 1 or (args.episodes is not None and args.episodes < 1):
        parser.error("--rounds, --workers and --episodes must be at least 1")
    from keras_rl.learners.table import no_stacked_learner

    if args.framework == "keras" and (why := no_stacked_learner(args.experiment, "keras")):
        parser.error(why)  # its committed figure was measured before
    if args.framework == "torch" and args.experiment != "cartpole":
        parser.error("--framework torch: the vectorised engine runs post 003 (cartpole) only")
    arms = ARMS[args.framework]
    new, old = arms

    times: dict[str, list[float]] = {arm: [] for arm in arms}
    for _ in range(args.rounds):
        for arm, flags in arms.items():
            scratch = tempfile.mkdtemp(prefix="study-")
            out = os.path.join(scratch, "out")
            try:
                argv = command(args.experiment, args.seeds, args.workers, args.episodes, flags, out)
                times[arm].append(timed(argv, scratch))
            finally:
                shutil.rmtree(scratch, ignore_errors=True)
            print(f"{arm}: {times[arm][-1]:.1f} s", file=sys.stderr)

    med = {arm: statistics.median(t) for arm, t in times.items()}
    ratio = med[old] / med[new]
    given = " ".join(sys.argv[1:])
    if args.markdown:
        print(
            f"`python benchmarks/study.py {given}` ({date.today()}, {platform.machine()}; {args.experiment}, "
            f"seeds {args.seeds}, --workers {args.workers}, "
            f"{args.episodes or 'the post'}'s episodes, medians of {args.rounds} rounds):\n"
        )
        print("| arm | command | wall time (s), median | each round (s) |")
        print("|---|---|---|---|")
        for arm, flags in arms.items():
            cmd = " ".join(command(args.experiment, args.seeds, args.workers, args.episodes, flags, "DIR"))
            rounds = ", ".join(f"{t:.1f}" for t in times[arm])
            print(f"| {arm} | `{cmd}` | {med[arm]:.1f} | {rounds} |")
        print(f"\nThe {new} arm runs the study **{ratio:.2f}x** as fast as the {old} arm.")
    else:
        for arm in arms:
            print(f"{arm:16s} {med[arm]:8.1f} s  ({', '.join(f'{t:.1f}' for t in times[arm])})")
        print(f"{new} is {ratio:.2f}x as fast as {old}")


if __name__ == "__main__":
    main()
