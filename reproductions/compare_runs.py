"""Tabulate multi-seed run folders against a baseline: the ledger's "measured effect" column.

    python reproductions/compare_runs.py results/pendulum/faithful \
        results/pendulum/fixed results/pendulum/ablations/*

Each argument is a folder of ``seed_<n>/summary.json`` written by ``keras-rl reproduce``.
The first is the baseline. For each folder it prints, as a Markdown table: the success
rate with a two-sided Fisher exact p-value against the baseline's; episodes-to-threshold
(median and IQR over successful seeds) with a two-sided Mann-Whitney U p-value against
the baseline's; and the final metric (median) with its Mann-Whitney p-value (SciPy).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from scipy.stats import fisher_exact, mannwhitneyu  # noqa: E402

from keras_rl.report.stats import episodes_to_threshold_stats  # noqa: E402


def load(folder: Path) -> list[dict]:
    summaries = [json.loads(p.read_text()) for p in sorted(folder.glob("seed_*/summary.json"))]
    if not summaries:
        raise SystemExit(f"error: {folder} holds no seed_*/summary.json")
    return summaries


def main(folders: list[str]) -> None:
    if not folders:
        raise SystemExit(__doc__)
    base = load(Path(folders[0]))
    base_hits = [s["reached_at_episode"] for s in base if s["success"] and s["reached_at_episode"]]
    base_ok = sum(bool(s["success"]) for s in base)
    base_final = [s["final_metric"] for s in base]
    print(
        "| runs | seeds | success | Fisher p | episodes to threshold: median (IQR) | Mann-Whitney p "
        "| final metric: median | Mann-Whitney p |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for folder in folders:
        summaries = load(Path(folder))
        st = episodes_to_threshold_stats(
            [s["reached_at_episode"] for s in summaries], [bool(s["success"]) for s in summaries]
        )
        hits = [s["reached_at_episode"] for s in summaries if s["success"] and s["reached_at_episode"]]
        final = [s["final_metric"] for s in summaries]
        first = folder == folders[0]
        p_hits = "-" if first or not hits or not base_hits else f"{mannwhitneyu(hits, base_hits).pvalue:.3f}"
        p_ok = (
            "-"
            if first
            else f"{fisher_exact([[st['successes'], st['seeds'] - st['successes']], [base_ok, len(base) - base_ok]]).pvalue:.3f}"  # noqa: E501
        )
        p_final = "-" if first else f"{mannwhitneyu(final, base_final).pvalue:.3f}"
        med = "n/a" if st["median"] is None else f"{st['median']:g} ({st['q25']:g}-{st['q75']:g})"
        print(
            f"| `{folder}` | {st['seeds']} | {st['successes']}/{st['seeds']} | {p_ok} | {med} | {p_hits} "
            f"| {np.median(final):.4g} | {p_final} |"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
