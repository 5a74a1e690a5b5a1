"""A whole study, timed as a user runs it: N seeds of a post through the CLI, on each way of
running seeds, interleaved, in one run (issue 34's "30-seed study with --workers 2" row).

    python benchmarks/study.py                                  # post 001, seeds 0-29, --workers 2, 2 rounds
    python benchmarks/study.py --episodes 200 --rounds 1
    python benchmarks/study.py --markdown                       # the table for docs/performance.md

The arms, each a ``keras-rl reproduce`` command into a fresh temporary folder:

- ``compiled``: ``--engine compiled`` (one XLA program per config, kept across a worker's seeds);
- ``seed-batch auto``: the Gymnasium loop with ``--seed-batch auto`` (stacked learners), the
  fastest way the project had before the compiled engine. Posts 000 and 003's stacked learners
  are retired (issue 34), so their studies are refused; their figures in docs/performance.md
  were measured before, at 97a22fc0.

Every arm runs the same seeds, episodes and workers; the rounds alternate the arms, so a
noisy neighbour slows both. The wall time is the whole command's: Python and TensorFlow
start-up, Ray's start (``--workers 2``), tracing and compilation, training and the records.
Only the ratio, measured in one run, means much on a shared machine.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date

ARMS = {
    "compiled": ["--engine", "compiled"],
    "seed-batch auto": ["--engine", "gymnasium", "--seed-batch", "auto"],
}


def command(experiment: str, seeds: str, workers: int, episodes: int | None, arm: str, out: str) -> list[str]:
    budget = ["--episodes", str(episodes)] if episodes else []
    return [
        *("keras-rl", "reproduce", experiment, "--seeds", seeds, "--workers", str(workers)),
        *budget,
        *ARMS[arm],
        *("--no-progress", "--min-success-rate", "0", "--out", out),
    ]


def timed(argv: list[str]) -> float:
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "keras_rl", *argv[1:]], capture_output=True, text=True, timeout=3600, check=False
    )
    if proc.returncode not in (0, 1):  # 1: a seed missed the threshold, which a study may see
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--experiment", choices=("pendulum", "cartpole", "mountaincar"), default="mountaincar")
    parser.add_argument("--seeds", default="0-29")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--episodes", type=int, default=None, help="a smaller budget (default: the post's)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--markdown", action="store_true", help="print the result as a Markdown table")
    args = parser.parse_args()
    if args.rounds < 1 or args.workers < 1 or (args.episodes is not None and args.episodes < 1):
        parser.error("--rounds, --workers and --episodes must be at least 1")
    from keras_rl.learners.table import no_stacked_learner

    if why := no_stacked_learner(args.experiment, "keras"):  # its committed figure was measured before
        parser.error(why)

    times: dict[str, list[float]] = {arm: [] for arm in ARMS}
    for _ in range(args.rounds):
        for arm in ARMS:
            out = tempfile.mkdtemp(prefix="study-")
            try:
                times[arm].append(timed(command(args.experiment, args.seeds, args.workers, args.episodes, arm, out)))
            finally:
                shutil.rmtree(out, ignore_errors=True)
            print(f"{arm}: {times[arm][-1]:.1f} s", file=sys.stderr)

    med = {arm: statistics.median(t) for arm, t in times.items()}
    ratio = med["seed-batch auto"] / med["compiled"]
    argv = " ".join(sys.argv[1:])
    if args.markdown:
        print(
            f"`python benchmarks/study.py {argv}` ({date.today()}, {platform.machine()}; {args.experiment}, "
            f"seeds {args.seeds}, --workers {args.workers}, "
            f"{args.episodes or 'the post'}'s episodes, medians of {args.rounds} rounds):\n"
        )
        print("| arm | command | wall time (s), median | each round (s) |")
        print("|---|---|---|---|")
        for arm in ARMS:
            cmd = " ".join(command(args.experiment, args.seeds, args.workers, args.episodes, arm, "DIR"))
            rounds = ", ".join(f"{t:.1f}" for t in times[arm])
            print(f"| {arm} | `{cmd}` | {med[arm]:.1f} | {rounds} |")
        print(f"\nThe compiled engine runs the study **{ratio:.2f}x** as fast as `--seed-batch auto`.")
    else:
        for arm in ARMS:
            print(f"{arm:16s} {med[arm]:8.1f} s  ({', '.join(f'{t:.1f}' for t in times[arm])})")
        print(f"compiled is {ratio:.2f}x as fast as seed-batch auto")


if __name__ == "__main__":
    main()
