"""``keras-rl compare``: the same seeds in Keras and PyTorch, and what differs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_OK,
    _check_writable_dir,
    _stopped,
    parse_seeds,
)
from keras_rl.errors import ConfigError
from keras_rl.runs.options import RunOptions, shared_flags


def add_parser(sub) -> None:
    """``compare``'s arguments."""
    cp = sub.add_parser(
        "compare",
        help="run or reuse the same seeds in Keras and PyTorch and report the difference",
        parents=[
            shared_flags(
                "compare",
                "--workers",
                "--address",
                "--seed-batch",
                "--episodes",
                "--no-progress",
                "--seeds",
                "--variant",
                "--matched-init",
                "--out",
            )
        ],
    )
    cp.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    cp.add_argument("--runs", type=Path, default=Path("results"), help="where run folders are found and made")
    cp.add_argument("--rerun", action="store_true", help="replace existing run folders instead of reusing them")
    cp.add_argument("--reuse-only", action="store_true", help="run nothing; fail if a seed is missing")


def compare(args: argparse.Namespace) -> int:
    try:
        result = compare_result(args)
    except KeyboardInterrupt:
        print(
            "interrupted: the runs so far are on disk; run compare again to reuse them and resume the rest",
            file=sys.stderr,
        )
        return _stopped()
    print(f"report: {result.out_dir / 'report.md'}")
    print(result.verdict)
    return EXIT_OK


def compare_result(args: argparse.Namespace):
    """``compare``'s work (``api.compare`` too): the runs made or reused, the report written;
    its ``CompareResult``. KeyboardInterrupt when a signal stopped the runs."""
    if args.rerun and args.reuse_only:
        raise ConfigError(
            "--rerun and --reuse-only contradict each other (one reruns every seed, the other runs none); pick one"
        )
    seeds = parse_seeds(args.seeds)
    options = RunOptions.from_args(args)
    _check_writable_dir(args.out, "--out")  # before any training
    if not args.reuse_only:
        _check_writable_dir(args.runs, "--runs")
    options.check_address()
    from keras_rl.learners.table import RETIRED, compared_frameworks, no_stacked_learner
    from keras_rl.registry import get_experiment

    experiment = get_experiment(args.experiment)
    compared = compared_frameworks(experiment.name)  # a clear error where there is nothing to compare
    if options.seed_batch == "auto" or int(options.seed_batch) > 1:
        alone = [framework for framework in compared if no_stacked_learner(experiment.name, framework)]
        if alone:  # reproduce refuses --seed-batch there; compare batches what it can, and says so
            why = "".join(
                f" ({fw}: {RETIRED[(experiment.name, fw)]})" for fw in alone if (experiment.name, fw) in RETIRED
            )
            print(
                f"warning: --seed-batch {options.seed_batch}: {experiment.name} in {', '.join(alone)} has no "
                f"seed-batched version, so its seeds run alone{why}",
                file=sys.stderr,
            )
    from keras_rl.report.compare import compare as write_compare
    from keras_rl.report.plots import draw_job_curves
    from keras_rl.runs.compare_runs import make_compare_runs
    from keras_rl.runs.provenance import command_line
    from keras_rl.torch import require_torch

    require_torch()
    make_compare_runs(
        experiment,
        args.variant,
        seeds,
        options,
        runs_root=args.runs,
        rerun=args.rerun,
        reuse_only=args.reuse_only,
        matched_init=args.matched_init,
        after_job=draw_job_curves,
    )
    return write_compare(
        experiment.name,
        seeds,
        variant=args.variant,
        runs_root=args.runs,
        out_root=args.out,
        matched_init=args.matched_init,
        episodes=options.episodes,
        command=command_line(),
        workers=options.workers,
    )
