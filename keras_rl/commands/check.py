"""``keras-rl check``: fresh seeds against the committed baselines."""

from __future__ import annotations

import argparse
import sys

from keras_rl.commands.common import (
    EXIT_CRITERION,
    EXIT_NO_VERDICT,
    EXIT_OK,
    _stopped,
    parse_seeds,
)
from keras_rl.commands.flags import options_from_args, set_changes, shared_flags
from keras_rl.errors import ConfigError, KerasRLError, NoVerdictError
from keras_rl.study import check_writable_dir


def add_parser(sub) -> None:
    """``check``'s arguments."""
    ck = sub.add_parser(
        "check",
        help="regression-test the reproductions: fresh seeds against the committed "
        "baseline, by each post's pre-registered rule (exit 0 consistent, 1 changed)",
        parents=[
            shared_flags(
                "check",
                "--workers",
                "--address",
                "--set",
                "--no-progress",
                "--tier",
                "--against",
                "--seeds",
                "--alpha",
                "--dry-run",
                "--out",
                "--framework",
            )
        ],
    )
    ck.add_argument(
        "experiments", nargs="*", default=None, help="experiments to check (default: pendulum cartpole mountaincar)"
    )
    ck.add_argument(
        "--sequential",
        action="store_true",
        help="fresh seeds in looks of 5 up to 30 per post, each post stopping where its calibrated "
        "design decides (results/checks/sequential.md: fewer seeds under a clear change, more under none)",
    )


def check(args: argparse.Namespace) -> int:
    try:
        results = check_results(args)
    except KeyboardInterrupt:
        print("interrupted: no verdict", file=sys.stderr)
        return _stopped()
    except NoVerdictError as exc:  # neither "consistent" nor "changed"
        print(f"error: no verdict: {exc}", file=sys.stderr)
        return EXIT_NO_VERDICT
    except KerasRLError:  # the user's input (a RunFolderError is an OSError too): exit 2, from main
        raise
    except OSError as exc:  # a full disk or a vanished folder mid-check: no verdict either
        print(f"error: no verdict: {exc}", file=sys.stderr)
        return EXIT_NO_VERDICT
    if args.dry_run:
        return EXIT_OK
    for r in results:
        level = f"alpha {r.rule.alpha}" if r.design is None else f"sequential, efficacy {r.design['efficacy']:.3g}"
        print(
            f"{r.experiment}: {r.verdict} ({r.rule.statistic}, {r.decision.test}, p = {r.decision.p:.3g}, "
            f"{level}; baseline {len(r.baseline)} seeds, new {len(r.new)})"
        )
        if r.twins is not None:
            print(f"  twins: {r.twins.text()}")
        if r.fallback is not None:
            print(f"  {r.fallback}")
        if r.baseline_note is not None:
            print(f"  {r.baseline_note}")
        elif not r.decision.changed:
            from keras_rl.check.command import what_it_sees

            print(f"  what it can see: {what_it_sees(r.rule)}")
        if r.config_changes:
            print(f"  {r.experiment}: the faithful config differs from the baseline's: {'; '.join(r.config_changes)}")
    from keras_rl.check.command import environment_lines

    for line in environment_lines(results):
        if line:
            print(f"  {line}".replace("`", ""))
    print(f"report: {args.out / 'check.md'}")
    return EXIT_CRITERION if any(r.decision.changed for r in results) else EXIT_OK


def check_results(args: argparse.Namespace) -> list:
    """``check``'s work (``api.check`` too): each post's ``CheckResult``, the report written."""
    from keras_rl.check.command import check_request
    from keras_rl.check.rules import rules_of

    known = rules_of(args.framework or "keras")
    names = args.experiments or sorted({e for e, _ in known}, key=["pendulum", "cartpole", "mountaincar"].index)
    framework = args.framework or "keras"
    check_request(names, args.tier, framework)
    if args.sequential and args.tier == "sensitive":
        raise ConfigError(
            "the sensitive tier has no sequential design: its fresh seeds were sized by a power computation "
            "(results/checks/sensitive_plan.md); run it without --sequential"
        )
    if args.sequential and framework == "torch":
        raise ConfigError(
            "--framework torch has no sequential design: sequential.json's designs were calibrated on the Keras "
            "baselines; run it without --sequential"
        )
    if args.sequential and args.seeds is not None:
        raise ConfigError("--seeds and --sequential do not go together: the sequential design runs its own fresh seeds")
    if args.alpha is not None and not args.sequential:
        raise ConfigError(
            "--alpha goes with --sequential: the fixed rule's alpha is pre-registered (keras_rl/check/rules.py)"
        )
    if args.alpha is not None and not 0 < args.alpha < 1:
        raise ConfigError(f"--alpha must lie in (0, 1), got {args.alpha}")
    seeds = parse_seeds(args.seeds) if args.seeds is not None else None
    options = options_from_args(args)
    from keras_rl.registry import get_experiment

    overrides = {name: set_changes(get_experiment(name).config_cls, args) for name in names}
    check_writable_dir(args.out, "--out")  # bad input (exit 2), found before any training
    options.check_address()
    from keras_rl.check.command import default_baselines, run_check

    against = args.against if args.against is not None else default_baselines()
    return run_check(
        names,
        args.tier,
        against,
        args.out,
        seeds,
        options,
        sequential=args.sequential,
        sequential_alpha=args.alpha,
        dry_run=args.dry_run,
        framework=framework,
        overrides=overrides,
    )
