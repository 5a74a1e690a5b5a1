"""A run set: a folder of ``seed_<n>/`` run folders, read one way.

Every reader of a set of seed folders (``aggregate``, ``check``'s baselines, the tables under
``reproductions/``, the manifest) finds them here, so "which folders are runs, in which order"
has one answer: folders named ``seed_<n>`` (``n`` a whole number), in seed order. Nothing here
imports TensorFlow.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

SEED_FOLDER = re.compile(r"seed_(\d+)")
"""The name of a run folder: ``seed_<n>``."""


def seed_of(seed_dir: Path) -> int:
    """The seed a run folder is named for (a ValueError for a name that is not ``seed_<n>``)."""
    match = SEED_FOLDER.fullmatch(Path(seed_dir).name)
    if match is None:
        raise ValueError(f"{seed_dir} is not named seed_<n>")
    return int(match.group(1))


@dataclass(frozen=True)
class RunSet:
    """The ``seed_<n>/`` folders of ``folder``."""

    folder: Path

    def seed_dirs(self, holding: str | None = None) -> list[Path]:
        """The run folders in seed order; only those that hold the file ``holding``, if given."""
        found = [
            p
            for p in Path(self.folder).glob("seed_*")
            if SEED_FOLDER.fullmatch(p.name) and p.is_dir() and (holding is None or (p / holding).is_file())
        ]
        return sorted(found, key=seed_of)

    @property
    def seeds(self) -> list[int]:
        return [seed_of(p) for p in self.seed_dirs()]

    def summary_records(self) -> list[dict[str, Any]]:
        """Each finished run's ``summary.json`` as written, in seed order."""
        return [json.loads((p / "summary.json").read_text()) for p in self.seed_dirs(holding="summary.json")]

    def summaries(self) -> list:
        """Each run's ``RunSummary`` (a RunFolderError names a corrupt one), in seed order."""
        from keras_rl.runs.summary import RunSummary

        return [RunSummary.read(p) for p in self.seed_dirs(holding="summary.json")]

    def configs(self) -> list[dict[str, Any]]:
        """Each run's ``config.json`` as written, in seed order."""
        return [json.loads((p / "config.json").read_text()) for p in self.seed_dirs(holding="config.json")]

    def episodes(self):
        """Every episode of every run, one row each with its ``seed``: a pandas DataFrame where
        pandas is installed (for a notebook to plot), else a list of dicts."""
        from keras_rl.runs.files import read_episodes

        rows = [
            {"seed": seed_of(p), **row}
            for p in self.seed_dirs(holding="episodes.csv")
            for row in read_episodes(p / "episodes.csv")
        ]
        try:
            import pandas as pd
        except ImportError:
            return rows
        return pd.DataFrame(rows)

    @staticmethod
    def find(root: Path) -> Iterator[RunSet]:
        """Every run set under ``root``, at any depth (a folder holding a ``seed_<n>/summary.json``)."""
        parents = {
            p.parent.parent for p in Path(root).rglob("seed_*/summary.json") if SEED_FOLDER.fullmatch(p.parent.name)
        }
        for parent in sorted(parents):
            yield RunSet(parent)
