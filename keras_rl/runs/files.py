"""Run folders on disk: atomic writes, ``episodes.csv`` and the recorder that writes a seed's folder.

A run folder holds ``config.json``, ``episodes.csv``, ``summary.json``, ``curve.png``
and the learner's weight files. ``episodes.csv`` is rewritten (atomically) after every
episode, so Ctrl-C, a NaN or a crash leaves a valid file with every finished episode.
No plotting here: ``keras_rl/report/plots.py`` draws the curves.
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from keras_rl.atomic import atomic_write_json, atomic_write_text
from keras_rl.errors import argument
from keras_rl.runs.signals import stop_signals_deferred


def run_folder(runs_root: Path, experiment: str, variant: str, framework: str, matched_init: bool = False) -> Path:
    """``results/<experiment>/<variant>[-torch[-matched-init]]``: where ``reproduce`` and
    ``compare`` put a variant's seed folders by default."""
    suffix = "" if framework == "keras" else f"-{framework}" + ("-matched-init" if matched_init else "")
    return Path(runs_root) / experiment / f"{variant}{suffix}"


SEED_FOLDER = re.compile(r"seed_(\d+)")
"""The name of a run folder: ``seed_<n>``."""


def seed_of(seed_dir: Path) -> int:
    """The seed a run folder is named for (a ValueError for a name that is not ``seed_<n>``)."""
    match = SEED_FOLDER.fullmatch(Path(seed_dir).name)
    if match is None:
        raise ValueError(f"{seed_dir} is not named seed_<n>")
    return int(match.group(1))


TIMING_COLUMNS = ("wall_seconds",)
"""The one column of ``episodes.csv`` that is not a function of the seed."""


def seed_rows(path: Path) -> list[dict[str, str]]:
    """The rows of an ``episodes.csv`` as the exact text written, without the timing column."""
    with open(path, newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(fh)]


def episode_columns(loss_names: tuple[str, ...]) -> tuple[str, ...]:
    """``episode`` counts from 1; ``steps`` is that episode's length; ``metric`` is the post's
    progress metric (post 000: the EMA; post 003: the 100-episode mean); each loss is the
    mean over the episode's updates (empty before training starts); ``wall_seconds`` is the
    time since the run started."""
    return ("episode", "steps", "total_steps", "score", "metric", *loss_names, "wall_seconds")


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


def episodes_csv_text(rows: Iterable[dict[str, Any]], columns: tuple[str, ...], header: bool = True) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    if header:
        writer.writeheader()
    for row in rows:
        writer.writerow(format_row(row, columns))
    return buf.getvalue()


INTEGER_COLUMNS = ("episode", "steps", "total_steps")


def read_episodes(path: Path, expected_rows: int | None = None) -> list[dict[str, Any]]:
    """Parse an ``episodes.csv`` back into typed rows. A damaged file (garbage, a line cut
    off mid-number, a missing field) or one of another length than ``expected_rows`` (what
    its ``summary.json`` counts) raises a RunFolderError that names the file and the line."""
    from keras_rl.errors import RunFolderError

    path = Path(path)
    damaged = (
        f"damaged or cut off: rerun the seed ({argument('overwrite')}, or {argument('rerun')} in compare and sweep)"
    )
    try:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames is None or "score" not in reader.fieldnames:
                raise RunFolderError(f"{path} is not an episodes.csv (no header with 'score'): {damaged}")
            rows = []
            for line, raw in enumerate(reader, start=2):
                if None in raw or None in raw.values():
                    raise RunFolderError(f"{path} line {line} has another number of fields than its header: {damaged}")
                try:
                    rows.append(
                        {k: (None if v == "" else int(v) if k in INTEGER_COLUMNS else float(v)) for k, v in raw.items()}
                    )
                except ValueError as exc:
                    raise RunFolderError(f"{path} line {line} cannot be read ({exc}): {damaged}") from None
    except UnicodeDecodeError:
        raise RunFolderError(f"{path} is not text: {damaged}") from None
    if expected_rows is not None and len(rows) != expected_rows:
        raise RunFolderError(
            f"{path} holds {len(rows)} episodes, but its summary.json counts {expected_rows}: {damaged}"
        )
    return rows


@dataclass
class RunRecorder:
    """Writes one seed's run folder as the run goes."""

    out_dir: Path
    loss_names: tuple[str, ...] = ()
    rows: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.out_dir = Path(self.out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._written: tuple[list, int] | None = None  # (the rows list, its length) as episodes.csv holds them

    def write_config(self, config_dict: dict[str, Any]) -> None:
        atomic_write_json(self.out_dir / "config.json", config_dict)

    def add_episode(self, row: dict[str, Any]) -> None:
        """The new row appended to ``episodes.csv`` in one ``write`` (a kill leaves it whole or
        absent), where the file holds exactly ``rows``; otherwise (a first episode, ``rows``
        replaced or cut, as a resume does) the whole file written atomically."""
        columns = episode_columns(self.loss_names)
        path = self.out_dir / "episodes.csv"
        # The file and the in-memory rows change together: Ctrl-C waits for both.
        with stop_signals_deferred():
            written = self._written
            if written is not None and written[0] is self.rows and written[1] == len(self.rows) and path.is_file():
                _append(path, episodes_csv_text([row], columns, header=False).encode("utf-8"))
            else:
                atomic_write_text(path, episodes_csv_text([*self.rows, row], columns))
            self.rows.append(row)
            self._written = (self.rows, len(self.rows))


def _append(path: Path, data: bytes) -> None:
    """``data`` at the end of ``path`` in one ``write`` call; a short write is undone."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        size = os.fstat(fd).st_size
        try:
            written = os.write(fd, data)
        except OSError as exc:  # a full disk: the message names the file
            os.ftruncate(fd, size)
            raise OSError(exc.errno, f"could not write {path}: {exc.strerror or exc}") from exc
        if written != len(data):
            os.ftruncate(fd, size)
            raise OSError(f"could not write {path}: {written} of {len(data)} bytes written")
    finally:
        os.close(fd)


@contextlib.contextmanager
def run_folder_locks(run_dirs: Iterable[Path]):
    """One writer per run folder: an exclusive ``flock`` on ``.<folder>.lock`` beside each
    folder (beside it, so clearing the folder for ``--overwrite`` keeps the lock), held for
    the block. A folder another process holds raises a RunFolderError that names it and
    the holder's pid, before anything in any of the folders is touched. The lock goes with
    the process, however it ends (``kill -9`` included); a block that ends removes its lock
    files, so output folders do not keep them (a process that locked a file just removed
    sees that the name now points elsewhere, and locks again)."""
    import fcntl

    from keras_rl.errors import RunFolderError

    handles: list[tuple[Path, Any]] = []
    try:
        for run_dir in run_dirs:
            run_dir.parent.mkdir(parents=True, exist_ok=True)
            path = run_dir.parent / f".{run_dir.name}.lock"
            while True:
                handle = open(path, "a+")
                try:
                    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    handle.seek(0)
                    holder = handle.read().strip() or "another process"
                    handle.close()
                    raise RunFolderError(
                        f"{run_dir} is being written by another keras-rl command ({holder}); wait for "
                        f"it to end, or pass another {argument('out')}"
                    ) from None
                try:
                    same = os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino
                except FileNotFoundError:
                    same = False
                if same:
                    break
                handle.close()  # its holder removed the file as we opened it: lock the new one
            handle.seek(0)
            handle.truncate()
            handle.write(f"pid {os.getpid()}")
            handle.flush()
            handles.append((path, handle))
        yield
    finally:
        for path, handle in handles:
            with contextlib.suppress(OSError):
                path.unlink()  # while still held, so no other process holds this file
            handle.close()  # releases the lock
