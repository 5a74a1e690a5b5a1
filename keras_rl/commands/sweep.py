"""``keras-rl sweep``: a grid of config values x seeds, with a report per point."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_CRITERION,
    EXIT_OK,
    _stopped,
    parse_seeds,
)
from keras_rl.commands.flags import options_from_args, set_changes, shared_flags
from keras_rl.errors import ConfigError
from keras_rl.study import check_seed_batch, check_writable_dir


def add_parser(sub) -> None:
    """``sweep``'s arguments."""
    sw = sub.add_parser(
        "sweep",
        help="a grid of config values x seeds, resumable, with a report per grid point",
        description="A grid of config values x seeds, resumable, with a report per grid point. A run "
        "whose loss turns NaN is a result of its config (the report shows it, and the console names "
        "it): it does not fail the command; a run that stops with an error does (exit 1).",
        parents=[
            shared_flags(
                "sweep",
                "--workers",
                "--address",
                "--seed-batch",
                "--episodes",
                "--set",
                "--no-progress",
                "--seeds",
                "--variant",
                "--framework",
                "--out",
            )
        ],
    )
    sw.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    sw.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="FIELD=V1,V2",
        help="values of a config field to sweep (repeatable: the cross product); layer widths "
        "separate their values with ';'",
    )
    sw.add_argument(
        "--ablate",
        action="store_true",
        help="one grid point per quirk switch of the variant (that switch off, the rest at their "
        "defaults), plus the unmodified variant",
    )
    sw.add_argument("--baseline", default=None, help="the grid point the others are compared with (default: the first)")
    sw.add_argument("--yes", action="store_true", help="allow a sweep of more than 10,000 jobs")


def sweep(args: argparse.Namespace) -> int:
    from keras_rl.dispatch.sweep import ablation_grid, parse_grid, record_grid, sweep_jobs
    from keras_rl.registry import get_experiment

    if args.out is None:
        raise ConfigError("sweep needs --out FOLDER: the sweep's folder (<grid point>/seed_<n>/, sweep.md)")
    experiment = get_experiment(args.experiment)
    seeds = parse_seeds(args.seeds)
    options = options_from_args(args)
    base = experiment.config_cls.for_variant(args.variant, framework=args.framework, **options.config_changes())
    changes = set_changes(experiment.config_cls, args)
    base = base.replace(**changes)
    if args.ablate and args.grid:
        raise ConfigError("--ablate makes its own grid; drop --grid, or sweep without --ablate")
    if not args.ablate and not args.grid:
        raise ConfigError("a sweep needs --grid FIELD=V1,V2 (repeatable) or --ablate")
    points = ablation_grid(experiment.config_cls, base) if args.ablate else parse_grid(experiment.config_cls, args.grid)
    both = sorted(set(changes) & {k for p in points for k in p.overrides})
    if both:
        raise ConfigError(
            f"{', '.join(both)} given both by --set and by the {'ablation' if args.ablate else '--grid'}; "
            "the grid would silently win: give each field one way"
        )
    for point in points:  # every point must be a valid config before anything runs
        base.replace(**point.overrides)
    baseline = args.baseline or points[0].name
    if baseline not in [p.name for p in points]:
        raise ConfigError(
            f"--baseline {baseline!r} is not a grid point; the points are {', '.join(p.name for p in points)}"
        )
    check_writable_dir(args.out, "--out")
    options.check_address()
    check_seed_batch(options.seed_batch, experiment.name, args.framework)
    every, todo, configs = sweep_jobs(base, points, seeds, args.out, args.yes)
    if args.framework == "torch":
        from keras_rl.torch import require_torch

        require_torch()
    print(
        f"sweep: {len(points)} grid points x {len(seeds)} seeds = {len(every)} jobs; "
        f"{len(every) - len(todo)} already done, {len(todo)} to run"
        + (f" ({resumed} resuming from a checkpoint)" if (resumed := sum(j.start == "resume" for j in todo)) else ""),
        file=sys.stderr,
    )
    from keras_rl.dispatch.backends import train_seeds
    from keras_rl.report.plots import draw_job_curves
    from keras_rl.report.sweep import write_sweep_report
    from keras_rl.runs.provenance import command_line
    from keras_rl.runs.summary import RunSummary

    record_grid(args.out, points)
    outcome = train_seeds(todo, options, after_job=draw_job_curves)
    summaries = {
        p.name: [
            RunSummary.read(j.out_dir)
            for j in every
            if Path(j.out_dir).parent.name == p.name and (Path(j.out_dir) / "summary.json").is_file()
        ]
        for p in points
    }
    result = write_sweep_report(args.out, experiment, base, summaries, baseline, command_line())
    print(f"report: {args.out / 'sweep.md'}")
    for row in result["points"]:
        median = "n/a (no seed reached the threshold)" if row["median"] is None else f"{row['median']:g}"
        print(f"  {row['point']}: {row['successes']}/{row['seeds']} succeeded, median episodes to threshold {median}")
    if outcome.interrupted:
        print("interrupted: finished jobs are kept; run the same sweep again to resume it", file=sys.stderr)
        return _stopped()
    # a loss that turns NaN is what that config does (a finding the report shows), not a failure
    # of the command; an error is
    for name, ss in summaries.items():
        for s in ss:
            if s.status in ("non_finite_loss", "error"):
                print(f"  {name} seed {s.seed} stopped ({s.status}): {s.message}", file=sys.stderr)
    failed = [s for ss in summaries.values() for s in ss if s.status == "error"]
    missing = sorted({Path(j.out_dir).parent.name for j in every if not (Path(j.out_dir) / "summary.json").is_file()})
    if missing:
        print(f"no runs for grid point(s) {', '.join(missing)}: see the errors above", file=sys.stderr)
    return EXIT_CRITERION if failed or missing else EXIT_OK
