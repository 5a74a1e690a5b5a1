"""``sweep.md`` and ``sweep.json``: one row per grid point, each compared with a baseline point.

Per point: success rate, episodes to threshold (median, IQR; by the plans' reading, each seed's
first passing episode, with the code's reading before issue 52 beside it where the two differ),
and against the baseline
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

from keras_rl.atomic import atomic_write_json, atomic_write_text
from keras_rl.errors import ConfigError, RunFolderError, argument
from keras_rl.report.aggregate import write_aggregate
from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING, Arm
from keras_rl.report.plots import plot_sweep
from keras_rl.report.stats import (
    censored_mann_whitney,
    fisher_exact,
    median_difference_ci,
    success_difference_ci,
)
from keras_rl.runs.run_set import RunSet
from keras_rl.runs.summary import RunSummary


def analyse_sweep(summaries: dict[str, list[RunSummary]], baseline: str) -> dict[str, Any]:
    """Every number in ``sweep.md``, from the seeds' summaries."""
    if baseline not in summaries:
        raise ConfigError(
            f"{argument('baseline', repr(baseline))} is not a grid point; the points are {', '.join(summaries)}"
        )
    if not summaries[baseline]:
        raise RunFolderError(
            f"the baseline grid point {baseline!r} has no run to compare with (its jobs' errors are above)"
        )
    # episodes to threshold by the plans' reading, as Mann-Whitney reads them; the code's reading
    # before issue 52 kept beside (``before_issue_52``) where it differs (post 001), not governing
    arms = {name: Arm.of(ss) for name, ss in summaries.items() if ss}  # a point none of whose seeds
    # left a summary (each job's error was printed) has no row
    stats = {name: arm.stats(FIRST_PASSING) for name, arm in arms.items()}
    old = {name: arm.stats(CONVERGED_AT_END) for name, arm in arms.items()}
    differ = any(old[name]["episodes_to_threshold"] != st["episodes_to_threshold"] for name, st in stats.items())
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
            row.update(
                median_difference=_difference(st["episodes_to_threshold"], base["episodes_to_threshold"]),
                success_difference=dataclasses.asdict(
                    success_difference_ci(st["successes"], st["seeds"], base["successes"], base["seeds"])
                ),
                mann_whitney_p=censored_mann_whitney(arms[name].episodes(), arms[baseline].episodes(), budget)[1],
                fisher_p=fisher_exact(st["successes"], st["seeds"], base["successes"], base["seeds"]),
            )
        if differ:
            was = old[name]
            row["before_issue_52"] = {
                "reading": CONVERGED_AT_END,
                "median": was["median"],
                "q25": was["q25"],
                "q75": was["q75"],
                "episodes_to_threshold": was["episodes_to_threshold"],
                **(
                    {}
                    if name == baseline
                    else {
                        "median_difference": _difference(
                            was["episodes_to_threshold"], old[baseline]["episodes_to_threshold"]
                        )
                    }
                ),
            }
        rows.append(row)
    return {"baseline": baseline, "points": rows}


def _difference(a: list[int], b: list[int]) -> dict[str, float] | None:
    """median(a) - median(b) with its percentile-bootstrap 95% CI (None where either is empty)."""
    if not (a and b):
        return None
    diff = median_difference_ci(a, b, np.random.default_rng(0))
    return {"estimate": diff.estimate, "low": diff.low, "high": diff.high}


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
        spread = f"{_fmt(row['median'])} ({_fmt(row['q25'])}-{_fmt(row['q75'])})"
        was = row.get("before_issue_52")
        if was is not None:  # the code's reading before issue 52, beside (the note below the table)
            spread += f"; before issue 52: {_fmt(was['median'])} ({_fmt(was['q25'])}-{_fmt(was['q75'])})"
            if row["point"] != baseline:
                d = was["median_difference"]
                diff_text += "; before issue 52: " + (
                    "n/a" if d is None else f"{d['estimate']:.4g} [{d['low']:.4g}, {d['high']:.4g}]"
                )
        lines.append(
            f"| `{row['point']}` | {row['successes']}/{row['seeds']}{unfinished} | {rate_text} "
            f"| {_fmt(row.get('fisher_p'), '.3g') if row['point'] != baseline else '-'} "
            f"| {spread} | {diff_text} "
            f"| {_fmt(row.get('mann_whitney_p'), '.3g') if row['point'] != baseline else '-'} "
            f"| [curves]({row['point']}/curves.png) |"
        )
    lines += [
        "",
        "The success difference is a point's success rate minus the baseline's, with Newcombe's hybrid "
        "score interval; Fisher's exact test compares the success counts. "
        + (
            f"Episodes to threshold are by the plan's reading (each seed's {FIRST_PASSING}, whether or not it "
            "succeeded), as Mann-Whitney reads them; beside them, labelled and not governing, the code's reading "
            f"before issue 52 ({CONVERGED_AT_END}). Their difference"
            if any("before_issue_52" in row for row in result["points"])
            else "Episodes to threshold are over the seeds that succeeded; their difference"
        )
        + " is the median of a point minus the baseline's, with a "
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
