"""Replaying a committed run: the command that reruns one seed, and where two runs part.

``episodes.csv`` is a function of the seed in every column but ``wall_seconds``. A rerun of a
committed seed (same code, same library versions, same kind of CPU) must give the same rows
bit for bit; where it does not, the first differing episode says how far the two agree. The
replay test (``tests/test_committed_runs_replay.py``) and the version matrix
(``matrix/compat_cell.py``) both use this.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

from keras_rl.runs.files import TIMING_COLUMNS, seed_rows

__all__ = [
    "TIMING_COLUMNS",
    "Divergence",
    "Replay",
    "first_divergence",
    "plan_replay",
    "seed_rows",
    "why_not_bit_exact",
]


@dataclass(frozen=True)
class Divergence:
    """Where a rerun first differs from the committed run (``None`` fields: it does not)."""

    compared: int  # episodes compared (the shorter of the two files, at most the budget)
    first_episode: int | None  # the first episode whose row differs
    columns: tuple[str, ...]  # the columns that differ in that row

    @property
    def identical(self) -> bool:
        return self.first_episode is None

    def as_dict(self) -> dict:
        return {"compared": self.compared, "first_episode": self.first_episode, "columns": list(self.columns)}


def first_divergence(expected: list[dict[str, str]], got: list[dict[str, str]]) -> Divergence:
    """Compare two runs row by row. A rerun with fewer rows than expected differs at the first
    missing episode (its ``columns`` are empty)."""
    for index, want in enumerate(expected):
        if index >= len(got):
            return Divergence(len(got), int(want["episode"]), ())
        have = got[index]
        if have != want:
            columns = tuple(sorted(k for k in set(want) | set(have) if want.get(k) != have.get(k)))
            return Divergence(index + 1, int(want["episode"]), columns)
    return Divergence(len(expected), None, ())


@dataclass(frozen=True)
class Replay:
    """How to rerun one committed seed folder, and what it should give."""

    folder: Path
    experiment: str
    variant: str
    seed: int
    budget: int  # episodes to rerun
    expected: list[dict[str, str]]  # the committed rows the rerun must equal
    engine: str = "gymnasium"
    """The engine the run recorded (``runs/lifecycle.recorded_engine``): the rerun names it, since
    ``--engine auto`` would pick the compiled engine for a new Keras study."""

    def command(self, out: Path, *extra: str, python: str | None = None) -> list[str]:
        return [
            python or sys.executable,
            "-m",
            "keras_rl",
            "reproduce",
            self.experiment,
            "--variant",
            self.variant,
            "--seeds",
            str(self.seed),
            "--episodes",
            str(self.budget),
            "--no-progress",
            "--engine",
            self.engine,
            "--out",
            str(out),
            *extra,
        ]

    def divergence(self, out: Path) -> Divergence:
        return first_divergence(self.expected, seed_rows(Path(out) / f"seed_{self.seed}" / "episodes.csv"))


def plan_replay(folder: Path, experiment: str, episodes: int | None = None) -> Replay:
    """The replay of a committed seed (``<set>/seed_<n>``, a folder or packed in the set's
    ``runs.parquet``): its first ``episodes`` rows, or the whole run (a run that ended before its
    budget is rerun with its own budget, so it ends the same way)."""
    from keras_rl.runs.run_set import RunSet

    folder = Path(folder)
    run = RunSet.seed_at(folder)
    config = run.config()
    rows = run.text_rows()
    expected = rows[:episodes] if episodes is not None else rows
    budget = len(expected) if episodes is not None else int(config["episodes"])
    from keras_rl.runs.lifecycle import recorded_engine

    engine = recorded_engine(folder) or "gymnasium"
    return Replay(folder, experiment, str(config["variant"]), int(config["seed"]), budget, expected, engine)


PLATFORMS = Path(__file__).resolve().parents[1] / "results" / "PLATFORMS.json"
"""Machines measured against the committed runs' bits, with the evidence: ``not_bit_exact``, those
measured not to reproduce them (a CPU of the same model name but another instruction set rounds
differently); ``bit_exact``, CPUs of another model name measured to reproduce the runs of one
framework made on ``same_as`` (TensorFlow's kernels follow the instruction set; PyTorch's matrix
products, MKL's, also follow the CPU's vendor)."""


def why_not_bit_exact(recorded: dict, platforms: Path = PLATFORMS, framework: str = "keras") -> str | None:
    """None where this machine is expected to rerun a ``framework`` run with provenance
    ``recorded`` bit for bit; else why not: another CPU model (unless ``platforms`` lists this
    machine as measured to give that model's bits for ``framework``), another instruction set
    (runs record ``cpu_isa`` from 2026-11-24 on), or this machine is listed in ``platforms`` as
    measured not to."""
    from keras_rl.runs.provenance import cpu_isa, cpu_model

    listed = json.loads(platforms.read_text()) if platforms.is_file() else {}
    here = (cpu_model(), cpu_isa())
    theirs = recorded.get("cpu_model")
    if recorded.get("cpu_isa") is not None and recorded["cpu_isa"] != cpu_isa():
        return f"made on a CPU with {', '.join(recorded['cpu_isa'])}; this one has {', '.join(cpu_isa())}"
    for entry in listed.get("bit_exact", []):
        if (entry["cpu_model"], entry["cpu_isa"]) == here and entry["same_as"] == theirs:
            if framework in entry["frameworks"]:
                return None
    if theirs is not None and theirs != cpu_model():
        return f"made on {theirs!r}, this is {cpu_model()!r}"
    for entry in listed.get("not_bit_exact", []):
        if (entry["cpu_model"], entry["cpu_isa"]) == here:
            return f"this machine ({cpu_model()}; {', '.join(cpu_isa())}) is measured not to: {entry['measured']}"
    return None
