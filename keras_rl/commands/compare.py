"""``keras-rl compare``: the same seeds in Keras and PyTorch, and what differs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_OK,
    _stopped,
    parse_seeds,
)
from keras_rl.commands.flags import options_from_args, shared_flags


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
    print(f"report: {result.out_dir / 'report.md'} (and result.json, curves.png, episodes_to_threshold.png)")
    print(result.verdict.replace("**", ""))  # the report's Markdown emphasis, not the terminal's
    return EXIT_OK


def compare_result(args: argparse.Namespace):
    """``compare``'s work (``api.compare`` too): the runs made or reused, the report written;
    its ``CompareResult``. KeyboardInterrupt when a signal stopped the runs."""
    from keras_rl.study import compare_frameworks

    options = options_from_args(args)
    return compare_frameworks(
        args.experiment,
        parse_seeds(args.seeds),
        options,
        runs=args.runs,
        out=args.out,
        variant=args.variant,
        matched_init=args.matched_init,
        rerun=args.rerun,
        reuse_only=args.reuse_only,
    )
