"""``summary.json``: one typed record per seed, written by the loop and read by every report."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from keras_rl.atomic import atomic_write_json
from keras_rl.errors import RunFolderError

Status = Literal["running", "completed", "interrupted", "non_finite_loss", "error"]


@dataclass
class RunSummary:
    experiment: str
    variant: str
    seed: int
    status: Status
    success: bool
    """The post's criterion (``criterion``) was met."""
    criterion: str
    reached_at_episode: int | None
    """The first episode whose metric met the threshold (None: never)."""
    episodes_run: int
    budget_episodes: int
    total_steps: int
    steps_to_threshold: int | None
    final_metric: float | None
    best_metric: float | None
    """The best metric by the metric's own comparison (the lowest for post 001's spread)."""
    wall_seconds: float
    framework: str = "keras"
    message: str = ""
    command: str = ""
    versions: dict[str, str] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    """CPU model, git commit and dirtiness, working directory, start time (runs made after
    provenance was recorded; empty for older ones)."""
    extras: dict[str, Any] = field(default_factory=dict)
    """Experiment-specific numbers (``Experiment.summary_extras``), stored flat in the file."""

    @property
    def finished(self) -> bool:
        return self.status == "completed"

    @property
    def rows_expected(self) -> int | None:
        """The rows its ``episodes.csv`` must hold: ``episodes_run``, once the run has ended
        (a run killed while running may have written one episode more than its summary counts)."""
        return None if self.status == "running" else self.episodes_run

    def to_json(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "extras"}
        out["finished"] = self.finished
        return {**out, **self.extras}

    @classmethod
    def from_json(cls, values: dict[str, Any]) -> RunSummary:
        names = {f.name for f in dataclasses.fields(cls)} - {"extras"}
        known = {k: v for k, v in values.items() if k in names}
        extras = {k: v for k, v in values.items() if k not in names and k != "finished"}
        return cls(**known, extras=extras)

    def write(self, run_dir: Path) -> None:
        atomic_write_json(Path(run_dir) / "summary.json", self.to_json())

    @classmethod
    def read(cls, run_dir: Path) -> RunSummary:
        """The summary of a seed folder, or a RunFolderError naming the folder and what is wrong."""
        path = Path(run_dir) / "summary.json"
        if not path.is_file():
            raise RunFolderError(f"{run_dir} has no summary.json; is it a run folder (one seed)?")
        try:
            return cls.from_json(json.loads(path.read_text()))
        except (OSError, ValueError, TypeError) as exc:
            raise RunFolderError(f"{path} is corrupt ({type(exc).__name__}: {exc})") from None
