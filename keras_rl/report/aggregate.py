"""Several seeds of one experiment: ``summary.md`` and a plot of all curves."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.errors import RunFolderError
from keras_rl.registry import get_experiment
from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING, Arm
from keras_rl.report.plots import plot_seed_curve, plt, save_figure
from keras_rl.runs.run_set import RunSet
from keras_rl.runs.summary import RunSummary


def _fmt(value: Any) -> str:
    return "n/a" if value is None else (f"{value:g}" if isinstance(value, float) else str(value))


def write_aggregate(
    out_dir: Path,
    summaries: list[RunSummary],
    threshold: float,
    title: str,
    metric_label: str,
    post_reference: str = "",
) -> dict[str, Any]:
    """Write ``summary.md`` and ``curves.png`` for the seeds in ``summaries`` (the set in
    ``out_dir``, folders or packed)."""
    out_dir = Path(out_dir)
    summaries = sorted(summaries, key=lambda s: s.seed)
    runs = {r.seed: r for r in RunSet(out_dir).runs()}
    curves = {}  # every seed's rows, read (and checked) before anything is written
    for s in summaries:
        if s.seed in runs:
            rows = runs[s.seed].rows(expected_rows=s.rows_expected)
            if rows:
                curves[s.seed] = rows
    # one set, no comparison: its summary.md counts the seeds that succeeded, and where the plans'
    # reading (each seed's first passing episode, which compare and sweep report) differs, says it
    arm = Arm.of(summaries)
    stats = arm.stats(CONVERGED_AT_END)
    plans = arm.stats(FIRST_PASSING)
    walls = [s.wall_seconds for s in summaries]
    lines = [
        f"# {title}",
        "",
        f"Criterion: {summaries[0].criterion}." if summaries else "",
        "",
        "| seeds | success rate | episodes to threshold: median | IQR (25th-75th) | min | max | wall s (median) |",
        "|---|---|---|---|---|---|---|",
        f"| {stats['seeds']} | {stats['successes']}/{stats['seeds']} ({stats['success_rate']:.0%}) "
        f"| {_fmt(stats['median'])} | {_fmt(stats['q25'])}-{_fmt(stats['q75'])} | {_fmt(stats['min'])} "
        f"| {_fmt(stats['max'])} | {np.median(walls):.1f} |",
        "",
    ]
    if plans["episodes_to_threshold"] != stats["episodes_to_threshold"]:
        lines += [
            f"Episodes to threshold above count the seeds that succeeded ({CONVERGED_AT_END}: the code's reading "
            f"before issue 52). By the plans' reading (each seed's {FIRST_PASSING}, "
            f"{len(plans['episodes_to_threshold'])} seeds), which `compare` and `sweep` report: "
            f"median {_fmt(plans['median'])}, IQR "
            f"{_fmt(plans['q25'])}-{_fmt(plans['q75'])}, range {_fmt(plans['min'])}-{_fmt(plans['max'])}.",
            "",
        ]
    if post_reference:
        lines += [post_reference, ""]
    lines += [
        "| seed | status | reached at episode | episodes run | env steps | final metric | wall s |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        final = None if s.final_metric is None else round(s.final_metric, 1)
        lines.append(
            f"| {s.seed} | {s.status} | {_fmt(s.reached_at_episode)} | {s.episodes_run} "
            f"| {s.total_steps} | {_fmt(final)} | {s.wall_seconds:.1f} |"
        )
    if summaries:
        lines += ["", f"Command: `{summaries[0].command}`", ""]
    atomic_write_text(out_dir / "summary.md", "\n".join(lines))

    fig = draw_set_curves(curves, {s.seed: s.reached_at_episode for s in summaries}, threshold, metric_label, title)
    save_figure(fig, out_dir / "curves.png")
    return stats


def draw_set_curves(
    curves: dict[int, list[dict[str, Any]]], reached: dict[int, int | None], threshold: float, label: str, title: str
):
    """Every seed's metric as a thin line, the median and interquartile band over the seeds still
    playing (drawn while at least half of them are: later, the few slow seeds left are not the
    set), a mark where each seed first met the threshold, and no per-seed legend."""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    longest = max((len(rows) for rows in curves.values()), default=0)
    grid = np.full((len(curves), longest), np.nan)
    for i, rows in enumerate(curves.values()):
        metric = [r["metric"] if r["metric"] is not None and np.isfinite(r["metric"]) else np.nan for r in rows]
        grid[i, : len(metric)] = metric
        ax.plot(np.arange(1, len(metric) + 1), metric, color="tab:blue", lw=0.5, alpha=0.3)
    if curves:
        ax.plot([], [], color="tab:blue", lw=0.5, alpha=0.6, label=f"each of {len(curves)} seeds")
        playing = np.sum(~np.isnan(grid), axis=0)
        shown = np.flatnonzero(playing >= max(1, len(curves) / 2))
        if shown.size:
            cut = shown[-1] + 1
            with np.errstate(all="ignore"):
                q25, median, q75 = np.nanpercentile(grid[:, :cut], [25, 50, 75], axis=0)
            x = np.arange(1, cut + 1)
            ax.fill_between(x, q25, q75, color="tab:blue", alpha=0.25, lw=0, label="interquartile range")
            ax.plot(x, median, color="black", lw=1.6, label="median (while at least half the seeds play)")
        met = [(e, grid[i, e - 1]) for i, (seed, e) in enumerate((s, reached.get(s)) for s in curves) if e]
        if met:
            ax.scatter(*zip(*met), s=14, color="tab:orange", zorder=3, label="a seed first meets the threshold")
    ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    ax.set_xlabel("episode")
    ax.set_ylabel(label)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best", framealpha=0.85)
    return fig


def rebuild(parent: Path, x_axis: str = "episode") -> dict[str, Any]:
    """Rewrite ``summary.md``, ``curves.png`` and each seed's ``curve.png`` of a multi-seed
    folder from its seeds' files."""
    parent = Path(parent)
    runs = RunSet(parent).runs(holding="config.json")
    if not runs:
        raise RunFolderError(f"{parent} holds no seed_*/ run folders and no runs.parquet")
    summaries = [r.summary() for r in runs]
    configs = [r.config() for r in runs]
    keys = RunSet(parent).kinds()
    if len(keys) != 1:
        raise RunFolderError(f"{parent} mixes runs of different experiments/variants/frameworks: {sorted(keys)}")
    ((name, variant, framework),) = keys
    experiment = get_experiment(name)
    loaded = [experiment.config_cls.from_dict(c) for c in configs]
    first = loaded[0].to_dict()
    for run, config in zip(runs[1:], loaded[1:]):
        other = config.to_dict()
        differing = loaded[0].differs_from(config)
        if differing:
            k = differing[0]
            raise RunFolderError(
                f"{run.where} was made with a different config than {runs[0].where} "
                f"({k}={other[k]!r} there, {first[k]!r} here); refusing to aggregate mixed runs"
            )
    for run, config in zip(runs, loaded):
        if run.folder is not None:  # a packed set keeps no per-seed picture
            plot_seed_curve(run.folder, experiment, config, x_axis=x_axis)
    return write_aggregate(
        parent,
        summaries,
        loaded[0].threshold,
        f"{name} ({variant}, {framework}), {len(summaries)} seeds",
        experiment.metric_label(loaded[0]),
        experiment.post_reference,
    )
