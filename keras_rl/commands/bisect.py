"""``keras-rl bisect``: the first commit whose check changed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_CRITERION,
    EXIT_NO_VERDICT,
    EXIT_OK,
    _stopped,
)
from keras_rl.commands.flags import shared_flags
from keras_rl.errors import ConfigError
from keras_rl.study import check_writable_dir


def add_parser(sub) -> None:
    """``bisect``'s arguments."""
    bi = sub.add_parser(
        "bisect",
        parents=[shared_flags("bisect", "--tier", "--alpha", "--against", "--out", "--workers")],
        help="find the first commit between GOOD and BAD whose learner `check` calls changed "
        "(git bisect in a temporary worktree; exit 0 found, 1 BAD consistent, 3 no verdict)",
    )
    bi.add_argument("good", help="a commit whose learner is consistent with the baseline")
    bi.add_argument("bad", help="a later commit whose learner is not")
    bi.add_argument("experiments", nargs="*", default=None, help="experiments to check (default: all three)")
    bi.add_argument(
        "--fixed-n",
        action="store_true",
        help="each step runs the fixed rule's seeds (Holm over the posts) instead of the sequential check, "
        "for commits whose check has no --sequential --alpha",
    )
    bi.add_argument("--repo", type=Path, default=Path("."), help="the git repository (default: here)")


def bisect(args: argparse.Namespace) -> int:
    from keras_rl.check.rules import CALIBRATED_TIERS, RULES, TIERS

    known = sorted({e for e, _ in RULES}, key=["pendulum", "cartpole", "mountaincar"].index)
    names = args.experiments or known
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ConfigError(f"unknown experiment {unknown[0]!r}; bisect checks {', '.join(known)}")
    if args.tier not in TIERS:
        raise ConfigError(f"unknown tier {args.tier!r}; choose one of {', '.join(TIERS)}")
    if args.tier not in CALIBRATED_TIERS and not args.fixed_n:
        raise ConfigError(
            f"bisect runs each post's calibrated sequential design, which the {args.tier} tier has none of; "
            f"choose one of {', '.join(CALIBRATED_TIERS)}, or pass --fixed-n for its fixed rule (a commit "
            "older than the tier has no such rule, and its step gives no verdict)"
        )
    if not 0 < args.alpha < 1:
        raise ConfigError(f"--alpha must lie in (0, 1), got {args.alpha}")
    if args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    check_writable_dir(args.out, "--out")  # exit 2, not one of the verdicts' exit codes
    from keras_rl.check.bisect import bisect as run_bisect
    from keras_rl.check.command import default_baselines
    from keras_rl.runs.signals import sigterm_as_interrupt

    against = (args.against if args.against is not None else default_baselines()).resolve()
    try:
        with sigterm_as_interrupt():  # SIGTERM unwinds like Ctrl-C, so the temporary worktree goes
            result = run_bisect(
                args.repo.resolve(),
                args.good,
                args.bad,
                names,
                args.tier,
                against,
                args.out.resolve(),
                args.alpha,
                ["--workers", str(args.workers), "--no-progress"],
                log=lambda line: print(line, file=sys.stderr),
                sequential=not args.fixed_n,
            )
    except KeyboardInterrupt:
        print("interrupted: no verdict", file=sys.stderr)
        return _stopped()
    print(f"report: {args.out / 'bisect.md'}")
    if result.outcome == "found":
        print(f"first changed commit: {result.first_changed}")
        return EXIT_OK
    if result.outcome == "bad is consistent":
        print(f"BAD {args.bad} is consistent with the baseline at alpha {result.alpha_per_step:.3g}: nothing to bisect")
        return EXIT_CRITERION
    among = f"; it is one of {' '.join(c[:10] for c in result.candidates)}" if result.candidates else ""
    print(f"no verdict: the checks that could run did not settle the first changed commit{among}", file=sys.stderr)
    return EXIT_NO_VERDICT
