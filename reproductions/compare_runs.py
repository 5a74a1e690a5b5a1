"""Tabulate multi-seed run folders against a baseline: the ledger's "measured effect" column.

    python reproductions/compare_runs.py results/pendulum/faithful \
        results/pendulum/fixed results/pendulum/ablations/*

Each argument is a folder of ``seed_<n>/summary.json`` written by ``keras-rl reproduce``.
The first is the baseline. For each folder it prints success rate, episodes-to-threshold
(median and IQR over successful seeds) and a two-sided Mann-Whitney U p-value
(SciPy) of its episodes-to-threshold against the baseline's, as a Markdown table.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scipy.stats import mannwhitneyu  # noqa: E402

from keras_rl.aggregate import episodes_to_threshold_stats  # noqa: E402


def load(folder: Path) -> list[dict]:
    summaries = [json.loads(p.read_text()) for p in sorted(folder.glob("seed_*/summary.json"))]
    if not summaries:
        raise SystemExit(f"error: {folder} holds no seed_*/summary.json")
    return summaries


def main(folders: list[str]) -> None:
    if not folders:
        raise SystemExit(__doc__)
    base = load(Path(folders[0]))
    base_hits = [s["reached_at_episode"] for s in base if s["success"]]
    print("| runs | seeds | success | episodes to threshold: median (IQR) | Mann-Whitney p vs first |")
    print("|---|---|---|---|---|")
    for folder in folders:
        summaries = load(Path(folder))
        st = episodes_to_threshold_stats([s["reached_at_episode"] for s in summaries])
        hits = [s["reached_at_episode"] for s in summaries if s["success"]]
        p = "-" if folder == folders[0] or not hits else f"{mannwhitneyu(hits, base_hits).pvalue:.3f}"
        med = "n/a" if st["median"] is None else f"{st['median']:g} ({st['q25']:g}-{st['q75']:g})"
        print(f"| `{folder}` | {st['seeds']} | {st['successes']}/{st['seeds']} | {med} | {p} |")


if __name__ == "__main__":
    main(sys.argv[1:])
