"""A run set: a folder of ``seed_<n>/`` run folders, or their packed form, read one way.

Every reader of a set of seeds (``aggregate``, ``compare``, ``check``'s baselines, the tables,
the calibration, the manifest) finds them here, so "which seeds, in which order, and what each
holds" has one answer, whichever form they are stored in:

- live runs write folders named ``seed_<n>`` (``n`` a whole number);
- a finished set is packed into one ``runs.parquet`` in the same folder (``runs/packed.py``).

A set may hold both (a packed set grown by new runs); a seed held in both is refused. Seeds
come in seed order. Nothing here imports TensorFlow.
"""

from __future__ import annotations

import json
import numbers
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.runs.files import SEED_FOLDER, seed_of

__all__ = ["SEED_FOLDER", "RunSet", "SeedRun", "seed_of"]


@dataclass(frozen=True)
class SeedRun:
    """One seed of a run set: its summary, config and episodes, from its folder or the packed file."""

    run_set: RunSet
    seed: int
    folder: Path | None
    """Its ``seed_<n>/`` folder, or None where it is packed."""

    @property
    def where(self) -> str:
        """How a message names it."""
        if self.folder is not None:
            return str(self.folder)
        from keras_rl.runs.packed import PACKED

        return f"{self.run_set.folder / PACKED} (seed {self.seed})"

    def summary_record(self) -> dict[str, Any]:
        """``summary.json`` as written."""
        if self.folder is not None:
            return json.loads((self.folder / "summary.json").read_text())
        return self.run_set.packed().summary_record(self.seed)

    def summary(self):
        """The typed ``RunSummary`` (a RunFolderError names a corrupt one)."""
        from keras_rl.runs.summary import RunSummary

        if self.folder is not None:
            return RunSummary.read(self.folder)
        return RunSummary.from_json(self.summary_record())

    def config(self) -> dict[str, Any]:
        """``config.json`` as written."""
        if self.folder is not None:
            path = self.folder / "config.json"
            try:
                return json.loads(path.read_text())
            except (OSError, ValueError) as exc:
                raise RunFolderError(f"{path} is missing or corrupt ({exc})") from None
        return self.run_set.packed().config(self.seed)

    def rows(self, expected_rows: int | None = None) -> list[dict[str, Any]]:
        """The typed rows of ``episodes.csv`` (``files.read_episodes``), or [] where it wrote none."""
        from keras_rl.runs.files import read_episodes

        if self.folder is not None:
            path = self.folder / "episodes.csv"
            return read_episodes(path, expected_rows=expected_rows) if path.is_file() else []
        return self.run_set.packed().rows(self.seed)

    def columns(self) -> dict[str, list[Any]]:
        """The typed episodes column by column (``rows`` turned on its side; the packed form
        reads them so without building a row at all)."""
        if self.folder is None:
            return self.run_set.packed().columns_of(self.seed)
        rows = self.rows()
        return {c: [row[c] for row in rows] for c in (rows[0] if rows else {})}

    def text_rows(self) -> list[dict[str, str]]:
        """The rows as the exact text written, without the timing column (what a replay compares)."""
        from keras_rl.runs.files import seed_rows

        if self.folder is not None:
            return seed_rows(self.folder / "episodes.csv")
        return self.run_set.packed().record(self.seed).text_rows()

    def file_text(self, name: str) -> str:
        """Another file of the seed's (``evaluation.json``): its folder's, or the packed copy."""
        if self.folder is not None:
            return (self.folder / name).read_text()
        files = self.run_set.packed().record(self.seed).files
        if name not in files:
            raise RunFolderError(f"{self.where} holds no {name}")
        return files[name]

    def extract(self, dest: Path) -> Path:
        """This seed as a run folder at ``dest``: a copy of its folder, or its packed records
        written out (``config.json`` and ``summary.json`` as they were, ``episodes.csv`` with
        wall time to the millisecond)."""
        if self.folder is not None:
            import shutil

            shutil.copytree(self.folder, dest)
            return Path(dest)
        from keras_rl.runs.packed import extract

        return extract(self.run_set.packed(), self.seed, dest)

    def config_path(self, scratch: Path) -> Path:
        """A ``config.json`` of this seed on disk (written under ``scratch`` where it is packed)."""
        if self.folder is not None:
            return self.folder / "config.json"
        from keras_rl.atomic import atomic_write_text

        path = Path(scratch) / f"seed_{self.seed}" / "config.json"
        atomic_write_text(path, self.run_set.packed().record(self.seed).config_text)
        return path


@dataclass(frozen=True)
class RunSet:
    """The seeds of ``folder``: its ``seed_<n>/`` folders and its ``runs.parquet``."""

    folder: Path

    def packed(self):
        """The packed part (``runs/packed.PackedSet``), or None where there is none."""
        from keras_rl.runs.packed import PACKED, open_packed

        path = Path(self.folder) / PACKED
        return open_packed(path) if path.is_file() else None

    def seed_dirs(self, holding: str | None = None) -> list[Path]:
        """The run folders in seed order (the folder form only); only those that hold the
        file ``holding``, if given."""
        folder = Path(self.folder)
        found = [
            p
            for p in folder.glob("seed_*")
            if SEED_FOLDER.fullmatch(p.name) and p.is_dir() and (holding is None or (p / holding).is_file())
        ]
        return sorted(found, key=seed_of)

    def runs(self, holding: str = "summary.json") -> list[SeedRun]:
        """Every seed, folders (those holding ``holding``) and packed alike, in seed order."""
        folders = {seed_of(p): p for p in self.seed_dirs(holding=holding)}
        packed = self.packed()
        out = {s: SeedRun(self, s, d) for s, d in folders.items()}
        for s in packed.seeds if packed is not None else ():
            if s in out:
                raise RunFolderError(
                    f"seed {s} is both in {folders[s]} and in {packed.path}: remove the one that is not the run"
                )
            out[s] = SeedRun(self, s, None)
        return [out[s] for s in sorted(out)]

    def run(self, seed: int) -> SeedRun:
        """One seed; a RunFolderError names the set and the seeds it holds."""
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
            raise ConfigError(f"a seed is a whole number, got {seed!r}")
        for r in self.runs():
            if r.seed == seed:
                return r
        raise RunFolderError(f"{self.folder} holds no finished seed {seed}")

    @property
    def seeds(self) -> list[int]:
        return [r.seed for r in self.runs()]

    def summary_records(self) -> list[dict[str, Any]]:
        """Each finished run's ``summary.json`` as written, in seed order."""
        return [r.summary_record() for r in self.runs()]

    def summaries(self) -> list:
        """Each run's ``RunSummary`` (a RunFolderError names a corrupt one), in seed order."""
        return [r.summary() for r in self.runs()]

    def configs(self) -> list[dict[str, Any]]:
        """Each run's ``config.json`` as written, in seed order."""
        return [r.config() for r in self.runs(holding="config.json")]

    def kinds(self) -> dict[tuple[str, str, str], list[int]]:
        """(experiment, variant, framework) -> the seeds of that kind: one key for a set that is one
        study, more for a folder that mixes them (which ``aggregate`` and ``reproduce`` refuse)."""
        out: dict[tuple[str, str, str], list[int]] = {}
        for run in self.runs(holding="config.json"):
            c = run.config()
            out.setdefault((c["experiment"], c["variant"], c.get("framework", "keras")), []).append(run.seed)
        return out

    def episodes(self):
        """Every episode of every run, one row each with its ``seed``: a pandas DataFrame where
        pandas is installed (for a notebook to plot), else a list of dicts."""
        rows = [{"seed": r.seed, **row} for r in self.runs(holding="episodes.csv") for row in r.rows()]
        try:
            import pandas as pd
        except ImportError:
            return rows
        return pd.DataFrame(rows)

    @staticmethod
    def seed_at(seed_dir: Path) -> SeedRun:
        """The seed a ``<set>/seed_<n>`` path names: its folder where there is one, else the
        set's packed record of it; a RunFolderError where neither holds it."""
        seed_dir = Path(seed_dir)
        seed = seed_of(seed_dir)
        run_set = RunSet(seed_dir.parent)
        if seed_dir.is_dir():
            return SeedRun(run_set, seed, seed_dir)
        packed = run_set.packed()
        if packed is None or seed not in packed.seeds:
            raise RunFolderError(
                f"{seed_dir} is not a run: no such folder, and no runs.parquet beside it holds seed {seed}"
            )
        return SeedRun(run_set, seed, None)

    @staticmethod
    def find(root: Path) -> Iterator[RunSet]:
        """Every run set under ``root``, at any depth (a folder holding a ``seed_<n>/summary.json``
        or a ``runs.parquet``)."""
        from keras_rl.runs.packed import PACKED

        parents = {
            p.parent.parent for p in Path(root).rglob("seed_*/summary.json") if SEED_FOLDER.fullmatch(p.parent.name)
        }
        parents |= {p.parent for p in Path(root).rglob(PACKED)}
        for parent in sorted(parents):
            yield RunSet(parent)
