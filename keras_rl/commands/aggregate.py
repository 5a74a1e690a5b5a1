"""``keras-rl aggregate`` and ``keras-rl list``."""

from __future__ import annotations

import argparse
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_OK,
)


def add_parser(sub) -> None:
    """``aggregate``'s arguments."""
    ag = sub.add_parser("aggregate", help="rebuild summary.md and curves.png of a multi-seed folder")
    ag.add_argument("parent", type=Path, help="a folder of seed_<n>/ run folders, e.g. results/pendulum/faithful")
    ag.add_argument(
        "--x-axis",
        choices=("episode", "steps"),
        default="episode",
        help="what each seed's curve.png counts along x: episodes (default) or env steps",
    )


def add_list_parser(sub) -> None:
    """``list [EXPERIMENT]``."""
    p = sub.add_parser(
        "list",
        help="list the experiments and their variants; with an experiment, every config field it takes",
    )
    p.add_argument(
        "experiment",
        nargs="?",
        default=None,
        help="list this experiment's config fields: type, default, range and the post's line each cites "
        "(what --set FIELD=VALUE takes)",
    )


def aggregate(args: argparse.Namespace) -> int:
    from keras_rl.report.aggregate import rebuild

    stats = rebuild(args.parent, x_axis=args.x_axis)
    print(f"{args.parent}/summary.md: {stats['successes']}/{stats['seeds']} seeds succeeded")
    return EXIT_OK


def list_experiments(args: argparse.Namespace) -> int:
    from keras_rl.learners.table import STACKED, frameworks
    from keras_rl.registry import EXPERIMENTS, get_experiment

    if getattr(args, "experiment", None) is not None:
        from keras_rl.config import describe_fields

        experiment = get_experiment(args.experiment)
        variants = ", ".join(experiment.config_cls.VARIANTS)
        print(f"{experiment.name}: every field of its config (--set FIELD=VALUE; variants: {variants})")
        for row in describe_fields(experiment.config_cls):
            allowed = f", {row['range']}" if row["range"] else ""
            print(f"  {row['field']}: {row['type']} = {row['default']}{allowed}")
            if row["post"]:
                print(f"      {row['post']}")
        return EXIT_OK

    for name, exp in sorted(EXPERIMENTS.items()):
        batching = [fw for fw in frameworks(name) if (name, fw) in STACKED]
        print(
            f"{name:12s} {exp.description}; variants: {', '.join(exp.config_cls.VARIANTS)}; "
            f"frameworks: {', '.join(frameworks(name))}; --seed-batch: {', '.join(batching) or 'none'}"
        )
    return EXIT_OK
