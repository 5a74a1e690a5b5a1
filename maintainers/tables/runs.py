"""Tabulate multi-seed run folders against a baseline: the ledger's "measured effect" column.

    python -m maintainers tables runs results/pendulum/faithful \
        results/pendulum/fixed results/pendulum/ablations/*

Each argument is a folder of ``seed_<n>/summary.json`` written by ``keras-rl reproduce``.
The first is the baseline. For each folder it prints, as a Markdown table: the seeds and the
success rate with a two-sided Fisher exact p-value against the baseline's; episodes-to-threshold
(median and IQR over the seeds that reached it, by the plans' reading: each seed's first passing
episode, with the code's reading before issue 52, counted only if converged at the end, beside it
where the two differ; and their range) with a two-sided Mann-Whitney U
p-value against the baseline's over every seed, a seed that never reached the threshold counting
as the budget + 1 (``report/stats.censored_mann_whitney``, as ``compare`` and ``check`` treat it);
and the final metric (median) with its Mann-Whitney p-value
(SciPy). ``report/tables/findings.py`` puts the same table into ``results/README.md``'s per-post
sections (``runs_table``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.stats import fisher_exact, mannwhitneyu

from keras_rl.errors import ConfigError
from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING, Arm
from keras_rl.report.stats import censored_mann_whitney
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT
from maintainers.markdown import seed_span


def load(folder: Path) -> list[dict]:
    summaries = RunSet(folder).summary_records()
    if not summaries:
        raise ConfigError(f"{folder} holds no run set (no seed_<n>/summary.json and no runs.parquet)")
    return sorted(summaries, key=lambda s: s["seed"])


def p_text(p: float) -> str:
    return f"{p:.3f}" if p >= 0.001 else f"{p:.1e}"


def runs_table(folders: list[Path]) -> str:
    """The table, the first folder the baseline; a folder is shown relative to the repository
    when it is inside it."""
    base = load(folders[0])
    base_hits = Arm.of(base).hits(FIRST_PASSING)
    base_ok = sum(bool(s["success"]) for s in base)
    base_final = [s["final_metric"] for s in base]
    lines = [
        "| runs | seeds | success | Fisher p | episodes to threshold: median (IQR), range | Mann-Whitney p "
        "| final metric: median | Mann-Whitney p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for i, folder in enumerate(folders):
        summaries = load(folder)
        st = Arm.of(summaries).stats(FIRST_PASSING)
        was = Arm.of(summaries).stats(CONVERGED_AT_END)
        hits = st["episodes_to_threshold"]
        final = [s["final_metric"] for s in summaries]
        first = i == 0
        budget = max(int(x["budget_episodes"]) for x in [*summaries, *base])
        p_hits = (
            "-"
            if first or not hits or not base_hits
            else p_text(censored_mann_whitney(Arm.of(summaries).episodes(), Arm.of(base).episodes(), budget)[1])
        )
        table = [[st["successes"], st["seeds"] - st["successes"]], [base_ok, len(base) - base_ok]]
        p_ok = "-" if first else p_text(fisher_exact(table).pvalue)
        p_final = "-" if first else p_text(mannwhitneyu(final, base_final).pvalue)
        med = _spread(st)
        if was["episodes_to_threshold"] != hits:  # the code's reading before issue 52, beside, not governing
            med += f"; before issue 52: {_spread(was)}"
        shown = folder.resolve()
        shown = shown.relative_to(ROOT) if shown.is_relative_to(ROOT) else folder
        lines.append(
            f"| `{shown}` | {seed_span([s['seed'] for s in summaries])} | {st['successes']}/{st['seeds']} | {p_ok} "
            f"| {med} | {p_hits} | {np.median(final):.4g} | {p_final} |"
        )
    return "\n".join(lines)


def _spread(st: dict) -> str:
    return "n/a" if st["median"] is None else f"{st['median']:g} ({st['q25']:g}-{st['q75']:g}), {st['min']}-{st['max']}"


def run(args: argparse.Namespace) -> int:
    print(runs_table(args.folders))
    return 0
