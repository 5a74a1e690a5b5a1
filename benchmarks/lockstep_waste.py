"""What a batch that steps its finished seeds on to the end of its longest seed wastes, from a
committed set's episodes (no training).

    python benchmarks/lockstep_waste.py [--set results/cartpole/faithful-torch-seeds-30-199] [--batch 8]

The set's seeds, in seed order, are cut into batches of ``--batch``; a batch in lockstep plays
its longest seed's env steps for every seed, a batch that sheds its finished seeds
(``keras_rl/train/vectorised.py``) plays each seed's own. The share of lockstep seed-steps that
were a finished seed's is what shedding saves (before the one compile per new batch size).
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
    own = lockstep = 0
    for i in range(0, len(seeds), args.batch):
        batch = [steps[s] for s in seeds[i : i + args.batch]]
        own += sum(batch)
        lockstep += max(batch) * len(batch)
    print(
        f"{args.set}: {len(seeds)} seeds in batches of {args.batch}: {own:,} seed-steps their own, "
        f"{lockstep:,} in lockstep; {1 - own / lockstep:.1%} of lockstep's steps are finished seeds'"
    )


if __name__ == "__main__":
    main()
