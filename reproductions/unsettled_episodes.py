"""Per seed, how many episodes in a window had a metric above the threshold (post 001: the
last-10 return spread above 2.0, i.e. episodes where the returns had not settled).

    python reproductions/unsettled_episodes.py results/mountaincar/faithful \\
        results/mountaincar/faithful-torch-matched-init results/mountaincar/faithful-torch

Each folder after the first also gets a Mann-Whitney p against the first. Used in
results/README.md to show that matched-init PyTorch runs follow their Keras twins.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from keras_rl.report.stats import mann_whitney
from keras_rl.runs.run_set import RunSet


def unsettled(folder: Path, first: int, last: int, threshold: float) -> dict[int, int]:
    counts = {}
    for run in RunSet(folder).runs():
        rows = run.rows()
        counts[run.seed] = sum(row["metric"] > threshold for row in rows if first <= row["episode"] <= last)
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--first", type=int, default=20)
    parser.add_argument("--last", type=int, default=70)
    parser.add_argument("--threshold", type=float, default=2.0)
    args = parser.parse_args()
    first = None
    for folder in args.folders:
        counts = unsettled(folder, args.first, args.last, args.threshold)
        values = [counts[s] for s in sorted(counts)]
        line = f"{folder}: " + " ".join(map(str, values))
        if first is None:
            first = values
        else:  # against the first folder: do the per-seed counts differ in distribution?
            line += f"   (Mann-Whitney p vs the first folder: {mann_whitney(first, values)[1]:.2f})"
        print(line)


if __name__ == "__main__":
    main()
