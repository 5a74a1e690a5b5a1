"""The runs ``keras-rl compare`` needs: the same seeds in each framework the experiment has
(``learners/table.frameworks``), reused where a folder holds a finished run of the same
config and code version, made where not (``report/compare.py`` then reads and reports them).

A folder made with another config or code version is never silently merged: the command
refuses and says which field differs (``--rerun`` replaces such folders). An interrupted run
of the same config and code version resumes from its checkpoint, as ``reproduce --resume``
would resume it (a batch with its whole batch); one without a checkpoint starts again.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from keras_rl.dispatch.backends import train_seeds
from keras_rl.dispatch.jobs import AfterJob, SeedJob
from keras_rl.dispatch.options import RunOptions
from keras_rl.errors import RunFolderError, argument
from keras_rl.experiment import Experiment
from keras_rl.learners.table import compared_frameworks
from keras_rl.runs.files import run_folder
from keras_rl.runs.lifecycle import UNRECORDED_ENGINE
from keras_rl.runs.provenance import code_version
from keras_rl.runs.reuse import check_reusable, start_of


def framework_overrides(framework: str, matched_init: bool) -> dict[str, Any]:
    return {"framework": framework, "matched_init": matched_init and framework == "torch"}


def gather(
    experiment: Experiment,
    variant: str,
    seeds: list[int],
    runs_root: Path,
    rerun: bool,
    reuse_only: bool,
    overrides: dict[str, Any],
    matched_init: bool = False,
) -> list[SeedJob]:
    """The jobs still to run for each framework (the rest are reused)."""
    jobs: list[SeedJob] = []
    missing: dict[str, list[int]] = {}
    compared = compared_frameworks(experiment.name)
    for framework in compared:
        base = experiment.config_cls.for_variant(variant, **framework_overrides(framework, matched_init), **overrides)
        folder = run_folder(runs_root, experiment.name, variant, framework, matched_init)
        engine = arm_engine(folder, seeds if rerun else ())
        for seed in seeds:
            config = base.replace(seed=seed)
            seed_dir = folder / f"seed_{seed}"
            # a report of existing runs trains nothing, so it mixes no code versions: it names them
            why = None if rerun else check_reusable(seed_dir, config, None if reuse_only else code_version())
            if rerun or why is not None:
                start = "overwrite" if rerun else start_of(seed_dir, why)
                jobs.append(SeedJob.of(config, seed_dir, start=start, engine=engine))
                missing.setdefault(framework, []).append(seed)
    if reuse_only and missing:
        have = {fw: sorted(set(seeds) - set(missing.get(fw, []))) for fw in compared}
        raise RunFolderError(
            f"mismatched seed sets: {', '.join(f'{fw} lacks seeds {s}' for fw, s in missing.items())} "
            f"(reusable: {have}); run without {argument('reuse_only')} to make them"
        )
    return jobs


def arm_engine(folder: Path, rerun: list[int] | tuple[int, ...] = ()) -> str:
    """The engine an arm's missing seeds train on: that of the runs its folder already holds (a
    set stays on the engine it started on, as ``reproduce``'s does), else the Gymnasium loop, on
    which every committed comparison was made."""
    from keras_rl.runs.lifecycle import set_engine

    return set_engine(folder, [folder / f"seed_{s}" for s in rerun]) or UNRECORDED_ENGINE


def make_compare_runs(
    experiment: Experiment,
    variant: str,
    seeds: list[int],
    options: RunOptions,
    runs_root: Path,
    rerun: bool,
    reuse_only: bool,
    matched_init: bool,
    after_job: AfterJob | None = None,
) -> None:
    """Run (S seeds at a time, on ``options``' backend) what ``gather`` finds missing.
    Raises KeyboardInterrupt when Ctrl-C stopped the runs (what finished is on disk)."""
    jobs = gather(experiment, variant, seeds, runs_root, rerun, reuse_only, options.config_changes(), matched_init)
    import sys

    for framework in compared_frameworks(experiment.name):
        folder = run_folder(runs_root, experiment.name, variant, framework, matched_init)
        made = sorted(j.config.seed for j in jobs if j.config.framework == framework)
        reused = len(seeds) - len(made)
        engines = {j.engine for j in jobs if j.config.framework == framework}
        to_run = (
            f"training {len(made)} ({', '.join(map(str, made[:10]))}{', ...' if len(made) > 10 else ''}) "
            f"on the {' and '.join(sorted(engines))} engine"
        )
        print(f"{framework}: {folder}: {reused} of {len(seeds)} seeds reused, {to_run if made else 'none to train'}",
              file=sys.stderr)  # fmt: skip
    if train_seeds(jobs, options, after_job=after_job).interrupted:
        raise KeyboardInterrupt
