"""``keras-rl``: reproduce a post over seeds, compare frameworks, or evaluate a saved run.

    keras-rl reproduce pendulum --variant faithful --seeds 0-9 --workers 2 --out results/pendulum
    keras-rl compare pendulum --seeds 0-9 --workers 2
    keras-rl evaluate results/pendulum/faithful/seed_0 --episodes 5 --gif pendulum.gif
    keras-rl aggregate results/pendulum/faithful
    keras-rl list
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from keras_rl import __version__
from keras_rl.errors import ConfigError, KerasRLError

EXIT_OK, EXIT_CRITERION, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def parse_seeds(text: str) -> list[int]:
    """``"0-9"``, ``"1,3,5"``, ``"0-2,7"`` -> a sorted list of distinct seeds."""
    seeds: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        lo_text, dash, hi_text = part.partition("-") if "-" in part[1:] else (part, "", part)
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise ConfigError(f"cannot read seeds {text!r}: use a list like 0,1,2 or a range like 0-9") from None
        if lo > hi:
            raise ConfigError(f"seed range {part!r} runs backwards; write {hi}-{lo}")
        if hi >= 2**32:
            raise ConfigError(f"seeds must be below 2**32 (NumPy's and Gymnasium's limit), got {hi}")
        seeds.update(range(lo, hi + 1))
    if not seeds:
        raise ConfigError(f"no seeds in {text!r}")
    if min(seeds) < 0:
        raise ConfigError(f"seeds must be zero or more, got {min(seeds)}")
    return sorted(seeds)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="keras-rl", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"keras-rl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    rep = sub.add_parser("reproduce", help="train one experiment over one or more seeds")
    rep.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    rep.add_argument("--variant", default="faithful",
                     help="faithful (the post's code as it ran), fixed, or another of the experiment's variants "
                          "(`keras-rl list`; mountaincar also has faithful-intended)")
    rep.add_argument("--framework", default="keras", help="keras (ours) or torch (where the experiment has one)")
    rep.add_argument("--matched-init", action="store_true",
                     help="torch only: start from the Keras networks' initial weights for the same seed")
    rep.add_argument("--seeds", default="0", help="seed list or range: 13, 0-9, 0,3,5 (default 0)")
    rep.add_argument("--episodes", type=int, default=None, help="episode budget (default: the post's)")
    rep.add_argument("--out", type=Path, default=None,
                     help="output folder (default results/<experiment>/<variant>); one seed_<n>/ per seed")
    rep.add_argument("--workers", type=int, default=1, help="processes for several seeds (default 1)")
    rep.add_argument("--set", dest="overrides", action="append", default=[], metavar="FIELD=VALUE",
                     help="override a config field, e.g. --set tau=0.005 (repeatable)")
    rep.add_argument("--min-success-rate", type=float, default=1.0,
                     help="exit 0 only if at least this share of seeds succeed (default 1.0: all)")
    rep.add_argument("--no-progress", action="store_true", help="no progress bars")

    ev = sub.add_parser("evaluate", help="reload a run's saved policy and play greedy episodes")
    ev.add_argument("run_dir", type=Path, help="a seed's run folder, e.g. results/pendulum/faithful/seed_0 "
                                               "(weights are not committed: reproduce the seed first)")
    ev.add_argument("--episodes", type=int, default=5, help="greedy episodes to play (default 5)")
    ev.add_argument("--seed", type=int, default=None, help="env seed (default: the run's seed + 10000)")
    ev.add_argument("--gif", type=Path, default=None, help="record the first episode to this GIF")

    cp = sub.add_parser("compare", help="run or reuse the same seeds in Keras and PyTorch and report the difference")
    cp.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    cp.add_argument("--seeds", default="0-9", help="seed list or range, the same for both frameworks (default 0-9)")
    cp.add_argument("--variant", default="faithful", help="the variant to compare (default faithful)")
    cp.add_argument("--matched-init", action="store_true",
                    help="torch runs start from the Keras runs' initial weights (report in <out>/<experiment>/matched-init)")
    cp.add_argument("--workers", type=int, default=1, help="processes for the runs still to make (default 1)")
    cp.add_argument("--episodes", type=int, default=None, help="episode budget (default: the post's)")
    cp.add_argument("--runs", type=Path, default=Path("results"), help="where run folders are found and made")
    cp.add_argument("--out", type=Path, default=Path("results/compare"), help="report folder root")
    cp.add_argument("--rerun", action="store_true", help="replace existing run folders instead of reusing them")
    cp.add_argument("--reuse-only", action="store_true", help="run nothing; fail if a seed is missing")
    cp.add_argument("--no-progress", action="store_true", help="no progress bars")

    ag = sub.add_parser("aggregate", help="rebuild summary.md and curves.png of a multi-seed folder")
    ag.add_argument("parent", type=Path, help="a folder of seed_<n>/ run folders, e.g. results/pendulum/faithful")

    sub.add_parser("list", help="list the experiments and their variants")
    return parser


def _check_counts(workers: int, episodes: int | None) -> None:
    if workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    if episodes is not None and episodes <= 0:
        raise ConfigError(f"--episodes must be positive, got {episodes}")


def reproduce(args: argparse.Namespace) -> int:
    from keras_rl.registry import get_experiment
    from keras_rl.report.aggregate import write_aggregate
    from keras_rl.runs.files import run_folder
    from keras_rl.runs.jobs import SeedJob, backend_for, run_jobs

    experiment = get_experiment(args.experiment)
    seeds = parse_seeds(args.seeds)
    _check_counts(args.workers, args.episodes)
    if not 0 <= args.min_success_rate <= 1:
        raise ConfigError(f"--min-success-rate must be in [0, 1], got {args.min_success_rate}")
    overrides = {"framework": args.framework, "matched_init": args.matched_init}
    if args.episodes is not None:
        overrides["episodes"] = args.episodes
    base = experiment.config_cls.for_variant(args.variant, **overrides).with_text_overrides(args.overrides)
    if args.framework == "torch":
        from keras_rl.torch import require_torch

        require_torch()
    out = args.out or run_folder(Path("results"), experiment.name, args.variant, args.framework, args.matched_init)
    jobs = [SeedJob.of(base.replace(seed=s), out / f"seed_{s}") for s in seeds]
    outcome = run_jobs(jobs, backend_for(args.workers, len(jobs)), progress=not args.no_progress)
    summaries = outcome.summaries
    failures = [s for s in summaries if s.status in ("non_finite_loss", "error")]
    for s in failures:
        print(f"error: seed {s.seed}: {s.message}", file=sys.stderr)
    if summaries and len(seeds) > 1:
        write_aggregate(out, summaries, base.threshold, f"{experiment.name} ({args.variant}, {args.framework}), "
                        f"{len(summaries)} seeds", experiment.metric_label(base), experiment.post_reference)
    for s in summaries:
        where = f"episode {s.reached_at_episode}" if s.success else "not reached"
        print(f"{experiment.name}/{args.variant}/{args.framework} seed {s.seed}: {s.status}, threshold {where} "
              f"({s.episodes_run} episodes, {s.total_steps} steps, {s.wall_seconds:.1f} s) -> {out}")
    if outcome.interrupted:
        print("interrupted: partial results are on disk, marked unfinished", file=sys.stderr)
        return EXIT_INTERRUPTED
    if failures:
        return EXIT_CRITERION
    rate = sum(s.success for s in summaries) / len(seeds)
    return EXIT_OK if rate >= args.min_success_rate else EXIT_CRITERION


def evaluate(args: argparse.Namespace) -> int:
    from keras_rl.runs.evaluate import evaluate_run

    result = evaluate_run(args.run_dir, episodes=args.episodes, gif=args.gif, seed=args.seed, progress=True)
    print(f"mean score over {result['episodes']} greedy episodes: {result['mean']:.2f} "
          f"(std {result['std']:.2f})" + (f"; GIF: {result['gif']}" if "gif" in result else ""))
    return EXIT_OK


def compare(args: argparse.Namespace) -> int:
    from keras_rl.report.compare import compare as run_compare
    from keras_rl.runs.provenance import command_line

    _check_counts(args.workers, args.episodes)
    try:
        result = run_compare(args.experiment, parse_seeds(args.seeds), args.variant, args.workers, args.runs,
                             args.out, args.rerun, args.reuse_only, args.episodes, not args.no_progress,
                             command_line(), args.matched_init)
    except KeyboardInterrupt:
        print("interrupted: the runs so far are on disk; run compare again to reuse them", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(f"report: {result.out_dir / 'report.md'}")
    print(result.verdict)
    return EXIT_OK


def aggregate(args: argparse.Namespace) -> int:
    from keras_rl.report.aggregate import rebuild

    stats = rebuild(args.parent)
    print(f"{args.parent}/summary.md: {stats['successes']}/{stats['seeds']} seeds succeeded")
    return EXIT_OK


def list_experiments(args: argparse.Namespace) -> int:
    from keras_rl.learners.table import frameworks
    from keras_rl.registry import EXPERIMENTS

    for name, exp in sorted(EXPERIMENTS.items()):
        print(f"{name:12s} {exp.description}; variants: {', '.join(exp.config_cls.VARIANTS)}; "
              f"frameworks: {', '.join(frameworks(name))}")
    return EXIT_OK


COMMANDS = {"reproduce": reproduce, "evaluate": evaluate, "compare": compare, "aggregate": aggregate,
            "list": list_experiments}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except KerasRLError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
