"""``sweep.md`` and ``sweep.json``: one row per grid point, each compared with a baseline point.

Per point: success rate, episodes to threshold (median, IQR), and against the baseline
(the first point, or ``--baseline NAME``): the difference of medians with a 95% percentile
bootstrap CI, Mann-Whitney U p, and Fisher's exact p on the success rates. The statistics
are ``report/stats.py``'s, the same ones ``compare`` reports; each point's folder also gets
``summary.md`` and ``curves.png`` from ``aggregate``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.report.aggregate import write_aggregate
from keras_rl.report.equivalence import Arm
from keras_rl.report.plots import plot_sweep
from keras_rl.report.stats import (
    censored_mann_whitney,
    episodes_to_threshold_stats,
    fisher_exact,
    median_difference_ci,
    success_difference_ci,
)
from keras_rl.runs.files import atomic_write_json, atomic_write_text
from keras_rl.runs.run_set import RunSet
from keras_rl.runs.summary import RunSummary


def analyse_sweep(summaries: dict[str, list[RunSummary]], baseline: str) -> dict[str, Any]:
    """Every number in ``sweep.md``, from the seeds' summaries."""
    if baseline not in summaries:
        raise ConfigError(f"--baseline {baseline!r} is not a grid point; the points are {', '.join(summaries)}")
    if not summaries[baseline]:
        raise RunFolderError(
            f"the baseline grid point {baseline!r} has no run to compare with (its jobs' errors are above)"
        )
    stats = {
        name: episodes_to_threshold_stats([s.reached_at_episode for s in ss], [s.success for s in ss])
        for name, ss in summaries.items()
        if ss  # a point none of whose seeds left a summary (each job's error was printed) has no row
    }
    base = stats[baseline]
    budget = max(s.budget_episodes for ss in summaries.values() for s in ss)
    rows = []
    for name, st in stats.items():
        row = {
            "point": name,
            "seeds": st["seeds"],
            "successes": st["successes"],
            "success_rate": st["success_rate"],
            "median": st["median"],
            "q25": st["q25"],
            "q75": st["q75"],
            "episodes_to_threshold": st["episodes_to_threshold"],
            "unfinished": sorted(s.seed for s in summaries[name] if s.status != "completed"),
        }
        if name != baseline:
            a, b = st["episodes_to_threshold"], base["episodes_to_threshold"]
            diff = median_difference_ci(a, b, np.random.default_rng(0)) if a and b else None
            row.update(
                median_difference=None
                if diff is None
                else {"estimate": diff.estimate, "low": diff.low, "high": diff.high},
                success_difference=dataclasses.asdict(
                    success_difference_ci(st["successes"], st["seeds"], base["successes"], base["seeds"])
                ),
                mann_whitney_p=censored_mann_whitney(
                    Arm.of(summaries[name]).episodes(), Arm.of(summaries[baseline]).episodes(), budget
                )[1],
                fisher_p=fisher_exact(st["successes"], st["seeds"], base["successes"], base["seeds"]),
            )
        rows.append(row)
    return {"baseline": baseline, "points": rows}


def _fmt(value: Any, digits: str = "g") -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "n/a"
    return f"{value:{digits}}"


def write_sweep_report(
    out: Path, experiment, base_config, summaries: dict[str, list[RunSummary]], baseline: str, command: str
) -> dict[str, Any]:
    out = Path(out)
    result = analyse_sweep(summaries, baseline)
    for name, ss in summaries.items():
        if ss:
            write_aggregate(
                out / name,
                ss,
                base_config.threshold,
                f"{experiment.name} sweep: {name}, {len(ss)} seeds",
                experiment.metric_label(base_config),
                experiment.post_reference,
            )
    criterion = next((s.criterion for ss in summaries.values() for s in ss), "")
    curves = {}
    for name, ss in summaries.items():
        runs = {r.seed: r for r in RunSet(out / name).runs()}
        rows = [runs[s.seed].rows(expected_rows=s.rows_expected) if s.seed in runs else [] for s in ss]
        curves[name] = [r for r in rows if r]
    plot_sweep(
        out / "sweep.png",
        curves,
        base_config.threshold,
        experiment.metric_label(base_config),
        f"{experiment.name} ({base_config.variant}, {base_config.framework}) sweep",
    )
    lines = [
        f"# {experiment.name} ({base_config.variant}, {base_config.framework}) sweep",
        "",
        f"Criterion: {criterion}. Baseline: `{baseline}`. Command: `{command}`",
        "",
        "![every grid point's median metric per episode, with its interquartile band](sweep.png)",
        "",
        "| grid point | success | minus baseline [95% CI] | Fisher p | episodes to threshold: median (IQR) "
        "| minus baseline [95% CI] | Mann-Whitney p | curves |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in result["points"]:
        diff = row.get("median_difference")
        diff_text = (
            "(baseline)"
            if row["point"] == baseline
            else ("n/a" if diff is None else f"{diff['estimate']:.4g} [{diff['low']:.4g}, {diff['high']:.4g}]")
        )
        rate = row.get("success_difference")
        rate_text = (
            "(baseline)" if rate is None else f"{rate['estimate']:+.2f} [{rate['low']:+.2f}, {rate['high']:+.2f}]"
        )
        unfinished = f" ({len(row['unfinished'])} unfinished)" if row["unfinished"] else ""
        lines.append(
            f"| `{row['point']}` | {row['successes']}/{row['seeds']}{unfinished} | {rate_text} "
            f"| {_fmt(row.get('fisher_p'), '.3g') if row['point'] != baseline else '-'} "
            f"| {_fmt(row['median'])} ({_fmt(row['q25'])}-{_fmt(row['q75'])}) | {diff_text} "
            f"| {_fmt(row.get('mann_whitney_p'), '.3g') if row['point'] != baseline else '-'} "
            f"| [curves]({row['point']}/curves.png) |"
        )
    lines += [
        "",
        "The success difference is a point's success rate minus the baseline's, with Newcombe's hybrid "
        "score interval; Fisher's exact test compares the success counts. Episodes to threshold are over the "
        "seeds that succeeded; their difference is the median of a point minus the baseline's, with a "
        "percentile bootstrap (10000 resamples); Mann-Whitney U is two-sided over every seed, one that never "
        "reached the threshold counting as the budget + 1 (Gehan's treatment of censoring, as in `check`). At "
        f"{_seed_count(result)} seeds a point only effects large enough for these intervals to exclude 0 are "
        "detectable: an interval that includes 0 is no evidence of no effect.",
        "",
    ]
    atomic_write_text(out / "sweep.md", "\n".join(lines))
    atomic_write_json(
        out / "sweep.json",
        {
            "experiment": experiment.name,
            "variant": base_config.variant,
            "framework": base_config.framework,
            "criterion": criterion,
            "command": command,
            **result,
        },
    )
    return result


def _seed_count(result: dict[str, Any]) -> str:
    """The seeds per point, as the sentence about detectable effects needs it ("10", "8 to 10")."""
    counts = sorted({row["seeds"] for row in result["points"]})
    return str(counts[0]) if len(counts) == 1 else f"{counts[0]} to {counts[-1]}"
