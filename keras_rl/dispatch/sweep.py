"""``keras-rl sweep``: the cross product of a grid of config values and seeds, as jobs.

A grid point is a set of field overrides on top of the variant (and ``--set``); its folder
name is made from them (``tau=0.005``, ``broadcast_target=false,tau=0.005``; ``base`` for
the unmodified variant), with one ``seed_<n>/`` per seed inside. A seed folder that already
holds a completed run of the same config and code version is skipped, so running the same
sweep again finishes in seconds and an interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.config import BASE, point_name, value_text
from keras_rl.dispatch.jobs import SeedJob
from keras_rl.errors import ConfigError, RunFolderError, argument
from keras_rl.runs.provenance import code_version
from keras_rl.runs.reuse import check_reusable, start_of

MAX_JOBS_WITHOUT_YES = 10_000


@dataclass(frozen=True)
class GridPoint:
    name: str
    overrides: dict[str, Any]


def parse_grid(config_cls, items: list[str]) -> list[GridPoint]:
    """``["tau=0.001,0.005", "gamma=0.9,0.99"]`` -> the cross product, each value parsed by
    its field's type (``config.parse_assignments``; a ConfigError names a bad field or value)."""
    axes = config_cls.parse_assignments(items, flag=argument("grid"), many=True)
    for name, parsed in axes.items():
        repeated = sorted({value_text(v) for v in parsed if parsed.count(v) > 1})
        if repeated:  # 0.1, 0.10 and 1e-1 are one grid point: as three they would count its seeds thrice
            raise ConfigError(
                f"{argument('grid')} {name}= gives {name}={' and '.join(repeated)} more than once (values are "
                "compared after parsing); give each value once"
            )
    points = [dict(zip(axes, combo)) for combo in itertools.product(*axes.values())]
    return [GridPoint(point_name(p), p) for p in points]


def ablation_grid(config_cls, base) -> list[GridPoint]:
    """The unmodified variant, then each quirk switch turned off alone (``QUIRKS``)."""
    points = [GridPoint(BASE, {})]
    for field_name, (_ledger_id, off) in config_cls.QUIRKS.items():
        if getattr(base, field_name) != off:
            points.append(GridPoint(point_name({field_name: off}), {field_name: off}))
    if len(points) == 1:
        raise ConfigError(
            f"the {base.variant} variant of {config_cls.experiment} has no quirk switch left on to ablate"
        )
    return points


def sweep_jobs(
    base, points: list[GridPoint], seeds: list[int], out: Path, yes: bool = False, **job_options: Any
) -> tuple[list[SeedJob], list[SeedJob], dict[str, Any]]:
    """(every job of the sweep, the ones still to run, each point's config) for the grid
    points on top of ``base``; refuses a folder made by another config or code version."""
    total = len(points) * len(seeds)
    if total > MAX_JOBS_WITHOUT_YES and not yes:
        raise ConfigError(
            f"this sweep has {total} jobs ({len(points)} grid points x {len(seeds)} seeds), more than "
            f"{MAX_JOBS_WITHOUT_YES}; pass {argument('yes')} if you mean it"
        )
    version = code_version()
    every, todo, configs = [], [], {}
    for point in points:
        config = base.replace(**point.overrides)
        configs[point.name] = config
        for seed in seeds:
            seed_dir = Path(out) / point.name / f"seed_{seed}"
            try:
                reason = check_reusable(seed_dir, config.replace(seed=seed), version)
            except RunFolderError as exc:
                raise RunFolderError(
                    f"{exc} (this sweep's folder {out} holds runs of another sweep or code version: use "
                    f"another {argument('out')})"
                ) from None
            job = SeedJob.of(config.replace(seed=seed), seed_dir, start=start_of(seed_dir, reason), **job_options)
            every.append(job)
            if reason is not None:
                todo.append(job)
    return every, todo, configs


def record_grid(out: Path, points: list[GridPoint]) -> None:
    """``grid.json``: the points in order (the first is the baseline unless one is named)."""
    from keras_rl.atomic import atomic_write_json

    atomic_write_json(Path(out) / "grid.json", [{"name": p.name, "overrides": p.overrides} for p in points])
