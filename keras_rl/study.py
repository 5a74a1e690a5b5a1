"""A study: one typed config over seeds into a folder, on an engine. The library under
``keras-rl reproduce`` and ``api.reproduce``: both build a ``Study`` (the command from its
argv, a notebook from a config object) and call ``plan`` and ``run``; nothing here reads or
builds a command line.

    from keras_rl.posts.pendulum import PendulumDDPGConfig
    from keras_rl.study import Study, plan, run

    study = Study(PendulumDDPGConfig(tau=0.005), seeds=(0, 1), out=Path("runs/p"))
    planned = plan(study)                 # a StudyPlan: .modes, .engine (auto resolved), .engine_why
    result = run(study, planned)          # a StudyResult: .runs, .summaries, .successes
"""

from __future__ import annotations

import numbers
import os
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from keras_rl.dispatch.options import RunOptions
from keras_rl.errors import ConfigError, argument
from keras_rl.runs.run_set import RunSet
from keras_rl.train.engine import VECTORISED

MAX_SEEDS = 10_000
"""The most seeds one study trains."""

START_WORDS = {
    "new": "new",
    "overwrite": "cleared, then new",
    "resume": "resumed from its checkpoint",
    "keep": "completed, kept",
}
"""How each seed of a plan starts, in words."""


def checked_seeds(seeds: int | Iterable[int]) -> tuple[int, ...]:
    """Whole numbers in [0, 2**32), distinct, at most ``MAX_SEEDS``: as given (``3``, ``range(10)``,
    ``[0, 5]``, NumPy integers too), or a ConfigError that names the one that is not."""
    items: object = [seeds] if isinstance(seeds, numbers.Integral) and not isinstance(seeds, bool) else seeds
    if isinstance(items, Mapping):  # its keys would pass for seeds
        raise ConfigError(f"seeds must be a whole number or several (a list, a range), not a mapping: got {seeds!r}")
    if isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
        raise ConfigError(f"seeds must be a whole number or several, got {seeds!r}")
    out: list[int] = []
    for s in items:
        if isinstance(s, bool) or not isinstance(s, numbers.Integral):
            raise ConfigError(f"seeds must be whole numbers, got {s!r}")
        if not 0 <= int(s) < 2**32:
            raise ConfigError(f"seeds must be in [0, 2**32), got {s}")
        if int(s) in out:
            raise ConfigError(f"seed {s} is named twice")
        out.append(int(s))
        if len(out) > MAX_SEEDS:
            raise ConfigError(f"more than {MAX_SEEDS} seeds; split the study into smaller ones")
    if not out:
        raise ConfigError("no seeds given")
    return tuple(sorted(out))


@dataclass(frozen=True)
class Study:
    """What to train: ``config`` (every field but the seed) for each of ``seeds``, one
    ``seed_<n>/`` folder each under ``out``, the way ``options`` says (engine, workers, progress)."""

    config: object
    """A post's typed config (``PendulumDDPGConfig``, ...); its ``seed`` is each seed's."""
    seeds: tuple[int, ...]
    out: Path
    options: RunOptions = field(default_factory=RunOptions)
    resume: bool = False
    """Continue interrupted runs from their checkpoints, keep completed ones."""
    overwrite: bool = False
    """Clear a seed folder that already holds a run, whole, and run it again."""
    checkpoint_every: int = 10
    tensorboard: Path | None = None
    evaluation: object | None = None
    """An ``EvalSchedule``: greedy episodes during training, or None."""
    recorded_engine: str | None = None
    """The engine that made the run ``config`` was read from (``reproduce --config``), which
    ``--engine auto`` reruns it on; None for a config made here."""

    def __post_init__(self) -> None:
        from keras_rl.config import ExperimentConfig

        if not isinstance(self.config, ExperimentConfig):
            raise ConfigError(f"a study's config is a post's config object, got {type(self.config).__name__}")
        object.__setattr__(self, "seeds", checked_seeds(self.seeds))
        if not isinstance(self.out, (str, os.PathLike)):
            raise ConfigError(f"{argument('out')} must be a folder's path, got {self.out!r}")
        object.__setattr__(self, "out", Path(self.out))
        if isinstance(self.checkpoint_every, bool) or not isinstance(self.checkpoint_every, int):
            raise ConfigError(f"{argument('checkpoint_every')} must be a whole number, got {self.checkpoint_every!r}")
        if self.checkpoint_every < 0:
            raise ConfigError(f"{argument('checkpoint_every')} must be zero or more, got {self.checkpoint_every}")
        if self.evaluation is not None and getattr(self.config, "learning_phase_training", False):
            raise ConfigError(
                f"{argument('eval_every')} does not cover learning_phase_training=true: its noise layer draws from "
                "TensorFlow's generator when the policy acts, which would change the training run"
            )

    @property
    def experiment(self):
        from keras_rl.registry import get_experiment

        return get_experiment(self.config.experiment)  # type: ignore[attr-defined]

    def seed_dirs(self) -> list[Path]:
        return [self.out / f"seed_{s}" for s in self.seeds]


@dataclass(frozen=True)
class StudyPlan:
    """What ``plan`` found: how each seed starts, and the engine that trains them, with why that one."""

    modes: list[str]
    """Each seed's start, in seed order: ``new``, ``overwrite``, ``resume`` or ``keep`` (``START_WORDS``)."""
    engine: str
    """One of ``train/engine.ENGINES``: never ``auto``."""
    engine_why: str
    """Why that engine, in words (``choose_engine``)."""


def plan(study: Study) -> StudyPlan:
    """How each seed starts (``new``, ``overwrite``, ``resume`` or ``keep``) and on which engine,
    after every check of the study against the disk and the engine: a ConfigError (or
    RunFolderError) names the first problem, before anything is written or TensorFlow is loaded."""
    from keras_rl.runs.lifecycle import _start_modes, check_keepable, check_resumable
    from keras_rl.runs.packed import refuse_packed

    experiment, config = study.experiment, study.config
    from keras_rl.envs import check_env_id

    env_id = getattr(config, "env_id", None)  # a post registered from outside may build its env otherwise
    if env_id is not None:
        check_env_id(env_id)  # a bad id is named before any folder is made
    check_not_inside_a_run(study.out)
    check_writable_dir(study.out, argument("out"))
    for seed_dir in study.seed_dirs():  # a seed folder that cannot be written, named before TensorFlow loads
        if seed_dir.is_dir():
            check_writable_dir(seed_dir, argument("out"))
    if study.tensorboard is not None:
        check_writable_dir(study.tensorboard, argument("tensorboard"))
    for seed_dir in study.seed_dirs():
        refuse_packed(seed_dir)
    check_one_kind(study)
    if not study.overwrite:
        from keras_rl.runs.reuse import made_by_experiment

        for seed_dir in study.seed_dirs():
            made_by = made_by_experiment(seed_dir)
            if made_by is not None and made_by != experiment.name:
                raise ConfigError(
                    f"{seed_dir} holds a run made by {made_by}, not {experiment.name}; it is left as it "
                    f"is: pass {argument('out')} for another folder"
                )
    modes = _start_modes(study.seed_dirs(), study.overwrite, study.resume, config.episodes)  # type: ignore[attr-defined]
    study.options.check_address()  # now that the input is good: is the cluster there?
    engine, why = choose_engine(study, modes)
    check_seed_batch(study.options.seed_batch, experiment.name, config.framework, engine)  # type: ignore[attr-defined]
    check_engine(engine, experiment, config)
    # what the run would refuse of the folders it keeps or resumes, refused here (a dry run too)
    triples = list(zip(study.seeds, study.seed_dirs(), modes))
    check_keepable(config, [(s, d) for s, d, m in triples if m == "keep"])
    check_resumable([(s, d) for s, d, m in triples if m == "resume"], engine)
    return StudyPlan(modes, engine, why)


def check_one_kind(study: Study) -> None:
    """A set holds one experiment, variant and framework (``aggregate`` refuses a folder that mixes
    them, and its ``summary.md`` would name only one): a ConfigError, before anything is written,
    where ``out`` already holds runs of another kind, whichever seeds they are (issue 72 item 2)."""
    from keras_rl.runs.run_set import RunSet

    if not study.out.is_dir():
        return
    c = study.config
    mine = (c.experiment, c.variant, c.framework)  # type: ignore[attr-defined]
    others = {k: seeds for k, seeds in RunSet(study.out).kinds().items() if k != mine}
    if others:
        (experiment, variant, framework), seeds = next(iter(others.items()))
        shown = ", ".join(map(str, seeds[:5])) + (f" and {len(seeds) - 5} more" if len(seeds) > 5 else "")
        raise ConfigError(
            f"{study.out} holds runs of {experiment} ({variant}, {framework}), seeds {shown}; this is "
            f"{mine[0]} ({mine[1]}, {mine[2]}), and a set holds one experiment, variant and framework: "
            f"pass {argument('out')} for another folder"
        )


def choose_engine(study: Study, modes: list[str]) -> tuple[str, str]:
    """The engine that trains ``study`` and why, for ``--engine auto`` (issue 54, item 11): a
    recorded run replays on the engine that made it, so that no committed command changes what it
    makes. In order: the engine asked for; the engine of ``--config``'s run; the engine of the runs
    already in ``out`` that stay (a set keeps the engine it was started on); else the compiled
    engine where it is certified (``compiled_scope.CERTIFIED``) and can run the config alone;
    else the Gymnasium loop."""
    from keras_rl.dispatch.options import AUTO
    from keras_rl.runs.lifecycle import set_engine

    asked = study.options.engine
    if asked != AUTO:
        return asked, argument("engine", asked)
    if study.recorded_engine is not None:
        return study.recorded_engine, f"the engine that made {argument('config')}'s run"
    leaving = [d for d, m in zip(study.seed_dirs(), modes) if m == "overwrite"]
    held = set_engine(study.out, leaving)
    if held is not None:
        return held, f"the engine of the runs already in {study.out} (a set stays on the engine it started on)"
    from keras_rl.train.compiled_scope import CERTIFIED, refusal

    experiment, framework = study.experiment.name, study.config.framework  # type: ignore[attr-defined]
    if (experiment, framework) not in CERTIFIED:
        return "gymnasium", f"the compiled engine is not certified for {experiment} in {framework}"
    if study.options.seed_batch != 1:
        return "gymnasium", f"{argument('seed_batch', study.options.seed_batch)} batches seeds on the Gymnasium loop"
    why_not = refusal(experiment, study.config)
    if why_not is not None:
        return "gymnasium", f"the compiled engine cannot run this config: {why_not}"
    return "compiled", f"certified for {experiment} in {framework}: {CERTIFIED[(experiment, framework)]}"


@dataclass
class StudyResult:
    """What a study left: its run set, each seed's summary (in seed order), and how it ended."""

    runs: RunSet
    summaries: list
    interrupted: bool
    failures: list
    """Seeds that stopped on a non-finite loss or an error (their summaries)."""
    unsaid: list[int]
    """Seeds whose worker raised before their folder held a summary."""

    @property
    def successes(self) -> int:
        return sum(s.success for s in self.summaries)

    def exit_code(self, seeds: int, min_success_rate: float) -> int:
        """The study's verdict as ``reproduce`` exits: a signal's code where one stopped it, 1 where a
        seed stopped on an error or fewer than ``min_success_rate`` of the ``seeds`` succeeded, else 0."""
        if self.interrupted:
            from keras_rl.runs.signals import stop_exit_code

            return stop_exit_code()
        return 1 if self.failures or self.unsaid or self.successes / seeds < min_success_rate else 0


MIN_SUCCESS_RATE = 1.0
"""The share of seeds that must succeed for a study to exit 0, unless told otherwise: all of them.
``api.reproduce``'s ``min_success_rate`` defaults to it, as the command's does (``test_api``)."""


def check_success_rate(rate: object, name: str = "min_success_rate") -> float:
    """A share of seeds in [0, 1], or a ConfigError naming the argument ``name``."""
    name = argument(name)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)):
        raise ConfigError(f"{name} must be a number in [0, 1], got {rate!r}")
    if not 0 <= rate <= 1:
        raise ConfigError(f"{name} must be in [0, 1], got {rate}")
    return float(rate)


def run(study: Study, planned: StudyPlan, after_job=None) -> StudyResult:
    """Train what ``plan`` found to do (each seed's mode, on its engine), keep what it found
    done, and write the set's ``summary.md`` and ``curves.png`` where there are several seeds."""
    from keras_rl.dispatch.backends import train_seeds
    from keras_rl.dispatch.jobs import SeedJob
    from keras_rl.report.aggregate import write_aggregate
    from keras_rl.runs.lifecycle import _kept_runs

    experiment, base, seeds = study.experiment, study.config, list(study.seeds)
    triples = list(zip(seeds, study.seed_dirs(), planned.modes))
    kept = _kept_runs(base, [(s, d) for s, d, m in triples if m == "keep"])
    outcome = train_seeds(
        [
            SeedJob.of(
                base.replace(seed=s),  # type: ignore[attr-defined]
                d,
                start=m,
                checkpoint_every=study.checkpoint_every,
                tensorboard=study.tensorboard,
                evaluation=study.evaluation,
                engine=planned.engine,
            )
            for s, d, m in triples
            if m != "keep"
        ],
        study.options,
        after_job=after_job,
    )
    summaries = sorted(kept + outcome.summaries, key=lambda s: seeds.index(s.seed))
    failures = [s for s in summaries if s.status in ("non_finite_loss", "error")]
    # a seed whose worker raised before its folder held a summary (the error was printed as it
    # happened) has no verdict: it fails the study whatever success rate is asked for
    unsaid = [] if outcome.interrupted else sorted(set(seeds) - {s.seed for s in summaries})
    if summaries and len(seeds) > 1:
        write_aggregate(
            study.out,
            summaries,
            base.threshold,  # type: ignore[attr-defined]
            f"{experiment.name} ({base.variant}, {base.framework}), {len(summaries)} seeds",  # type: ignore[attr-defined]
            experiment.metric_label(base),
            experiment.post_reference,
        )
    return StudyResult(RunSet(study.out), summaries, outcome.interrupted, failures, unsaid)


def compare_frameworks(
    experiment: str,
    seeds: Iterable[int],
    options: RunOptions,
    *,
    runs: Path,
    out: Path,
    variant: str = "faithful",
    matched_init: bool = False,
    rerun: bool = False,
    reuse_only: bool = False,
):
    """The same seeds of ``experiment`` in each framework it has (``keras-rl compare`` and
    ``api.compare``): runs under ``runs`` made where missing (reused where they hold a finished run
    of the same config and code version; none made with ``reuse_only``), the report under ``out``;
    its ``CompareResult``. KeyboardInterrupt when a signal stopped the runs."""
    import sys

    if rerun and reuse_only:
        raise ConfigError(
            f"{argument('rerun')} and {argument('reuse_only')} contradict each other (one reruns every seed, "
            "the other runs none); pick one"
        )
    seed_list = list(checked_seeds(seeds))
    runs, out = Path(runs), Path(out)
    check_writable_dir(out, argument("out"))  # before any training
    if not reuse_only:
        check_writable_dir(runs, argument("runs"))
    options.check_address()
    from keras_rl.learners.table import RETIRED, compared_frameworks, no_stacked_learner
    from keras_rl.registry import get_experiment

    exp = get_experiment(experiment)
    compared = compared_frameworks(exp.name)  # a clear error where there is nothing to compare
    if options.seed_batch == "auto" or int(options.seed_batch) > 1:
        alone = [framework for framework in compared if no_stacked_learner(exp.name, framework)]
        if alone:  # reproduce refuses --seed-batch there; compare batches what it can, and says so
            why = "".join(f" ({fw}: {RETIRED[(exp.name, fw)]})" for fw in alone if (exp.name, fw) in RETIRED)
            print(
                f"warning: {argument('seed_batch', options.seed_batch)}: {exp.name} in {', '.join(alone)} has no "
                f"seed-batched version, so its seeds run alone{why}",
                file=sys.stderr,
            )
    from keras_rl.dispatch.compare_runs import make_compare_runs
    from keras_rl.report.compare import compare as write_compare
    from keras_rl.report.plots import draw_job_curves
    from keras_rl.runs.provenance import command_line
    from keras_rl.torch import require_torch

    require_torch()
    make_compare_runs(
        exp,
        variant,
        seed_list,
        options,
        runs_root=runs,
        rerun=rerun,
        reuse_only=reuse_only,
        matched_init=matched_init,
        after_job=draw_job_curves,
    )
    return write_compare(
        exp.name,
        seed_list,
        variant=variant,
        runs_root=runs,
        out_root=out,
        matched_init=matched_init,
        episodes=options.episodes,
        command=command_line(),
        workers=options.workers,
    )


# -- the checks a study makes of its input ----------------------------------------------------------


def check_writable_dir(path: Path, flag: str) -> None:
    """A folder that exists and is writable, or can be made: else a ConfigError naming it as
    ``flag`` says it (``argument("out")``): a name longer than the file system takes, a symlink
    loop, a file, no write permission."""
    path = Path(path)
    for part in path.parts:
        if len(os.fsencode(part)) > 255:
            raise ConfigError(
                f"{flag}: the folder name {part[:40]}... is {len(os.fsencode(part))} bytes, more than the 255 a "
                f"file system takes; pass {flag} with a shorter name"
            )
    try:
        path.resolve(strict=False)
    except (RuntimeError, OSError) as exc:  # Python 3.11 raises RuntimeError on a loop
        raise ConfigError(f"{flag} {path} is a symlink loop ({exc}); name another folder") from None
    if path.is_symlink() and not path.exists():
        raise ConfigError(f"{flag} {path} is a symlink to nothing ({os.readlink(path)}); name another folder")
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{flag} {path} is a file, not a folder")
    probe = path
    while not probe.exists():
        probe = probe.parent
    try:  # really write (root passes os.access everywhere, /proc included)
        if not probe.is_dir():
            raise OSError("not a folder")
        fd, name = tempfile.mkstemp(dir=probe, prefix=".keras-rl-probe-")
        os.close(fd)
        os.unlink(name)
    except OSError:
        raise ConfigError(f"{flag} {path}: {probe} is not a writable folder") from None


def check_not_inside_a_run(out: Path) -> None:
    """``out`` names the folder that holds ``seed_<n>/`` folders: one inside a run folder
    would nest runs in a run."""
    for folder in (out, *out.parents):
        if folder.name.startswith("seed_") and (folder / "config.json").is_file():
            raise ConfigError(
                f"{argument('out', out)} is inside the run folder {folder}; name the folder that holds the "
                "seed_<n>/ folders (its parent), or another one"
            )


def check_engine(engine: str, experiment, config) -> None:
    """A clear error before anything runs where ``engine`` cannot run ``config``."""
    if engine == "gymnasium":
        return
    # each engine's refusal imports neither TensorFlow nor torch: refused before they load
    if engine == "compiled":
        from keras_rl.train.compiled_scope import refusal
    elif engine in VECTORISED:
        from keras_rl.train.vectorised import refusal
    else:
        raise ConfigError(f"unknown engine {engine!r}")
    why = refusal(experiment.name, config)
    if why is not None:
        raise ConfigError(f"{argument('engine', engine)}: {why}")


def check_seed_batch(seed_batch: int | str, experiment: str, framework: str, engine: str = "gymnasium") -> None:
    """A seed batch (S > 1): a clear error before anything runs when it cannot apply (``auto``
    runs seeds alone where nothing batches). The vectorised engine batches whatever it runs
    (``check_engine`` says what that is)."""
    if engine in VECTORISED:
        return
    if seed_batch != "auto" and int(seed_batch) > 1:
        from keras_rl.learners.table import stacked_implementation

        stacked_implementation(experiment, framework)  # a clear error if there is none
