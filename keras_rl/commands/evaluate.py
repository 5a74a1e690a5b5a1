"""``keras-rl evaluate``: greedy episodes from a run's saved weights."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from keras_rl.commands.common import (
    EXIT_OK,
    _check_writable_file,
    _stopped,
)
from keras_rl.commands.flags import path_arg, shared_flags
from keras_rl.errors import ConfigError


def add_parser(sub) -> None:
    """``evaluate``'s arguments."""
    ev = sub.add_parser(
        "evaluate",
        help="reload a run's saved policy and play greedy episodes",
        parents=[shared_flags("evaluate", "--episodes", "--overwrite")],
    )
    ev.add_argument(
        "run_dir",
        type=Path,
        help="a seed's run folder with its weights, e.g. runs/pendulum/seed_0 "
        "(committed runs hold none: reproduce the seed first)",
    )
    ev.add_argument("--seed", type=int, default=None, help="env seed (default: the run's seed + 10000)")
    ev.add_argument("--gif", type=path_arg, default=None, help="record the first episode to this .gif file")


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
