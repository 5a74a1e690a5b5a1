"""Every figure the project draws to a file (matplotlib, no display)."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402

from keras_rl.runs.files import atomic_write_bytes, read_episodes  # noqa: E402


def save_figure(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def plot_curve(path: Path, rows: list[dict[str, Any]], threshold: float, title: str,
               metric_label: str, score_label: str = "score", metric_in_score_units: bool = True) -> None:
    """Score and metric per episode with the threshold line, like the post's figure.

    A metric in other units than the score (post 001's goal share or return spread) gets
    its own axis on the right, with the threshold drawn there.
    """
    fig, ax = plt.subplots(figsize=(7, 4))
    episodes = [r["episode"] for r in rows]
    ax.plot(episodes, [r["score"] for r in rows], color="tab:blue", lw=0.8, label=score_label)
    metric_ax = ax if metric_in_score_units else ax.twinx()
    metric = [r["metric"] if r["metric"] is not None and math.isfinite(r["metric"]) else float("nan") for r in rows]
    metric_ax.plot(episodes, metric, color="tab:orange", lw=1.6, label=metric_label)
    metric_ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    if not metric_in_score_units:
        metric_ax.set_ylabel(metric_label, color="tab:orange", fontsize=8)
    ax.set_xlabel("episode")
    ax.set_ylabel(score_label)
    ax.set_title(title)
    handles = ax.get_legend_handles_labels()
    if metric_ax is not ax:
        extra = metric_ax.get_legend_handles_labels()
        handles = (handles[0] + extra[0], handles[1] + extra[1])
    ax.legend(*handles, loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def plot_seed_curve(run_dir: Path, experiment, config) -> None:
    """A seed folder's ``curve.png`` from its ``episodes.csv`` (nothing if it has no episode)."""
    csv_path = Path(run_dir) / "episodes.csv"
    rows = read_episodes(csv_path) if csv_path.is_file() else []
    if rows:
        plot_curve(Path(run_dir) / "curve.png", rows, config.threshold,
                   f"{experiment.name} ({config.variant}, {config.framework}), seed {config.seed}",
                   experiment.metric_label(config), metric_in_score_units=experiment.metric_in_score_units)
