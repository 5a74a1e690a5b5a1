"""``keras-rl reproduce``: train one experiment over seeds into run folders."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_CRITERION,
    EXIT_OK,
    _check_engine,
    _check_not_inside_a_run,
    _check_seed_batch,
    _check_writable_dir,
    _recorded_config,
    _stopped,
    parse_seeds,
)
from keras_rl.errors import ConfigError
from keras_rl.runs.lifecycle import _kept_runs, _start_modes
from keras_rl.runs.options import RUN_FLAGS, RunOptions, path_arg, shared_flags
from keras_rl.runs.packed import refuse_packed


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
        default=1.0,
        help="exit 0 only if at least this share of seeds succeed (default 1.0: all)",
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


def _set_suffix(config_cls, assignments: tuple[str, ...]) -> str:
    """``-set-broadcast_target=false,tau=0.005`` for a default folder of a modified config,
    named from the parsed values (``tau=5e-3`` and ``tau=0.005`` name one folder)."""
    from keras_rl.config import overrides_name

    return "-set-" + overrides_name(config_cls.parse_assignments(assignments)).replace("/", "_")


def reproduce(args: argparse.Namespace) -> int:
    # Every check that can fail on the user's input runs before TensorFlow is imported.
    from keras_rl.registry import get_experiment
    from keras_rl.runs.files import run_folder

    experiment = get_experiment(args.experiment)
    recorded = _recorded_config(experiment, args) if args.config is not None else None
    seeds = parse_seeds(args.seeds if args.seeds is not None else str(recorded.seed) if recorded else "0")
    args.variant = recorded.variant if recorded else args.variant or "faithful"
    args.framework = recorded.framework if recorded else args.framework or "keras"
    args.matched_init = recorded.matched_init if recorded else args.matched_init
    options = RunOptions.from_args(args)
    if args.checkpoint_every < 0:
        raise ConfigError(f"--checkpoint-every must be zero or more, got {args.checkpoint_every}")
    if args.eval_every < 0:
        raise ConfigError(f"--eval-every must be zero (no evaluations) or more, got {args.eval_every}")
    from keras_rl.runs.evaluate import EvalSchedule

    if args.eval_episodes is not None and not args.eval_every:
        raise ConfigError("--eval-episodes sets the size of each --eval-every evaluation; give --eval-every N too")
    eval_episodes = 10 if args.eval_episodes is None else args.eval_episodes
    evaluation = EvalSchedule(args.eval_every, eval_episodes) if args.eval_every else None
    if not 0 <= args.min_success_rate <= 1:
        raise ConfigError(f"--min-success-rate must be in [0, 1], got {args.min_success_rate}")
    if recorded is not None:
        base = recorded.replace(**options.config_changes()).with_text_overrides(options.overrides)
    else:
        base = experiment.config_cls.for_variant(
            args.variant, framework=args.framework, matched_init=args.matched_init, **options.config_changes()
        ).with_text_overrides(options.overrides)
    if args.framework == "torch":
        from keras_rl.torch import require_torch

        require_torch()
    out = args.out
    if out is None:
        out = run_folder(Path("results"), experiment.name, args.variant, args.framework, args.matched_init)
        if options.overrides:  # a modified config never lands in the variant's own folder
            out = out.with_name(out.name + _set_suffix(experiment.config_cls, options.overrides))
    _check_not_inside_a_run(out)
    _check_writable_dir(out, "--out")
    if args.tensorboard is not None:
        _check_writable_dir(args.tensorboard, "--tensorboard")
    seed_dirs = [out / f"seed_{s}" for s in seeds]
    for seed_dir in seed_dirs:
        refuse_packed(seed_dir)
    if evaluation is not None and getattr(base, "learning_phase_training", False):
        raise ConfigError(
            "--eval-every does not cover learning_phase_training=true: its noise layer draws from "
            "TensorFlow's generator when the policy acts, which would change the training run"
        )
    if not args.overwrite:
        from keras_rl.runs.reuse import made_by_experiment

        for seed_dir in seed_dirs:
            made_by = made_by_experiment(seed_dir)
            if made_by is not None and made_by != experiment.name:
                raise ConfigError(
                    f"{seed_dir} holds a run made by {made_by}, not {experiment.name}; it is left as it "
                    "is: pass --out for another folder"
                )
    modes = _start_modes(seed_dirs, args.overwrite, args.resume, base.episodes)
    options.check_address()  # now that the input is good: is the cluster there?
    _check_seed_batch(options.seed_batch, experiment.name, args.framework)
    _check_engine(options.engine, experiment, base)
    if args.dry_run:
        import json

        print(json.dumps({k: v for k, v in base.to_dict().items() if k != "seed"}, indent=2, sort_keys=True))
        how = {
            "new": "new",
            "overwrite": "cleared, then new",
            "resume": "resumed from its checkpoint",
            "keep": "completed, kept",
        }
        for s, d, m in zip(seeds, seed_dirs, modes):
            print(f"seed {s}: {d} ({how[m]})")
        return EXIT_OK

    from keras_rl.report.aggregate import write_aggregate
    from keras_rl.report.plots import draw_job_curves
    from keras_rl.runs.backends import train_seeds
    from keras_rl.runs.jobs import SeedJob

    kept = _kept_runs(base, [(s, d) for s, d, m in zip(seeds, seed_dirs, modes) if m == "keep"])
    outcome = train_seeds(
        [
            SeedJob.of(
                base.replace(seed=s),
                d,
                start=m,
                checkpoint_every=args.checkpoint_every,
                tensorboard=args.tensorboard,
                evaluation=evaluation,
                engine=options.engine,
            )
            for s, d, m in zip(seeds, seed_dirs, modes)
            if m != "keep"
        ],
        options,
        after_job=draw_job_curves,
    )
    summaries = sorted(kept + outcome.summaries, key=lambda s: seeds.index(s.seed))
    failures = [s for s in summaries if s.status in ("non_finite_loss", "error")]
    for s in failures:
        print(f"error: seed {s.seed}: {s.message}", file=sys.stderr)
    # a seed whose worker raised before its folder held a summary (the error was printed as it
    # happened) has no verdict: it fails the command whatever --min-success-rate says
    unsaid = [] if outcome.interrupted else sorted(set(seeds) - {s.seed for s in summaries})
    if summaries and len(seeds) > 1:
        write_aggregate(
            out,
            summaries,
            base.threshold,
            f"{experiment.name} ({args.variant}, {args.framework}), {len(summaries)} seeds",
            experiment.metric_label(base),
            experiment.post_reference,
        )
    for s in summaries:
        verdict = "PASS" if s.success else "FAIL" if s.status == "completed" else "no verdict"
        where = f"reached at episode {s.reached_at_episode}" if s.reached_at_episode else "not reached"
        seed_dir = out / f"seed_{s.seed}"
        files = ", ".join(sorted(p.name for p in seed_dir.iterdir() if not p.name.startswith(".")))
        print(
            f"{experiment.name}/{args.variant}/{args.framework} seed {s.seed}: {s.status}, {verdict} "
            f"({s.criterion}: {where}; {s.episodes_run} episodes, {s.total_steps} steps, {s.wall_seconds:.1f} s)"
            f"\n  {seed_dir}/: {files}"
        )
    if summaries and len(seeds) > 1:
        print(f"all seeds: {out / 'summary.md'} and {out / 'curves.png'}")
    if args.tensorboard is not None:
        print(f"TensorBoard: tensorboard --logdir {args.tensorboard}")
    if experiment.post_reference:
        print(experiment.post_reference)
    if outcome.interrupted:
        print("interrupted: partial results are on disk, marked unfinished; --resume continues them", file=sys.stderr)
        return _stopped()
    if failures or unsaid:
        print(
            f"exit 1: {len(failures) + len(unsaid)} of {len(seeds)} seeds stopped with an error"
            + (f" (seeds {', '.join(map(str, unsaid))} left no summary.json)" if unsaid else ""),
            file=sys.stderr,
        )
        return EXIT_CRITERION
    successes = sum(s.success for s in summaries)
    if successes / len(seeds) >= args.min_success_rate:
        return EXIT_OK
    print(
        f"exit 1: criterion not met: {successes}/{len(seeds)} seeds succeeded, need "
        f"{args.min_success_rate:.0%} (--min-success-rate {args.min_success_rate:g})",
        file=sys.stderr,
    )
    return EXIT_CRITERION
