"""What a batch that steps its finished seeds on to the end of its longest seed wastes, from a
committed set's episodes (no training).

    python benchmarks/lockstep_waste.py [--set results/cartpole/faithful-torch-seeds-30-199] [--batch 8]

The set's seeds, in seed order, are cut into batches of ``--batch``; a batch in lockstep plays
its longest seed's env steps for every seed, a batch that sheds its finished seeds
(``keras_rl/train/vectorised.py``) plays each seed's own. The share of lockstep seed-steps that
were a finished seed's is what shedding saves, before the one compile per new batch size
(30-70 s on this CPU, ``benchmarks/torch_vectorised.py``'s compile column) that each process pays
once for each size it meets: up to ``--batch`` sizes where every seed is shed as it finishes.

A third way is priced beside them: a batch that sheds only down a ladder of halves (8, 4, 2, 1),
stepping its finished seeds on until the running ones fit the next rung, meets fewer sizes and
wastes some steps.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--set", default="results/cartpole/faithful-torch-seeds-30-199", help="a committed run set")
    parser.add_argument("--batch", type=int, default=8, help="seeds per batch")
    args = parser.parse_args()
    if args.batch < 2:
        parser.error("--batch must be at least 2")
    from keras_rl.runs.run_set import RunSet

    runs = RunSet(Path(args.set)).runs(holding="episodes.csv")
    steps = {run.seed: sum(int(row["steps"]) for row in run.rows()) for run in runs}
    if not steps:
        sys.exit(f"error: {args.set} holds no runs")
    seeds = sorted(steps)
    own = lockstep = ladder = 0
    shed_sizes: set[int] = set()
    ladder_sizes: set[int] = set()
    for i in range(0, len(seeds), args.batch):
        batch = sorted((steps[s] for s in seeds[i : i + args.batch]), reverse=True)
        own += sum(batch)
        lockstep += batch[0] * len(batch)
        rungs = [len(batch) >> k for k in range(len(batch).bit_length())]  # n, n/2, ..., 1
        for running in range(len(batch), 0, -1):  # `running` seeds left, until the next one finishes
            span = batch[running - 1] - (batch[running] if running < len(batch) else 0)
            rung = min(r for r in rungs if r >= running)
            ladder += span * rung
            shed_sizes.add(running)
            ladder_sizes.add(rung)
    print(
        f"{args.set}: {len(seeds)} seeds in batches of {args.batch}: {own:,} seed-steps their own, "
        f"{lockstep:,} in lockstep; {1 - own / lockstep:.1%} of lockstep's steps are finished seeds'"
    )
    print(
        f"shedding each finished seed: no finished seed's step, {len(shed_sizes)} batch sizes to compile; "
        f"shedding down a ladder of halves: {1 - own / ladder:.1%} of its steps are finished seeds', "
        f"{len(ladder_sizes)} sizes ({', '.join(map(str, sorted(ladder_sizes, reverse=True)))})"
    )


if __name__ == "__main__":
    main()
