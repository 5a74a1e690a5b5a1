"""Every figure the project draws to a file (matplotlib, no display)."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from keras_rl.atomic import atomic_write_bytes
from keras_rl.runs.files import read_episodes  # noqa: E402


def save_figure(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, palette_png(buf.getvalue()))


def palette_png(png: bytes) -> bytes:
    """An opaque RGB(A) PNG as a 256-colour palette PNG (median cut, no dithering): a line plot
    looks the same at about a third of the bytes (``results/``' 91 figures went from 12.5 MB to
    about 4). Deterministic for a given Pillow."""
    from PIL import Image

    image = Image.open(io.BytesIO(png))
    if image.mode == "P":
        return png
    out = io.BytesIO()
    image.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
        out, format="PNG", optimize=True
    )
    return out.getvalue()


X_AXES = {"episode": "episode", "steps": "env steps"}
"""What a curve's x axis counts: episodes, or env steps (``total_steps`` at the episode's end)."""


def plot_curve(
    path: Path,
    rows: list[dict[str, Any]],
    threshold: float,
    title: str,
    metric_label: str,
    score_label: str = "score",
    metric_in_score_units: bool = True,
    reached_at: int | None = None,
    x_axis: str = "episode",
) -> None:
    """Score and metric per episode with the threshold line, like the post's figure.

    A metric in other units than the score (post 001's goal share or return spread) gets
    its own axis on the right, with the threshold drawn there. ``reached_at``: the episode
    where the run first met its criterion, marked with a dotted line. ``x_axis``: ``episode``
    or ``steps`` (``X_AXES``).
    """
    if x_axis not in X_AXES:
        raise ValueError(f"x_axis must be one of {', '.join(X_AXES)}, got {x_axis!r}")
    fig, ax = plt.subplots(figsize=(7, 4))
    episodes = [r["episode"] if x_axis == "episode" else r["total_steps"] for r in rows]
    ax.plot(episodes, [r["score"] for r in rows], color="tab:blue", lw=0.8, label=score_label)
    metric_ax = ax if metric_in_score_units else ax.twinx()
    metric = [r["metric"] if r["metric"] is not None and math.isfinite(r["metric"]) else float("nan") for r in rows]
    metric_ax.plot(episodes, metric, color="tab:orange", lw=1.6, label=metric_label)
    metric_ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    if reached_at is not None and 1 <= reached_at <= len(rows):
        at = episodes[reached_at - 1]
        ax.axvline(
            at,
            color="tab:green",
            ls=":",
            lw=1.2,
            label=f"threshold reached (episode {reached_at}" + (f", step {at})" if x_axis == "steps" else ")"),
        )
    if not metric_in_score_units:
        metric_ax.set_ylabel(metric_label, color="tab:orange", fontsize=8)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(X_AXES[x_axis])
    ax.set_ylabel(score_label)
    ax.set_title(title)
    handles = ax.get_legend_handles_labels()
    if metric_ax is not ax:
        extra = metric_ax.get_legend_handles_labels()
        handles = (handles[0] + extra[0], handles[1] + extra[1])
    ax.legend(*handles, loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def plot_false_alarm_spread(path: Path, rates: dict[str, dict[int, Any]], alpha: float, title: str) -> None:
    """The spread of a check's false-alarm rate over the baselines it could have been given:
    one panel per tier, the empirical CDF of the rate given the baseline for each baseline
    size (``rates[tier][seeds]``: one rate per simulated baseline), with ``alpha`` marked, so
    the share of baselines above it reads off where each curve crosses the line."""
    import numpy as np

    if not rates:
        raise ValueError("no spread to plot")
    fig, axes = plt.subplots(1, len(rates), figsize=(5 * len(rates), 3.8), sharey=True, squeeze=False)
    for ax, (tier, by_size) in zip(axes[0], rates.items()):
        for seeds, values in sorted(by_size.items()):
            v = np.sort(np.asarray(values, dtype=float)) * 100
            share = float((v > alpha * 100).mean())
            ax.step(
                v,
                np.arange(1, len(v) + 1) / len(v),
                where="post",
                label=f"{seeds}-seed baselines: median {np.median(v):.2f}%, {share:.0%} above {alpha:.0%}",
            )
        ax.axvline(alpha * 100, color="k", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("false-alarm rate given the baseline (%)")
        ax.set_title(f"{tier} tier", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="lower right")
    axes[0][0].set_ylabel("share of baselines")
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)


def plot_seed_curve(run_dir: Path, experiment, config, x_axis: str = "episode") -> None:
    """A seed folder's ``curve.png`` from its ``episodes.csv`` (nothing if it has no episode),
    the episode where it met its criterion marked (from ``summary.json``, when there is one)."""
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.summary import RunSummary

    csv_path = Path(run_dir) / "episodes.csv"
    rows = read_episodes(csv_path) if csv_path.is_file() else []
    try:
        reached = RunSummary.read(run_dir).reached_at_episode
    except RunFolderError:
        reached = None
    if rows:
        plot_curve(
            Path(run_dir) / "curve.png",
            rows,
            config.threshold,
            f"{experiment.name} ({config.variant}, {config.framework}), seed {config.seed}",
            experiment.metric_label(config),
            metric_in_score_units=experiment.metric_in_score_units,
            reached_at=reached,
            x_axis=x_axis,
        )


def metric_quantiles(
    runs: list[list[dict[str, Any]]], qs: tuple[float, ...], episodes: int | None = None, min_share: float = 0.0
):
    """Per episode, the given percentiles of the runs' finite metrics: (episode numbers, one
    array per percentile). Episodes no run played (after every seed stopped) are left out, and
    a run that stopped early leaves the later episodes' quantiles to the others; with
    ``min_share``, so are episodes fewer than that share of the runs reached (the few slow seeds
    left are not the set)."""
    import numpy as np

    length = max((len(rows) for rows in runs), default=0)
    length = length if episodes is None else min(length, episodes)
    if not length:
        return np.zeros(0, int), [np.zeros(0) for _ in qs]
    grid = np.full((len(runs), length), np.nan)
    for i, rows in enumerate(runs):
        for j, r in enumerate(rows[:length]):
            if r["metric"] is not None and math.isfinite(r["metric"]):
                grid[i, j] = r["metric"]
    counts = np.sum(~np.isnan(grid), axis=0)
    played = (counts > 0) & (counts >= min_share * len(runs))
    return np.arange(1, length + 1)[played], [np.nanpercentile(grid[:, played], q, axis=0) for q in qs]


def plot_sweep(
    path: Path, curves: dict[str, list[list[dict[str, Any]]]], threshold: float, metric_label: str, title: str
) -> None:
    """One figure for a sweep: per grid point, the median of its seeds' metric per episode
    with the interquartile band (episodes a seed did not play, after it stopped, are left
    out of that episode's quantiles)."""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    drawn = 0
    for name, runs in curves.items():
        if not any(runs):
            continue
        episodes, (q25, q50, q75) = metric_quantiles(runs, (25, 50, 75))
        # a point whose every metric is NaN keeps its legend entry, with nothing drawn
        (line,) = ax.plot(episodes, q50, lw=1.4, label=f"{name} (median of {len(runs)} seeds)")
        ax.fill_between(episodes, q25, q75, color=line.get_color(), alpha=0.2, lw=0)
        drawn += bool(len(episodes))
    if not drawn:  # say so, rather than draw an empty frame
        ax.text(0.5, 0.5, "no grid point has an episode yet", ha="center", va="center", transform=ax.transAxes)
    ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("episode")
    ax.set_ylabel(f"{metric_label} (median, IQR band)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    save_figure(fig, path)


def draw_job_curves(job) -> None:
    """Each seed folder of a finished (or stopped) job gets its ``curve.png``: the commands
    pass this to ``train_seeds(..., after_job=...)``. A full disk is a warning: the run's own
    files and summary are what count, so any failure to draw (a full disk, a damaged file,
    matplotlib refusing odd data) is a warning that names the file, never an error after the
    training is done."""
    import sys

    from keras_rl.registry import get_experiment

    for member in getattr(job, "jobs", (job,)):  # a batch's seeds, or the one seed (dispatch/jobs.members)
        experiment = get_experiment(member.experiment)
        try:
            plot_seed_curve(Path(member.out_dir), experiment, member.config)
        except Exception as exc:  # noqa: BLE001 - the runs are written; a missing plot must not fail the command
            print(
                f"warning: could not draw {Path(member.out_dir) / 'curve.png'}: {type(exc).__name__}: {exc}",
                file=sys.stderr,
            )
