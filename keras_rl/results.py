"""Run folders: what each seed writes, written atomically so nothing is ever half a file.

A run folder holds ``config.json``, ``episodes.csv``, ``summary.json``, ``curve.png``
and ``<network>.weights.h5``. ``episodes.csv`` is rewritten (atomically) after every
episode, so Ctrl-C, a NaN or a crash leaves a valid file with every finished episode.
"""

from __future__ import annotations

import contextlib
import csv
import math
import io
import json
import os
import platform
import signal
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402

def episode_columns(loss_names: tuple[str, ...]) -> tuple[str, ...]:
    """``episode`` counts from 1; ``steps`` is that episode's length; ``metric`` is the post's
    progress metric (post 000: the EMA; post 003: the 100-episode mean); each loss is the
    mean over the episode's updates (empty before training starts); ``wall_seconds`` is the
    time since the run started."""
    return ("episode", "steps", "total_steps", "score", "metric", *loss_names, "wall_seconds")


@contextlib.contextmanager
def sigint_as_flag():
    """Inside the block, Ctrl-C appends to the yielded list instead of raising.

    The training loop checks the list between env steps. A KeyboardInterrupt raised
    asynchronously can land inside TensorFlow's C++ code (e.g. ``tf.constant`` converting
    a numpy array), which turns it into a SystemError: the run would end as an "error"
    instead of "interrupted". Outside the main thread signals cannot be handled, and a
    SIGINT the process was started with ignored (``cmd &`` in a script) stays ignored.
    """
    caught: list[int] = []
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        yield caught
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def sigint_deferred(reraise: bool = True):
    """Hold Ctrl-C back until the block is done, so a write and its bookkeeping stay together.

    A SIGINT that arrives inside the block is remembered and raised as KeyboardInterrupt
    when the block ends (``reraise=False``: dropped, for a flush that is the run's last act).
    """
    with sigint_as_flag() as caught:
        yield
    if caught and reraise:
        raise KeyboardInterrupt


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write to a temporary file beside ``path``, fsync, then rename over it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2) + "\n")


def save_figure(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def save_weights(model, path: Path) -> None:
    """``model.save_weights`` to a temporary ``.weights.h5`` name, then rename."""
    path = Path(path)
    tmp = path.with_name(f".tmp-{os.getpid()}-{path.name}")
    try:
        model.save_weights(str(tmp))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load_weights(model, path: Path) -> None:
    """``model.load_weights`` with a RunFolderError that names a missing or damaged file."""
    from keras_rl.errors import RunFolderError

    path = Path(path)
    if not path.is_file():
        raise RunFolderError(f"{path} is missing; the run did not save it")
    try:
        model.load_weights(str(path))
    except Exception as exc:  # h5py/keras raise many kinds for a damaged file
        raise RunFolderError(f"{path} could not be loaded ({type(exc).__name__}: {exc})") from None


def library_versions() -> dict[str, str]:
    import gymnasium
    import keras
    import numpy
    import tensorflow

    from keras_rl import __version__

    return {"keras_rl": __version__, "python": platform.python_version(),
            "tensorflow": tensorflow.__version__, "keras": keras.__version__,
            "keras_backend": keras.backend.backend(), "gymnasium": gymnasium.__version__,
            "numpy": numpy.__version__}


def format_row(row: dict[str, Any], columns: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for key in columns:
        value = row.get(key)
        if value is None:
            out[key] = ""
        elif isinstance(value, float):
            out[key] = f"{value:.6f}" if key == "wall_seconds" else repr(value)
        else:
            out[key] = str(value)
    return out


def episodes_csv_text(rows: Iterable[dict[str, Any]], columns: tuple[str, ...]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(format_row(row, columns))
    return buf.getvalue()


def read_episodes(path: Path) -> list[dict[str, Any]]:
    """Parse an ``episodes.csv`` back into typed rows."""
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or "score" not in reader.fieldnames:
            raise ValueError(f"{path} is not an episodes.csv (no header with 'score')")
        rows = []
        for raw in reader:
            rows.append({k: (float(v) if v not in ("", None) and k not in ("episode", "steps", "total_steps")
                             else (int(v) if v not in ("", None) else None)) for k, v in raw.items()})
        return rows


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


@dataclass
class RunRecorder:
    """Writes one seed's run folder as the run goes."""

    out_dir: Path
    loss_names: tuple[str, ...] = ()
    rows: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.out_dir = Path(self.out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)

    def write_config(self, config_dict: dict[str, Any]) -> None:
        atomic_write_json(self.out_dir / "config.json", config_dict)

    def add_episode(self, row: dict[str, Any]) -> None:
        # The file and the in-memory rows change together: Ctrl-C waits for both.
        with sigint_deferred():
            atomic_write_text(self.out_dir / "episodes.csv",
                              episodes_csv_text([*self.rows, row], episode_columns(self.loss_names)))
            self.rows.append(row)

    def write_summary(self, summary: dict[str, Any]) -> None:
        atomic_write_json(self.out_dir / "summary.json", summary)

    def command_line(self) -> str:
        return command_line()


def command_line() -> str:
    """The command that produced this run, as a user would type it."""
    prog = Path(sys.argv[0]).name
    if prog in ("__main__.py", "keras-rl", "cli.py"):
        prog = "keras-rl"
    elif prog.endswith(".py"):
        prog = f"python {sys.argv[0]}"
    return " ".join([prog, *sys.argv[1:]])
