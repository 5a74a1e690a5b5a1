"""Several seeds of one experiment: ``summary.md`` and a plot of all curves."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.results import atomic_write_text, plt, read_episodes, save_figure


def episodes_to_threshold_stats(reached: list[int | None], success: list[bool] | None = None) -> dict[str, Any]:
    """Success rate and the distribution of episodes-to-threshold over successful seeds.

    ``success`` defaults to "reached the threshold"; experiments judged at the end of the
    run (post 001) pass their own. IQR is the 25th to 75th percentile (NumPy's default
    linear interpolation).
    """
    success = [r is not None for r in reached] if success is None else success
    hits = np.array([r for r, ok in zip(reached, success) if ok and r is not None], dtype=float)
    stats: dict[str, Any] = {"seeds": len(reached), "successes": int(sum(success)),
                             "success_rate": sum(success) / len(reached) if reached else 0.0}
    if hits.size:
        q25, q50, q75 = np.percentile(hits, [25, 50, 75])
        stats.update(median=float(q50), q25=float(q25), q75=float(q75),
                     min=int(hits.min()), max=int(hits.max()))
    else:
        stats.update(median=None, q25=None, q75=None, min=None, max=None)
    return stats


def write_aggregate(out_dir: Path, summaries: list[dict[str, Any]], threshold: float, title: str,
                    metric_label: str, post_reference: str = "") -> dict[str, Any]:
    """Write ``summary.md`` and ``curves.png`` for the seeds in ``summaries``."""
    out_dir = Path(out_dir)
    summaries = sorted(summaries, key=lambda s: s["seed"])
    stats = episodes_to_threshold_stats([s["reached_at_episode"] for s in summaries],
                                        [bool(s["success"]) for s in summaries])
    walls = [s["wall_seconds"] for s in summaries]
    fmt = lambda v: "n/a" if v is None else (f"{v:g}" if isinstance(v, float) else str(v))  # noqa: E731
    lines = [
        f"# {title}",
        "",
        f"Criterion: {summaries[0]['criterion']}." if summaries else "",
        "",
        "| seeds | success rate | episodes to threshold: median | IQR (25th-75th) | min | max | wall s (median) |",
        "|---|---|---|---|---|---|---|",
        f"| {stats['seeds']} | {stats['successes']}/{stats['seeds']} ({stats['success_rate']:.0%}) "
        f"| {fmt(stats['median'])} | {fmt(stats['q25'])}-{fmt(stats['q75'])} | {fmt(stats['min'])} "
        f"| {fmt(stats['max'])} | {np.median(walls):.1f} |",
        "",
    ]
    if post_reference:
        lines += [post_reference, ""]
    lines += ["| seed | status | reached at episode | episodes run | env steps | final metric | wall s |",
              "|---|---|---|---|---|---|---|"]
    for s in summaries:
        lines.append(f"| {s['seed']} | {s['status']} | {fmt(s['reached_at_episode'])} | {s['episodes_run']} "
                     f"| {s['total_steps']} | {fmt(None if s['final_metric'] is None else round(s['final_metric'], 1))} "
                     f"| {s['wall_seconds']:.1f} |")
    if summaries:
        lines += ["", f"Command: `{summaries[0]['command']}`", ""]
    atomic_write_text(out_dir / "summary.md", "\n".join(lines))

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for s in summaries:
        csv_path = out_dir / f"seed_{s['seed']}" / "episodes.csv"
        if not csv_path.is_file():
            continue
        rows = read_episodes(csv_path)
        metric = [r["metric"] if r["metric"] is not None and np.isfinite(r["metric"]) else np.nan for r in rows]
        ax.plot([r["episode"] for r in rows], metric, lw=1.2, label=f"seed {s['seed']}")
    ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    ax.set_xlabel("episode")
    ax.set_ylabel(metric_label)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    save_figure(fig, out_dir / "curves.png")
    return stats


def rebuild(parent: Path) -> dict[str, Any]:
    """Rewrite ``summary.md`` and ``curves.png`` of a multi-seed folder from its seeds' files."""
    import json

    from keras_rl.errors import RunFolderError
    from keras_rl.experiments import get_experiment, metric_label

    parent = Path(parent)
    paths = sorted(parent.glob("seed_*/summary.json"))
    if not paths:
        raise RunFolderError(f"{parent} holds no seed_*/summary.json")
    try:
        summaries = [json.loads(p.read_text()) for p in paths]
        configs = [json.loads((p.parent / "config.json").read_text()) for p in paths]
    except (OSError, ValueError) as exc:
        raise RunFolderError(f"{parent}: a seed folder is unreadable ({exc})") from None
    keys = {(c["experiment"], c["variant"], c.get("framework", "keras")) for c in configs}
    if len(keys) != 1:
        raise RunFolderError(f"{parent} mixes runs of different experiments/variants/frameworks: {sorted(keys)}")
    (name, variant, framework), = keys
    experiment = get_experiment(name)
    from keras_rl.results import plot_curve

    for path, config in zip(paths, configs):  # redraw each seed's curve from its CSV
        rows = read_episodes(path.parent / "episodes.csv")
        if rows:
            plot_curve(path.parent / "curve.png", rows, config["threshold"],
                       f"{name} ({variant}, {framework}), seed {config['seed']}",
                       metric_label(experiment, experiment.config_cls.from_dict(config)),
                       metric_in_score_units=experiment.metric_in_score_units)
    return write_aggregate(parent, summaries, configs[0]["threshold"],
                           f"{name} ({variant}, {framework}), {len(summaries)} seeds",
                           metric_label(experiment, experiment.config_cls.from_dict(configs[0])),
                           experiment.post_reference)
