"""``keras-rl reproduce``: train one experiment over seeds into run folders."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_OK,
    _recorded_config,
    parse_seeds,
)
from keras_rl.commands.flags import RUN_FLAGS, options_from_args, path_arg, set_changes, shared_flags
from keras_rl.errors import ConfigError
from keras_rl.study import MIN_SUCCESS_RATE


def add_parser(sub) -> None:
    """``reproduce``'s arguments."""
    rep = sub.add_parser(
        "reproduce",
        help="train one experiment over one or more seeds",
        parents=[
            shared_flags(
                "reproduce",
                *RUN_FLAGS,
                "--seeds",
                "--variant",
                "--framework",
                "--matched-init",
                "--out",
                "--overwrite",
                "--dry-run",
            )
        ],
    )
    rep.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    rep.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="RUN/config.json",
        help="rerun a recorded run: its config.json gives every field (its seed too, unless --seeds "
        "is given); --set and --episodes still apply on top",
    )
    rep.add_argument(
        "--min-success-rate",
        type=float,
        default=MIN_SUCCESS_RATE,
        help=f"exit 0 only if at least this share of seeds succeed (default {MIN_SUCCESS_RATE:g}; 1 is every seed)",
    )
    rep.add_argument(
        "--resume",
        action="store_true",
        help="continue interrupted or killed runs from their checkpoint.pkl, keeping seeds that already "
        "completed (same options as before)",
    )
    rep.add_argument(
        "--checkpoint-every",
        type=int,
        default=10,
        metavar="N",
        help="write checkpoint.pkl every N episodes, and when stopped (default 10; 0: only when stopped)",
    )
    rep.add_argument(
        "--tensorboard",
        type=path_arg,
        default=None,
        metavar="DIR",
        help="also log per-episode score, metric and losses as TensorBoard scalars under DIR",
    )
    rep.add_argument(
        "--eval-every",
        type=int,
        default=0,
        metavar="N",
        help="every N training episodes, play --eval-episodes greedy episodes on an env of their own, "
        "leaving training as it is (evaluations.csv; the best mean's weights in best/); default 0: none",
    )
    rep.add_argument(
        "--eval-episodes",
        type=int,
        default=None,
        metavar="K",
        help="greedy episodes per evaluation of --eval-every (default 10; only with --eval-every)",
    )


def _set_suffix(changes: dict) -> str:
    """``-set-broadcast_target=false,tau=0.005`` for a default folder of a modified config,
    named from the parsed values (``tau=5e-3`` and ``tau=0.005`` name one folder)."""
    from keras_rl.config import overrides_name

    return "-set-" + overrides_name(changes).replace("/", "_")


def reproduce(args: argparse.Namespace) -> int:
    """The command: its argv into a typed ``Study`` (``keras_rl/study.py``), planned, run, reported."""
    from keras_rl.study import START_WORDS, plan, run

    study = study_from_args(args)
    planned = plan(study)
    if args.dry_run:
        import json

        config = study.config.to_dict()  # type: ignore[attr-defined]
        print(json.dumps({k: v for k, v in config.items() if k != "seed"}, indent=2, sort_keys=True))
        print(f"engine: {planned.engine} ({planned.engine_why})")
        for s, d, m in zip(study.seeds, study.seed_dirs(), planned.modes):
            print(f"seed {s}: {d} ({START_WORDS[m]})")
        return EXIT_OK
    from keras_rl.report.plots import draw_job_curves

    if study.options.engine != planned.engine:  # chosen by --engine auto: say which, and why
        print(f"engine: {planned.engine} ({planned.engine_why})", file=sys.stderr)
    result = run(study, planned, after_job=draw_job_curves)
    return report(study, result, args.min_success_rate)


def study_from_args(args: argparse.Namespace):
    """The ``Study`` the command line asks for; every check that can fail on the user's input runs
    here or in ``study.plan``, before TensorFlow is imported."""
    from keras_rl.registry import get_experiment
    from keras_rl.runs.evaluate import EvalSchedule
    from keras_rl.runs.files import run_folder
    from keras_rl.study import Study, check_success_rate

    experiment = get_experiment(args.experiment)
    recorded, recorded_engine = _recorded_config(experiment, args) if args.config is not None else (None, None)
    seeds = parse_seeds(args.seeds if args.seeds is not None else str(recorded.seed) if recorded else "0")
    variant = recorded.variant if recorded else args.variant or "faithful"
    framework = recorded.framework if recorded else args.framework or "keras"
    matched_init = recorded.matched_init if recorded else args.matched_init
    options = options_from_args(args)
    if args.eval_every < 0:
        raise ConfigError(f"--eval-every must be zero (no evaluations) or more, got {args.eval_every}")
    if args.eval_episodes is not None and not args.eval_every:
        raise ConfigError("--eval-episodes sets the size of each --eval-every evaluation; give --eval-every N too")
    eval_episodes = 10 if args.eval_episodes is None else args.eval_episodes
    evaluation = EvalSchedule(args.eval_every, eval_episodes) if args.eval_every else None
    check_success_rate(args.min_success_rate)
    changes = set_changes(experiment.config_cls, args)
    if recorded is not None:
        base = recorded.replace(**options.config_changes()).replace(**changes)
    else:
        base = experiment.config_cls.for_variant(
            variant, framework=framework, matched_init=matched_init, **options.config_changes()
        ).replace(**changes)
    if framework == "torch":
        from keras_rl.torch import check_torch

        check_torch()
    out = args.out
    if out is None:
        out = run_folder(Path("results"), experiment.name, variant, framework, matched_init)
        if changes:  # a modified config never lands in the variant's own folder
            out = out.with_name(out.name + _set_suffix(changes))
    return Study(
        base,
        tuple(seeds),
        out,
        options,
        resume=args.resume,
        overwrite=args.overwrite,
        checkpoint_every=args.checkpoint_every,
        tensorboard=args.tensorboard,
        evaluation=evaluation,
        recorded_engine=recorded_engine,
    )


def _reached_text(s, judged_at_end: bool) -> str:
    """Where a seed met its threshold, in words: for a post judged at the end (post 001), the first
    episode that met it is not the verdict, the last episode's metric is."""
    if not judged_at_end:
        return f"reached at episode {s.reached_at_episode}" if s.reached_at_episode else "not reached"
    final = "none" if s.final_metric is None else f"{s.final_metric:.3g}"
    first = f"first met at episode {s.reached_at_episode}" if s.reached_at_episode else "never met"
    return f"judged on the last episode's metric, {final}; {first}"


def report(study, result, min_success_rate: float) -> int:
    """Each seed's line, where the files are, and the exit code: 0 where at least
    ``min_success_rate`` of the seeds succeeded and none stopped on an error."""
    experiment, base, out, seeds = study.experiment, study.config, study.out, study.seeds
    for s in result.failures:
        print(f"error: seed {s.seed}: {s.message}", file=sys.stderr)
    for s in result.summaries:
        verdict = "PASS" if s.success else "FAIL" if s.status == "completed" else "no verdict"
        where = _reached_text(s, experiment.success_at_end)
        seed_dir = out / f"seed_{s.seed}"
        files = ", ".join(sorted(p.name for p in seed_dir.iterdir() if not p.name.startswith(".")))
        print(
            f"{experiment.name}/{base.variant}/{base.framework} seed {s.seed}: {s.status}, {verdict} "
            f"({s.criterion}: {where}; {s.episodes_run} episodes, {s.total_steps} steps, {s.wall_seconds:.1f} s)"
            f"\n  {seed_dir}/: {files}"
        )
    if result.summaries and len(seeds) > 1:
        print(f"all seeds: {out / 'summary.md'} and {out / 'curves.png'}")
    if study.tensorboard is not None:
        print(f"TensorBoard: tensorboard --logdir {study.tensorboard}")
    if experiment.post_reference:
        print(experiment.post_reference)
    if result.interrupted:
        print("interrupted: partial results are on disk, marked unfinished; --resume continues them", file=sys.stderr)
    elif result.failures or result.unsaid:
        print(
            f"exit 1: {len(result.failures) + len(result.unsaid)} of {len(seeds)} seeds stopped with an error"
            + (f" (seeds {', '.join(map(str, result.unsaid))} left no summary.json)" if result.unsaid else ""),
            file=sys.stderr,
        )
    elif result.successes / len(seeds) < min_success_rate:
        print(
            f"exit 1: criterion not met: {result.successes}/{len(seeds)} seeds succeeded, need "
            f"{min_success_rate:.0%} (--min-success-rate {min_success_rate:g})",
            file=sys.stderr,
        )
    return result.exit_code(len(seeds), min_success_rate)
