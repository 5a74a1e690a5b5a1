"""The Python API, for notebooks: train seeds, load a run set, compare frameworks, check.

Each function takes typed inputs (a post's config object, seeds as whole numbers, paths) and
calls the library the command calls (``keras_rl/study.py``, ``check/command.run_check``): no
command line is built or parsed. Bad input raises a ``ConfigError`` that names it, before
anything is written; each returns a typed result. ``docs/api.md`` shows them.

    from keras_rl import api
    from keras_rl.posts.pendulum import PendulumDDPGConfig
    runs = api.load("results/pendulum/faithful")
    runs.episodes()                      # every episode of every seed, a DataFrame with pandas
    made = api.reproduce(PendulumDDPGConfig(tau=0.005), seeds=range(2), out="runs/tau")
    report = api.compare("pendulum", seeds=range(30), reuse_only=True, out="runs/compare")
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.config import ExperimentConfig
from keras_rl.dispatch.options import AUTO, RunOptions
from keras_rl.errors import ConfigError, argument
from keras_rl.runs.run_set import RunSet
from keras_rl.study import MIN_SUCCESS_RATE, checked_seeds

__all__ = ["Reproduced", "RunSet", "check", "compare", "load", "reproduce"]


@dataclass(frozen=True)
class Reproduced:
    """What ``reproduce`` made: the run set, each seed's summary, and the command's exit code
    (0: at least ``min_success_rate`` of the seeds succeeded, none stopped on an error)."""

    runs: RunSet
    summaries: list
    exit_code: int


def load(folder: str | Path) -> RunSet:
    """A run set: a folder of ``seed_<n>/`` run folders, or a packed ``runs.parquet``; a
    RunFolderError names a path that is neither."""
    from keras_rl.errors import RunFolderError

    if not isinstance(folder, (str, os.PathLike)):
        raise ConfigError(f"load takes a folder's path, got {folder!r}")
    path = Path(folder)
    if path.is_file():
        raise RunFolderError(f"{path} is a file, not a folder of runs; load the folder that holds it, {path.parent}")
    if not path.is_dir():
        raise RunFolderError(f"{path} is not a folder of runs (no such folder)")
    runs = RunSet(path)
    if runs.runs():
        return runs
    if any((path / name).is_file() for name in ("summary.json", "config.json")):
        raise RunFolderError(f"{path} is one seed's run folder; load the set that holds it, {path.parent}")
    raise RunFolderError(f"{path} holds no run set: no seed_<n>/summary.json and no runs.parquet")


def reproduce(
    config: str | ExperimentConfig,
    seeds: int | Iterable[int] = 0,
    *,
    out: str | Path,
    variant: str = "faithful",
    framework: str = "keras",
    overrides: Mapping[str, object] | None = None,
    episodes: int | None = None,
    engine: str = AUTO,
    workers: int = 1,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    min_success_rate: float = MIN_SUCCESS_RATE,
) -> Reproduced:
    """Train ``seeds`` of a config into ``out``/seed_<n>/ (``keras_rl.study``, as ``keras-rl
    reproduce`` does). ``config`` is a post's typed config (``PendulumDDPGConfig(tau=0.005)``),
    or an experiment's name, made from ``variant``, ``framework`` and ``overrides`` (typed
    values: ``{"actor_hidden_units": (32, 32)}``). Bad input raises a ConfigError naming it
    before anything is written."""
    from keras_rl.study import Study, check_success_rate, plan, run

    if isinstance(config, str):
        from keras_rl.registry import get_experiment

        config = get_experiment(config).config_cls.for_variant(variant, framework=framework)
    elif not isinstance(config, ExperimentConfig):
        raise ConfigError(f"config must be a post's config or an experiment's name, got {config!r}")
    changes = _overrides(overrides)
    if episodes is not None:
        changes["episodes"] = episodes
    config = config.replace(**changes)  # typed and checked, a config built directly too
    rate = check_success_rate(min_success_rate, "min_success_rate")
    for name, value in (("resume", resume), ("overwrite", overwrite), ("progress", progress)):
        _flag(value, name)
    if config.framework == "torch":  # type: ignore[attr-defined]
        from keras_rl.torch import check_torch

        check_torch()
    study = Study(
        config,
        checked_seeds(seeds),
        _path(out, "out"),
        RunOptions.checked(workers=_whole(workers), engine=engine, progress=progress),
        resume=resume,
        overwrite=overwrite,
    )
    result = run(study, plan(study))
    return Reproduced(result.runs, result.summaries, result.exit_code(len(study.seeds), rate))


RUN_PARAMETERS = {"seed": "seeds", "variant": "variant", "framework": "framework"}
"""Config fields that ``reproduce`` sets from its own parameters, so ``overrides`` may not."""


def _overrides(overrides: object) -> dict[str, object]:
    """``overrides`` as a dict of config fields, or a ConfigError naming what is not one."""
    if overrides is None:
        return {}
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides must be a mapping of config field to value, got {overrides!r}")
    for name in overrides:
        if name in RUN_PARAMETERS:
            raise ConfigError(f"overrides cannot set {name}; pass {RUN_PARAMETERS[name]}=")
    return dict(overrides)


def _flag(value: object, name: str) -> bool:
    """``True`` or ``False``, or a ConfigError: ``resume="yes"`` and ``overwrite=1`` are not switches."""
    if not isinstance(value, bool):
        raise ConfigError(f"{name} must be True or False, got {value!r}")
    return value


def _whole(value: Any) -> Any:
    """NumPy's whole numbers as Python's (``workers=np.int64(2)``); anything else as given, for
    ``RunOptions.checked`` to refuse by name."""
    return int(value) if isinstance(value, numbers.Integral) and not isinstance(value, bool) else value


def _path(value: object, name: str) -> Path:
    if not isinstance(value, (str, os.PathLike)) or not str(value).strip():
        raise ConfigError(f"{name} must be a folder's path, got {value!r}")
    return Path(value)


def compare(
    experiment: str,
    seeds: int | Iterable[int],
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
    from keras_rl.study import compare_frameworks

    return compare_frameworks(
        _name(experiment),
        checked_seeds(seeds),
        RunOptions.checked(workers=_whole(workers), progress=False),
        runs=_path(runs, "runs"),
        out=_path(out, "out"),
        matched_init=_flag(matched_init, "matched_init"),
        reuse_only=_flag(reuse_only, "reuse_only"),
    )


def check(
    experiments: str | Iterable[str] = ("pendulum", "cartpole", "mountaincar"),
    *,
    out: str | Path,
    tier: str = "smoke",
    workers: int = 1,
    against: str | Path | None = None,
    framework: str = "keras",
) -> list:
    """``keras-rl check``: fresh seeds against the committed baselines (or ``against``); each
    post's ``CheckResult`` (``.verdict``, ``.decision.p``, ``.config_changes``). ``framework="torch"``:
    the PyTorch rules (``rules.TORCH_RULES``), for the posts that have one."""
    from keras_rl.check.command import check_request, default_baselines, run_check

    names = [experiments] if isinstance(experiments, str) else [_name(e) for e in experiments]
    check_request(names, tier, framework)
    out_path = _path(out, "out")
    from keras_rl.study import check_writable_dir

    check_writable_dir(out_path, argument("out"))
    baselines = default_baselines() if against is None else _path(against, "against")
    options = RunOptions.checked(workers=_whole(workers), progress=False)
    return run_check(names, tier, baselines, out_path, None, options, framework=framework)


def _name(experiment: object) -> str:
    if not isinstance(experiment, str):
        raise ConfigError(f"an experiment is named by a string (see keras-rl list), got {experiment!r}")
    return experiment
