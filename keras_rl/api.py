"""The Python API, for notebooks: train seeds, load a run set, compare frameworks, check.

Each function takes the same inputs as its command (``keras-rl reproduce``, ``compare``,
``check``), checks them the same way (a ``ConfigError`` names bad input, before anything is
written) and returns a typed result instead of an exit code. ``docs/api.md`` shows them.

    from keras_rl import api
    runs = api.load("results/pendulum/faithful")
    runs.episodes()                      # every episode of every seed, a DataFrame with pandas
    report = api.compare("pendulum", seeds=range(30), reuse_only=True, out="runs/compare")
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from keras_rl.runs.run_set import RunSet

__all__ = ["Reproduced", "RunSet", "check", "compare", "load", "reproduce"]


@dataclass(frozen=True)
class Reproduced:
    """What ``reproduce`` made: the run set, and the command's exit code (0: the criterion held)."""

    runs: RunSet
    exit_code: int

    @property
    def summaries(self) -> list:
        return self.runs.summaries()


def _seeds(seeds: int | str | Iterable[int]) -> str:
    if isinstance(seeds, str):
        return seeds
    if isinstance(seeds, int):
        return str(seeds)
    return ",".join(str(int(s)) for s in seeds)


def _args(argv: list[str]):
    from keras_rl.cli import parse_args

    return parse_args(argv)


def load(folder: str | Path) -> RunSet:
    """A folder of ``seed_<n>/`` run folders."""
    return RunSet(Path(folder))


def reproduce(
    experiment: str,
    seeds: int | str | Iterable[int] = 0,
    *,
    out: str | Path,
    variant: str = "faithful",
    framework: str = "keras",
    episodes: int | None = None,
    overrides: dict[str, object] | None = None,
    workers: int = 1,
    resume: bool = False,
    progress: bool = False,
    min_success_rate: float = 0.0,
) -> Reproduced:
    """``keras-rl reproduce``: train ``seeds`` into ``out``/seed_<n>/ and return the run set."""
    argv = ["reproduce", experiment, "--seeds", _seeds(seeds), "--out", str(out), "--variant", variant]
    argv += ["--framework", framework, "--workers", str(workers), "--min-success-rate", str(min_success_rate)]
    argv += [] if episodes is None else ["--episodes", str(episodes)]
    argv += [a for k, v in (overrides or {}).items() for a in ("--set", f"{k}={v}")]
    argv += (["--resume"] if resume else []) + ([] if progress else ["--no-progress"])
    from keras_rl.commands.reproduce import reproduce as run_reproduce

    return Reproduced(RunSet(Path(out)), run_reproduce(_args(argv)))


def compare(
    experiment: str,
    seeds: int | str | Iterable[int],
    *,
    runs: str | Path = "results",
    out: str | Path,
    matched_init: bool = False,
    reuse_only: bool = True,
    workers: int = 1,
):
    """``keras-rl compare``: the Keras and PyTorch runs of ``seeds`` under ``runs`` (made where
    missing unless ``reuse_only``), reported under ``out``; returns the ``CompareResult``
    (``.verdict``, ``.result`` with every number, ``.out_dir``)."""
    from keras_rl.commands.compare import compare_result

    argv = ["compare", experiment, "--seeds", _seeds(seeds), "--runs", str(runs), "--out", str(out), "--no-progress"]
    argv += ["--workers", str(workers)] + (["--matched-init"] if matched_init else [])
    argv += ["--reuse-only"] if reuse_only else []
    return compare_result(_args(argv))


def check(experiments: Iterable[str], *, out: str | Path, tier: str = "smoke", workers: int = 1) -> list:
    """``keras-rl check``: fresh seeds against the committed baselines; each post's
    ``CheckResult`` (``.verdict``, ``.decision.p``, ``.config_changes``)."""
    from keras_rl.commands.check import check_results

    argv = ["check", *experiments, "--tier", tier, "--out", str(out), "--workers", str(workers), "--no-progress"]
    return check_results(_args(argv))
