"""``keras-rl``: reproduce a post over seeds, compare frameworks, or evaluate a saved run.

keras-rl reproduce pendulum --variant faithful --seeds 0-9 --workers 2 --out runs/pendulum
keras-rl compare pendulum --seeds 0-9 --workers 2 --runs runs --out runs/compare
keras-rl sweep pendulum --grid tau=0.001,0.005 --seeds 0-3 --workers 2 --out runs/s
keras-rl evaluate runs/pendulum/seed_0 --episodes 5 --gif pendulum.gif
keras-rl aggregate results/pendulum/faithful
keras-rl check pendulum cartpole mountaincar --tier smoke
keras-rl list
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from keras_rl import __version__
from keras_rl.errors import ConfigError, KerasRLError, NoVerdictError
from keras_rl.runs.options import RunOptions, run_options_parser

EXIT_OK, EXIT_CRITERION, EXIT_USAGE, EXIT_NO_VERDICT = 0, 1, 2, 3
MAX_SEEDS = 10_000
"""More seeds than this in one command is taken for a typo (``0-100000``) and refused."""


def _stopped() -> int:
    """The exit code of a command a signal stopped (130 Ctrl-C, 143 SIGTERM)."""
    from keras_rl.runs.signals import stop_exit_code

    return stop_exit_code()


def parse_seeds(text: str) -> list[int]:
    """``"0-9"``, ``"1,3,5"``, ``"0-2,7"`` -> a sorted list of distinct seeds.

    Refused, each with a ConfigError naming it: an empty item (``1,,2``), a seed named twice
    (``1,1``), digits other than ASCII ones, and more than ``MAX_SEEDS`` seeds, which is
    checked from the range's ends before any list is built (``0-4294967295`` would not fit
    in memory)."""
    seeds: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            raise ConfigError(f"seeds {text!r} has an empty item; write a list like 0,1,2 or a range like 0-9")
        if not part.isascii():
            raise ConfigError(f"seeds {text!r}: {part!r} is not written in ASCII digits")
        lo_text, dash, hi_text = part.partition("-") if "-" in part[1:] else (part, "", part)
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise ConfigError(f"cannot read seeds {text!r}: use a list like 0,1,2 or a range like 0-9") from None
        if lo > hi:
            raise ConfigError(f"seed range {part!r} runs backwards; write {hi}-{lo}")
        if lo < 0:
            raise ConfigError(f"seeds must be zero or more, got {lo}")
        if hi >= 2**32:
            raise ConfigError(f"seeds must be below 2**32 (NumPy's and Gymnasium's limit), got {hi}")
        if len(seeds) + hi - lo + 1 > MAX_SEEDS:
            raise ConfigError(f"{text!r} names more than {MAX_SEEDS} seeds; split the run into smaller commands")
        part_seeds = range(lo, hi + 1)
        twice = seeds.intersection(part_seeds)
        if twice:
            raise ConfigError(f"seeds {text!r} names seed {min(twice)} twice")
        seeds.update(part_seeds)
    return sorted(seeds)


def _path_arg(text: str) -> Path:
    """A path option; an empty one is an error (``Path("")`` would silently mean the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty; name a path")
    return Path(text)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="keras-rl", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"keras-rl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    rep = sub.add_parser(
        "reproduce", help="train one experiment over one or more seeds", parents=[run_options_parser()]
    )
    rep.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    rep.add_argument(
        "--variant",
        default=None,
        help="the variant: faithful (the default), fixed; mountaincar also has faithful-intended "
        "(all: `keras-rl list`)",
    )
    rep.add_argument(
        "--framework", default=None, help="keras (ours; the default) or torch (where the experiment has one)"
    )
    rep.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="RUN/config.json",
        help="rerun a recorded run: its config.json gives every field (its seed too, unless --seeds "
        "is given); --set and --episodes still apply on top",
    )
    rep.add_argument(
        "--dry-run",
        action="store_true",
        help="print the resolved config and each seed folder with how it would start; train nothing",
    )
    rep.add_argument(
        "--matched-init",
        action="store_true",
        help="torch only: start from the Keras networks' initial weights for the same seed",
    )
    rep.add_argument("--seeds", default=None, help="seed list or range: 13, 0-9, 0,3,5 (default 0, or --config's)")
    rep.add_argument(
        "--out",
        type=_path_arg,
        default=None,
        help="output folder (default results/<experiment>/<variant>); one seed_<n>/ per seed",
    )
    rep.add_argument(
        "--min-success-rate",
        type=float,
        default=1.0,
        help="exit 0 only if at least this share of seeds succeed (default 1.0: all)",
    )
    rep.add_argument(
        "--overwrite",
        action="store_true",
        help="replace seed folders that already hold a run (each is cleared whole first)",
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
        type=_path_arg,
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

    ev = sub.add_parser("evaluate", help="reload a run's saved policy and play greedy episodes")
    ev.add_argument(
        "run_dir",
        type=Path,
        help="a seed's run folder with its weights, e.g. runs/pendulum/seed_0 "
        "(committed runs hold none: reproduce the seed first)",
    )
    ev.add_argument("--episodes", type=int, default=5, help="greedy episodes to play (default 5)")
    ev.add_argument("--seed", type=int, default=None, help="env seed (default: the run's seed + 10000)")
    ev.add_argument("--gif", type=_path_arg, default=None, help="record the first episode to this .gif file")
    ev.add_argument(
        "--overwrite", action="store_true", help="replace an evaluation.json of more episodes than this one plays"
    )

    cp = sub.add_parser(
        "compare",
        help="run or reuse the same seeds in Keras and PyTorch and report the difference",
        parents=[run_options_parser("workers", "address", "seed_batch", "episodes", "no_progress")],
    )
    cp.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    cp.add_argument("--seeds", default="0-9", help="seed list or range, the same for both frameworks (default 0-9)")
    cp.add_argument("--variant", default="faithful", help="the variant to compare (default faithful)")
    cp.add_argument(
        "--matched-init",
        action="store_true",
        help="torch runs start from the Keras runs' initial weights (report in <out>/<experiment>/matched-init)",
    )
    cp.add_argument("--runs", type=Path, default=Path("results"), help="where run folders are found and made")
    cp.add_argument("--out", type=Path, default=Path("results/compare"), help="report folder root")
    cp.add_argument("--rerun", action="store_true", help="replace existing run folders instead of reusing them")
    cp.add_argument("--reuse-only", action="store_true", help="run nothing; fail if a seed is missing")

    sw = sub.add_parser(
        "sweep",
        help="a grid of config values x seeds, resumable, with a report per grid point",
        description="A grid of config values x seeds, resumable, with a report per grid point. A run "
        "whose loss turns NaN is a result of its config (the report shows it, and the console names "
        "it): it does not fail the command; a run that stops with an error does (exit 1).",
        parents=[run_options_parser()],
    )
    sw.add_argument("experiment", help="experiment name (see `keras-rl list`)")
    sw.add_argument("--seeds", default="0-9", help="seed list or range for every grid point (default 0-9)")
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
    sw.add_argument("--variant", default="faithful", help="the variant the grid modifies (default faithful)")
    sw.add_argument("--framework", default="keras", help="keras (ours) or torch")
    sw.add_argument("--out", type=_path_arg, required=True, help="the sweep's folder: <grid point>/seed_<n>/, sweep.md")
    sw.add_argument("--yes", action="store_true", help="allow a sweep of more than 10,000 jobs")

    ag = sub.add_parser("aggregate", help="rebuild summary.md and curves.png of a multi-seed folder")
    ag.add_argument("parent", type=Path, help="a folder of seed_<n>/ run folders, e.g. results/pendulum/faithful")
    ag.add_argument(
        "--x-axis",
        choices=("episode", "steps"),
        default="episode",
        help="what each seed's curve.png counts along x: episodes (default) or env steps",
    )

    ck = sub.add_parser(
        "check",
        help="regression-test the reproductions: fresh seeds against the committed "
        "baseline, by each post's pre-registered rule (exit 0 consistent, 1 changed)",
        parents=[run_options_parser("workers", "address", "set", "no_progress", workers_default=2)],
    )
    ck.add_argument(
        "experiments", nargs="*", default=None, help="experiments to check (default: pendulum cartpole mountaincar)"
    )
    ck.add_argument("--tier", default="smoke", help="smoke (minutes, in `make test`) or full (default smoke)")
    ck.add_argument(
        "--against",
        type=Path,
        default=None,
        help="the folder holding <experiment>/baseline/seed_<n> (default results/checks of this "
        "checkout; copy it outside the tree for `git bisect run`)",
    )
    ck.add_argument(
        "--seeds",
        default=None,
        help="fresh seeds instead of the rule's (never the baseline's); "
        "the rule's error rates are for its own number of seeds",
    )
    ck.add_argument(
        "--sequential",
        action="store_true",
        help="fresh seeds in looks of 5 up to 30 per post, each post stopping where its calibrated "
        "design decides (results/checks/sequential.md: fewer seeds under a clear change, more under none)",
    )
    ck.add_argument(
        "--alpha",
        type=float,
        default=None,
        help="with --sequential: the command's false-alarm bound, split over its posts and each post's looks "
        "(union bound) instead of the committed designs' 1%% (what a bisect step uses)",
    )
    ck.add_argument(
        "--out",
        type=_path_arg,
        default=Path("check-runs"),
        help="where the fresh runs, check.md, check.json and the plots go (default check-runs; "
        "an earlier check's output there is replaced, anything else is refused)",
    )

    bi = sub.add_parser(
        "bisect",
        help="find the first commit between GOOD and BAD whose learner `check` calls changed "
        "(git bisect in a temporary worktree; exit 0 found, 1 BAD consistent, 3 no verdict)",
    )
    bi.add_argument("good", help="a commit whose learner is consistent with the baseline")
    bi.add_argument("bad", help="a later commit whose learner is not")
    bi.add_argument("experiments", nargs="*", default=None, help="experiments to check (default: all three)")
    bi.add_argument("--tier", default="smoke", help="the check's tier at each step (default smoke)")
    bi.add_argument(
        "--alpha", type=float, default=0.01, help="false-alarm rate of the whole bisect, split over its steps (0.01)"
    )
    bi.add_argument(
        "--against",
        type=Path,
        default=None,
        help="the folder holding <experiment>/baseline (default results/checks of this checkout; copied to OUT)",
    )
    bi.add_argument(
        "--out", type=_path_arg, default=Path("bisect-runs"), help="the steps' reports (default bisect-runs)"
    )
    bi.add_argument(
        "--fixed-n",
        action="store_true",
        help="each step runs the fixed rule's seeds (Holm over the posts) instead of the sequential check, "
        "for commits whose check has no --sequential --alpha",
    )
    bi.add_argument("--workers", type=int, default=2, help="--workers of each step's check (default 2)")
    bi.add_argument("--repo", type=Path, default=Path("."), help="the git repository (default: here)")

    sub.add_parser("list", help="list the experiments and their variants")
    return parser


def _check_writable_dir(path: Path, flag: str) -> None:
    """A folder that exists and is writable, or can be made: else a ConfigError naming it."""
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{flag} {path} is a file, not a folder")
    probe = path
    while not probe.exists():
        probe = probe.parent
    try:  # really write (root passes os.access everywhere, /proc included)
        if not probe.is_dir():
            raise OSError("not a folder")
        fd, name = tempfile.mkstemp(dir=probe, prefix=".keras-rl-probe-")
        os.close(fd)
        os.unlink(name)
    except OSError:
        raise ConfigError(f"{flag} {path}: {probe} is not a writable folder") from None


def _check_not_inside_a_run(out: Path) -> None:
    """``--out`` names the folder that holds ``seed_<n>/`` folders: one inside a run folder
    would nest runs in a run."""
    for folder in (out, *out.parents):
        if folder.name.startswith("seed_") and (folder / "config.json").is_file():
            raise ConfigError(
                f"--out {out} is inside the run folder {folder}; name the folder that holds the "
                "seed_<n>/ folders (its parent), or another one"
            )


def _check_writable_file(path: Path, flag: str) -> None:
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a folder; name a file")
    _check_writable_dir(path.parent if str(path.parent) else Path("."), f"{flag}'s folder")


def _seed_folder_state(seed_dir: Path) -> tuple[str, str] | None:
    """None for a folder that does not exist or is empty; else (its summary's status, or
    "unreadable", and what it holds, for messages)."""
    if not seed_dir.is_dir() or not any(seed_dir.iterdir()):
        return None
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.summary import RunSummary

    try:
        s = RunSummary.read(seed_dir)
        return s.status, f"a {s.status} run, {s.episodes_run} episodes"
    except RunFolderError:
        return "unreadable", "files of an earlier run"


def _start_modes(seed_dirs: list[Path], overwrite: bool, resume: bool, episodes: int | None = None) -> list[str]:
    """How each seed folder starts (new, overwrite, resume, keep), or a ConfigError before
    anything runs. With ``--resume``, a completed run asked for more episodes than it played
    is extended from its final checkpoint (``resume``); one that has none is refused."""
    if overwrite and resume:
        raise ConfigError("--overwrite and --resume contradict each other; pick one")
    from keras_rl.runs.checkpoint import CHECKPOINT
    from keras_rl.runs.reuse import joins_its_stopped_batch

    modes, occupied = [], []
    for seed_dir in seed_dirs:
        state = _seed_folder_state(seed_dir)
        status, held = state if state is not None else (None, None)
        if resume:
            extend = status == "completed" and episodes is not None and _extendable(seed_dir, episodes)
            # a finished seed of a stopped batch resumes with it
            rejoins = status == "completed" and joins_its_stopped_batch(seed_dir)
            if (seed_dir / CHECKPOINT).is_file() and (status != "completed" or extend or rejoins):
                modes.append("resume")
            elif held is None:
                modes.append("new")  # nothing to resume: start it
            elif extend:
                raise ConfigError(
                    f"--resume --episodes {episodes}: {seed_dir} completed its budget but holds no final "
                    f"{CHECKPOINT} (a seed-batched run keeps none), so it cannot be extended; "
                    "--overwrite reruns it"
                )
            elif status == "completed":
                modes.append("keep")  # finishing an interrupted set: its finished seeds stay as they are
            else:
                raise ConfigError(
                    f"--resume: {seed_dir} holds {held} but no {CHECKPOINT}, so it cannot be "
                    "continued (use --overwrite to run it again)"
                )
        elif held is not None and not overwrite:
            occupied.append(f"{seed_dir} ({held})")
        else:
            modes.append("overwrite" if held is not None else "new")
    if occupied:
        committed = any("results" in Path(d).parts for d in seed_dirs)
        raise ConfigError(
            "these seed folders already hold a run and are left untouched: "
            + "; ".join(occupied[:5])
            + (f" and {len(occupied) - 5} more" if len(occupied) > 5 else "")
            + (
                ". They are results: pass --out for a folder of your own (for example --out runs/mine)"
                if committed
                else ". Pass --overwrite to replace them, --resume to continue unfinished ones, "
                "or --out for another folder"
            )
        )
    return modes


def _extendable(seed_dir: Path, episodes: int) -> bool:
    """A completed run that played its whole budget, fewer episodes than ``episodes`` (one
    stopped at its threshold stops there again in a straight run of any budget: it is kept)."""
    import json

    from keras_rl.runs.summary import RunSummary

    summary = RunSummary.read(seed_dir)
    stop = json.loads((seed_dir / "config.json").read_text()).get("stop_at_threshold", True)
    stopped_early = summary.reached_at_episode is not None and stop
    return summary.episodes_run == summary.budget_episodes < episodes and not stopped_early


def _kept_runs(base, seeds_and_dirs: list) -> list:
    """The summaries of the completed seeds ``--resume`` keeps; refuses a completed run made
    by another config or code version, which must not join the set unnoticed."""
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.provenance import code_version
    from keras_rl.runs.reuse import check_reusable
    from keras_rl.runs.summary import RunSummary

    if not seeds_and_dirs:
        return []
    kept, version = [], code_version()
    for seed, seed_dir in seeds_and_dirs:
        try:
            check_reusable(seed_dir, base.replace(seed=seed), version)
        except RunFolderError as exc:
            raise ConfigError(
                f"--resume keeps completed seeds, but {str(exc).split('; ')[0]}; "
                "use --overwrite to run it again, or --out for another folder"
            ) from None
        print(f"seed {seed}: already completed in {seed_dir}, kept", file=sys.stderr)
        kept.append(RunSummary.read(seed_dir))
    return kept


def _recorded_config(experiment, args: argparse.Namespace):
    """``--config``: the config a run folder recorded; the options it settles must not be given too."""
    import json

    given = [f"--{name.replace('_', '-')}" for name in ("variant", "framework") if getattr(args, name) is not None]
    if args.matched_init:
        given.append("--matched-init")
    if given:
        raise ConfigError(f"--config gives the variant and framework; drop {', '.join(given)}")
    path = args.config if args.config.name == "config.json" or not args.config.is_dir() else args.config / "config.json"
    try:
        values = json.loads(path.read_text())
    except OSError as exc:
        raise ConfigError(f"--config {path}: cannot read it ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--config {path} is not JSON ({exc})") from None
    if not isinstance(values, dict) or values.get("experiment") != experiment.name:
        theirs = values.get("experiment") if isinstance(values, dict) else None
        raise ConfigError(f"--config {path} is a config of {theirs!r}, not of {experiment.name}")
    import dataclasses

    cls = experiment.config_cls
    lacking = sorted({f.name for f in dataclasses.fields(cls)} - set(cls.upgrade(values)))
    if lacking:
        raise ConfigError(
            f"--config {path} lacks field(s) {', '.join(lacking)}: a recorded config.json names every "
            "field, so none is filled in silently; add them, or use --variant and --set"
        )
    return cls.from_dict(values)


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
    from keras_rl.runs.backends import backend_for
    from keras_rl.runs.jobs import SeedJob, batched, run_jobs

    kept = _kept_runs(base, [(s, d) for s, d, m in zip(seeds, seed_dirs, modes) if m == "keep"])
    jobs = batched(
        [
            SeedJob.of(
                base.replace(seed=s),
                d,
                start=m,
                checkpoint_every=args.checkpoint_every,
                tensorboard=args.tensorboard,
                evaluation=evaluation,
            )
            for s, d, m in zip(seeds, seed_dirs, modes)
            if m != "keep"
        ],
        options.seed_batch,
        options.workers,
    )
    outcome = run_jobs(
        jobs, backend_for(options.workers, len(jobs), options.address), options.progress, after_job=draw_job_curves
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


def evaluate(args: argparse.Namespace) -> int:
    if args.seed is not None and not 0 <= args.seed < 2**32:
        raise ConfigError(f"--seed must be in [0, 2**32), got {args.seed}")
    if args.episodes <= 0:
        raise ConfigError(f"--episodes must be positive, got {args.episodes}")
    if args.gif is not None:
        _check_writable_file(args.gif, "--gif")
        if args.gif.suffix.lower() != ".gif":
            raise ConfigError(f"--gif writes a GIF; name it *.gif, not {args.gif.name!r}")
    from keras_rl.runs.evaluate import evaluate_run

    result = evaluate_run(
        args.run_dir, episodes=args.episodes, gif=args.gif, seed=args.seed, progress=True, overwrite=args.overwrite
    )
    if result.get("interrupted"):
        print(f"interrupted: {len(result['scores'])} episodes kept in {result['written']}", file=sys.stderr)
        return _stopped()
    print(
        f"mean score over {result['episodes']} greedy episodes: {result['mean']:.2f} "
        f"(std {result['std']:.2f})" + (f"; GIF: {result['gif']}" if "gif" in result else "")
    )
    return EXIT_OK


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
    _check_seed_batch(options.seed_batch, args.experiment, "keras")
    from keras_rl.learners.table import compared_frameworks, stacked_implementation
    from keras_rl.registry import get_experiment

    experiment = get_experiment(args.experiment)
    compared = compared_frameworks(experiment.name)  # a clear error where there is nothing to compare
    if options.seed_batch == "auto" or int(options.seed_batch) > 1:
        alone = []
        for framework in compared:
            try:
                stacked_implementation(experiment.name, framework)
            except ConfigError:
                alone.append(framework)
        if alone:  # reproduce refuses --seed-batch there; compare batches what it can, and says so
            print(
                f"warning: --seed-batch {options.seed_batch}: {experiment.name} in {', '.join(alone)} has no "
                "seed-batched version, so its seeds run alone",
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


def _check_seed_batch(seed_batch: int | str, experiment: str, framework: str) -> None:
    """``--seed-batch S`` (S > 1): a clear error before anything runs when it cannot apply
    (``auto`` runs seeds alone where nothing batches)."""
    if seed_batch != "auto" and int(seed_batch) > 1:
        from keras_rl.learners.table import stacked_implementation

        stacked_implementation(experiment, framework)  # a clear error if there is none


def sweep(args: argparse.Namespace) -> int:
    from keras_rl.registry import get_experiment
    from keras_rl.runs.sweep import ablation_grid, parse_grid, record_grid, sweep_jobs

    experiment = get_experiment(args.experiment)
    seeds = parse_seeds(args.seeds)
    options = RunOptions.from_args(args)
    base = experiment.config_cls.for_variant(args.variant, framework=args.framework, **options.config_changes())
    base = base.with_text_overrides(options.overrides)
    if args.ablate and args.grid:
        raise ConfigError("--ablate makes its own grid; drop --grid, or sweep without --ablate")
    if not args.ablate and not args.grid:
        raise ConfigError("a sweep needs --grid FIELD=V1,V2 (repeatable) or --ablate")
    points = ablation_grid(experiment.config_cls, base) if args.ablate else parse_grid(experiment.config_cls, args.grid)
    both = sorted(
        set(experiment.config_cls.parse_assignments(options.overrides)) & {k for p in points for k in p.overrides}
    )
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
    _check_writable_dir(args.out, "--out")
    options.check_address()
    _check_seed_batch(options.seed_batch, experiment.name, args.framework)
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
    from keras_rl.report.plots import draw_job_curves
    from keras_rl.report.sweep import write_sweep_report
    from keras_rl.runs.backends import backend_for
    from keras_rl.runs.jobs import batched, run_jobs
    from keras_rl.runs.provenance import command_line
    from keras_rl.runs.summary import RunSummary

    record_grid(args.out, points)
    todo = batched(todo, options.seed_batch, options.workers)
    outcome = run_jobs(
        todo, backend_for(options.workers, len(todo), options.address), options.progress, after_job=draw_job_curves
    )
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


def aggregate(args: argparse.Namespace) -> int:
    from keras_rl.report.aggregate import rebuild

    stats = rebuild(args.parent, x_axis=args.x_axis)
    print(f"{args.parent}/summary.md: {stats['successes']}/{stats['seeds']} seeds succeeded")
    return EXIT_OK


def list_experiments(args: argparse.Namespace) -> int:
    from keras_rl.learners.table import STACKED, frameworks
    from keras_rl.registry import EXPERIMENTS

    for name, exp in sorted(EXPERIMENTS.items()):
        batching = [fw for fw in frameworks(name) if (name, fw) in STACKED]
        print(
            f"{name:12s} {exp.description}; variants: {', '.join(exp.config_cls.VARIANTS)}; "
            f"frameworks: {', '.join(frameworks(name))}; --seed-batch: {', '.join(batching) or 'none'}"
        )
    return EXIT_OK


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
    for r in results:
        level = f"alpha {r.rule.alpha}" if r.design is None else f"sequential, efficacy {r.design['efficacy']:.3g}"
        print(
            f"{r.experiment}: {r.verdict} ({r.rule.statistic}, {r.decision.test}, p = {r.decision.p:.3g}, "
            f"{level}; baseline {len(r.baseline)} seeds, new {len(r.new)})"
        )
        if r.config_changes:
            print(f"  {r.experiment}: the faithful config differs from the baseline's: {'; '.join(r.config_changes)}")
    print(f"report: {args.out / 'check.md'}")
    return EXIT_CRITERION if any(r.decision.changed for r in results) else EXIT_OK


def check_results(args: argparse.Namespace) -> list:
    """``check``'s work (``api.check`` too): each post's ``CheckResult``, the report written."""
    from keras_rl.check.rules import RULES, TIERS

    known = sorted({e for e, _ in RULES}, key=["pendulum", "cartpole", "mountaincar"].index)
    names = args.experiments or known
    unknown = [n for n in names if n not in known]
    if unknown:  # before TensorFlow loads: a typo is named in a second, not after the imports
        raise ConfigError(f"unknown experiment {unknown[0]!r}; check knows {', '.join(known)}")
    if args.tier not in TIERS:
        raise ConfigError(f"unknown tier {args.tier!r}; choose one of {', '.join(TIERS)}")
    if len(set(names)) != len(names):
        raise ConfigError(f"an experiment is named twice: {' '.join(names)}")
    if args.sequential and args.seeds is not None:
        raise ConfigError("--seeds and --sequential do not go together: the sequential design runs its own fresh seeds")
    if args.alpha is not None and not args.sequential:
        raise ConfigError(
            "--alpha goes with --sequential: the fixed rule's alpha is pre-registered (keras_rl/check/rules.py)"
        )
    if args.alpha is not None and not 0 < args.alpha < 1:
        raise ConfigError(f"--alpha must lie in (0, 1), got {args.alpha}")
    seeds = parse_seeds(args.seeds) if args.seeds is not None else None
    options = RunOptions.from_args(args)
    _check_writable_dir(args.out, "--out")  # bad input (exit 2), found before any training
    options.check_address()
    from keras_rl.check.command import CALIBRATION, run_check

    against = args.against if args.against is not None else CALIBRATION.parent
    return run_check(
        names, args.tier, against, args.out, seeds, options, sequential=args.sequential, sequential_alpha=args.alpha
    )


def bisect(args: argparse.Namespace) -> int:
    from keras_rl.check.rules import RULES, TIERS

    known = sorted({e for e, _ in RULES}, key=["pendulum", "cartpole", "mountaincar"].index)
    names = args.experiments or known
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ConfigError(f"unknown experiment {unknown[0]!r}; bisect checks {', '.join(known)}")
    if args.tier not in TIERS:
        raise ConfigError(f"unknown tier {args.tier!r}; choose one of {', '.join(TIERS)}")
    if not 0 < args.alpha < 1:
        raise ConfigError(f"--alpha must lie in (0, 1), got {args.alpha}")
    if args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    _check_writable_dir(args.out, "--out")  # exit 2, not one of the verdicts' exit codes
    from keras_rl.check.bisect import bisect as run_bisect
    from keras_rl.check.command import CALIBRATION
    from keras_rl.runs.signals import sigterm_as_interrupt

    against = (args.against if args.against is not None else CALIBRATION.parent).resolve()
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


COMMANDS = {
    "bisect": bisect,
    "check": check,
    "reproduce": reproduce,
    "evaluate": evaluate,
    "compare": compare,
    "sweep": sweep,
    "aggregate": aggregate,
    "list": list_experiments,
}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except KerasRLError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # a full disk or a vanished folder mid-run: say so, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_CRITERION


if __name__ == "__main__":
    sys.exit(main())
