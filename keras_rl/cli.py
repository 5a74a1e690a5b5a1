"""``keras-rl``: reproduce a post over seeds, or evaluate a saved run.

    keras-rl reproduce pendulum --variant faithful --seeds 0-9 --workers 2 --out results/pendulum
    keras-rl evaluate results/pendulum/faithful/seed_0 --episodes 5 --gif pendulum.gif
    keras-rl aggregate results/pendulum/faithful
    keras-rl list
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import signal
import sys
from pathlib import Path
from typing import Any, Sequence

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
        seeds.update(range(lo, hi + 1))
    if not seeds:
        raise ConfigError(f"no seeds in {text!r}")
    if min(seeds) < 0:
        raise ConfigError(f"seeds must be zero or more, got {min(seeds)}")
    return sorted(seeds)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="keras-rl", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    rep = sub.add_parser("reproduce", help="train one experiment over one or more seeds")
    rep.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    rep.add_argument("--variant", default="faithful", help="faithful (the post's code as it ran) or fixed")
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
    ev.add_argument("run_dir", type=Path, help="a seed's run folder, e.g. results/pendulum/faithful/seed_0")
    ev.add_argument("--episodes", type=int, default=5)
    ev.add_argument("--seed", type=int, default=None, help="env seed (default: the run's seed + 10000)")
    ev.add_argument("--gif", type=Path, default=None, help="record the first episode to this GIF")

    cp = sub.add_parser("compare", help="run or reuse the same seeds in Keras and PyTorch and report the difference")
    cp.add_argument("experiment")
    cp.add_argument("--seeds", default="0-9")
    cp.add_argument("--variant", default="faithful")
    cp.add_argument("--matched-init", action="store_true",
                    help="torch runs start from the Keras runs' initial weights (report in <out>/<experiment>/matched-init)")
    cp.add_argument("--workers", type=int, default=1)
    cp.add_argument("--episodes", type=int, default=None, help="episode budget (default: the post's)")
    cp.add_argument("--runs", type=Path, default=Path("results"), help="where run folders are found and made")
    cp.add_argument("--out", type=Path, default=Path("results/compare"), help="report folder root")
    cp.add_argument("--rerun", action="store_true", help="replace existing run folders instead of reusing them")
    cp.add_argument("--reuse-only", action="store_true", help="run nothing; fail if a seed is missing")
    cp.add_argument("--no-progress", action="store_true")

    ag = sub.add_parser("aggregate", help="rebuild summary.md and curves.png of a multi-seed folder")
    ag.add_argument("parent", type=Path, help="a folder of seed_<n>/ run folders, e.g. results/pendulum/faithful")

    sub.add_parser("list", help="list the experiments and their variants")
    return parser


def _run_one(args: tuple[str, dict[str, Any], str, bool, int]) -> dict[str, Any]:
    """Worker entry point (module level so that spawn can pickle it)."""
    from keras_rl.experiments import get_experiment
    from keras_rl.loop import run_seed

    name, config_dict, out_dir, progress, position = args
    experiment = get_experiment(name)
    config = experiment.config_cls.from_dict(config_dict)
    return run_seed(experiment, config, Path(out_dir), progress=progress, position=position)


def _worker(job: tuple[str, dict[str, Any], str, bool, int]) -> None:
    if _run_one(job)["status"] == "interrupted":
        raise SystemExit(EXIT_INTERRUPTED)


def _run_in_processes(jobs: list, workers: int) -> bool:
    """Run seeds in at most ``workers`` spawned processes; True if Ctrl-C stopped them.

    Each seed writes its own folder, so results are read back from disk. On Ctrl-C no
    further seed starts; running seeds get SIGINT (a terminal sends it to them as well),
    write their partial results, and are waited for.
    """
    ctx = multiprocessing.get_context("spawn")  # TensorFlow is not fork-safe
    pending, running, interrupted = list(jobs), [], False
    try:
        while pending or running:
            while pending and len(running) < workers:
                proc = ctx.Process(target=_worker, args=(pending.pop(0),))
                proc.start()
                running.append(proc)
            running[0].join(timeout=0.5)
            for proc in [p for p in running if not p.is_alive()]:
                running.remove(proc)
                if proc.exitcode == EXIT_INTERRUPTED:
                    interrupted, pending = True, []
    except KeyboardInterrupt:
        interrupted = True
    if interrupted:
        # A terminal's Ctrl-C reached the workers too; give them a moment to flush, and
        # interrupt only those that did not hear it (SIGINT sent to this process alone).
        try:
            for proc in running:
                proc.join(timeout=2.0)
        except KeyboardInterrupt:
            pass
        for proc in running:
            if proc.is_alive():
                os.kill(proc.pid, signal.SIGINT)
        for proc in running:
            while proc.is_alive():
                try:
                    proc.join()
                except KeyboardInterrupt:  # a second Ctrl-C while the seeds flush: keep waiting
                    pass
    return interrupted


def reproduce(args: argparse.Namespace) -> int:
    from keras_rl.aggregate import write_aggregate
    from keras_rl.experiments import get_experiment, metric_label

    experiment = get_experiment(args.experiment)
    seeds = parse_seeds(args.seeds)
    if args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if not 0 <= args.min_success_rate <= 1:
        raise ConfigError(f"--min-success-rate must be in [0, 1], got {args.min_success_rate}")
    overrides = {"framework": args.framework, "matched_init": args.matched_init}
    if args.episodes is not None:
        overrides["episodes"] = args.episodes
    if args.episodes is not None and args.episodes <= 0:
        raise ConfigError(f"--episodes must be positive, got {args.episodes}")
    base = experiment.config_cls.for_variant(args.variant, **overrides).with_text_overrides(args.overrides)
    if args.framework == "torch":
        from keras_rl.torch import require_torch

        require_torch()
    from keras_rl.compare import run_folder

    out = args.out or run_folder(Path("results"), experiment.name, args.variant, args.framework, args.matched_init)
    jobs = [(experiment.name, base.replace(seed=s).to_dict(), str(out / f"seed_{s}"),
             not args.no_progress, i % args.workers) for i, s in enumerate(seeds)]

    if args.workers == 1 or len(seeds) == 1:
        interrupted = False
        try:
            for job in jobs:
                if _run_one(job)["status"] == "interrupted":
                    interrupted = True
                    break
        except KeyboardInterrupt:  # arrived outside a seed's episode loop
            interrupted = True
    else:
        interrupted = _run_in_processes(jobs, args.workers)
    # Read back what each seed wrote (a worker interrupted mid-run reports only on disk).
    summaries = [json.loads(p.read_text()) for p in (Path(job[2]) / "summary.json" for job in jobs)
                 if p.is_file()]
    failures = [s for s in summaries if s["status"] in ("non_finite_loss", "error")]
    for s in failures:
        print(f"error: seed {s['seed']}: {s['message']}", file=sys.stderr)
    if summaries and len(seeds) > 1:
        write_aggregate(out, summaries, base.threshold, f"{experiment.name} ({args.variant}, {args.framework}), "
                        f"{len(summaries)} seeds", metric_label(experiment, base), experiment.post_reference)
    for s in summaries:
        where = f"episode {s['reached_at_episode']}" if s["success"] else "not reached"
        print(f"{experiment.name}/{args.variant}/{args.framework} seed {s['seed']}: {s['status']}, threshold {where} "
              f"({s['episodes_run']} episodes, {s['total_steps']} steps, {s['wall_seconds']:.1f} s) -> {out}")
    if interrupted:
        print("interrupted: partial results are on disk, marked unfinished", file=sys.stderr)
        return EXIT_INTERRUPTED
    if failures:
        return EXIT_CRITERION
    rate = sum(s["success"] for s in summaries) / len(seeds)
    return EXIT_OK if rate >= args.min_success_rate else EXIT_CRITERION


def evaluate(args: argparse.Namespace) -> int:
    from keras_rl.loop import evaluate_run

    result = evaluate_run(args.run_dir, episodes=args.episodes, gif=args.gif, seed=args.seed, progress=True)
    print(f"mean score over {result['episodes']} greedy episodes: {result['mean']:.2f} "
          f"(std {result['std']:.2f})" + (f"; GIF: {result['gif']}" if "gif" in result else ""))
    return EXIT_OK


def list_experiments() -> int:
    from keras_rl.experiments import EXPERIMENTS

    for name, exp in sorted(EXPERIMENTS.items()):
        print(f"{name:12s} {exp.description}; variants: {', '.join(exp.config_cls.VARIANTS)}; "
              f"frameworks: {', '.join(exp.config_cls.FRAMEWORKS)}")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "reproduce":
            return reproduce(args)
        if args.command == "evaluate":
            return evaluate(args)
        if args.command == "compare":
            from keras_rl.compare import compare
            from keras_rl.results import command_line

            if args.workers < 1:
                raise ConfigError(f"--workers must be at least 1, got {args.workers}")
            if args.episodes is not None and args.episodes <= 0:
                raise ConfigError(f"--episodes must be positive, got {args.episodes}")
            try:
                out = compare(args.experiment, parse_seeds(args.seeds), args.variant, args.workers, args.runs, args.out,
                              args.rerun, args.reuse_only, args.episodes, not args.no_progress, command_line(),
                              args.matched_init)
            except KeyboardInterrupt:
                print("interrupted: the runs so far are on disk; run compare again to reuse them", file=sys.stderr)
                return EXIT_INTERRUPTED
            print(f"report: {out / 'report.md'}")
            print((out / "report.md").read_text().split("**Verdict.** ")[-1].splitlines()[0])
            return EXIT_OK
        if args.command == "aggregate":
            from keras_rl.aggregate import rebuild

            stats = rebuild(args.parent)
            print(f"{args.parent}/summary.md: {stats['successes']}/{stats['seeds']} seeds succeeded")
            return EXIT_OK
        return list_experiments()
    except KerasRLError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
