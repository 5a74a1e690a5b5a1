"""The command line's flags, declared once: every flag more than one command takes (``--workers``,
``--address``, ``--seed-batch``, ``--episodes``, ``--set``, ``--no-progress``, ``--engine``, and
``--seeds``, ``--out``, ``--variant``, ...) is in ``FLAGS``, and a command takes its subset from
:func:`shared_flags`, so each has one default and one help text. :func:`options_from_args` turns
them into the library's typed ``RunOptions`` (checked there, a ``ConfigError`` naming the flag) and
resolves ``--address`` against ``$RAY_ADDRESS``. The library below ``commands/`` never sees argparse.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from keras_rl.dispatch.options import AUTO, RunOptions
from keras_rl.train.engine import ENGINE_NAMES


def options_from_args(args: argparse.Namespace) -> RunOptions:
    """The options a command was given, checked; absent flags take their defaults."""
    address, source = None, "address"
    if hasattr(args, "address"):
        address = args.address or os.environ.get("RAY_ADDRESS") or None
        source = "address" if args.address else "$RAY_ADDRESS"
    return RunOptions.checked(
        workers=getattr(args, "workers", 1),
        episodes=getattr(args, "episodes", None),
        seed_batch=getattr(args, "seed_batch", 1),
        engine=getattr(args, "engine", AUTO),
        address=address,
        address_source=source,
        progress=not getattr(args, "no_progress", False),
    )


def set_changes(config_cls, args: argparse.Namespace) -> dict[str, Any]:
    """``--set FIELD=VALUE``'s texts, parsed once by the config's field types into the typed changes
    the library takes (``config.replace(**changes)``)."""
    return config_cls.parse_assignments(tuple(getattr(args, "overrides", None) or ()))


def seed_batch_arg(text: str) -> int | str:
    """``--seed-batch``'s value: a whole number, or ``auto``."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number or auto, got {text!r}") from None


def path_arg(text: str) -> Path:
    """A path option; an empty one is an error (``Path("")`` would silently mean the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty; name a path")
    return Path(text)


def variant_help(command: str) -> str:
    """``--variant``'s help: each post's variants as its config class names them (``VARIANTS``),
    so that a variant added to a post is offered without editing a help text (issue 54, item 15)."""
    from keras_rl.registry import EXPERIMENTS

    posts = "; ".join(f"{name}: {', '.join(e.config_cls.VARIANTS)}" for name, e in EXPERIMENTS.items())
    return f"the variant (default faithful): {posts} (`keras-rl list` says what each changes)"


def seed_batch_help(command: str) -> str:
    """``--seed-batch``'s help: the posts and frameworks with a seed-batched learner
    (``learners/table.STACKED``), and the retired ones as retired (``RETIRED``), never offered."""
    from keras_rl.learners.table import RETIRED, STACKED

    def pairs(table) -> str:
        names = [f"{experiment} ({framework})" for experiment, framework in table]
        return ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else "".join(names)

    instead = "run their seeds with --engine compiled" if command == "reproduce" else "auto runs their seeds alone"
    vectorised = (
        "; with --engine vectorised, S seeds of cartpole (torch) in one program" if command == "reproduce" else ""
    )
    return (
        f"train S seeds together in one compiled step per env step, for {pairs(STACKED)} (default 1: each "
        f"seed alone; auto: the post's measured batch size, split evenly over --workers){vectorised}. Retired "
        f"for {pairs(RETIRED)}: {instead}"
    )


FLAGS: dict[str, dict[str, Any]] = {
    "--workers": dict(
        type=int,
        default=1,
        help="seeds (or seed batches) at once, each in a process of its own (default 1: in this process)",
    ),
    "--address": dict(default=None, help="run on the Ray cluster at HOST:PORT instead (default: $RAY_ADDRESS if set)"),
    "--seed-batch": dict(type=seed_batch_arg, default=1, metavar="S", help=seed_batch_help),
    "--episodes": dict(
        type=int,
        default=None,
        help="the training budget in episodes (default: the post's)",
    ),
    "--set": dict(
        dest="overrides",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="override a config field of every run, e.g. --set tau=0.005 (repeatable)",
    ),
    "--no-progress": dict(action="store_true", help="no progress bars"),
    "--engine": dict(
        choices=(AUTO, *ENGINE_NAMES),
        default=AUTO,
        help="auto (the default: the engine the runs already in --out, or --config's run, were made on; "
        "else compiled where it is certified, posts 000, 001 and 003 in Keras with their faithful switches "
        "and no --seed-batch; else gymnasium), gymnasium (the reference loop: Gymnasium's envs, one learner "
        "call per env step), compiled (each episode one XLA program) or vectorised (post 003's PyTorch "
        "tutorial, --seed-batch S seeds in one program, on the GPU where there is one; vectorised-compiled: its "
        "step compiled by torch.compile, about a minute to compile, then about 2.5x faster on a CPU)",
    ),
    "--seeds": dict(
        default=None,
        help="seed list or range: 13, 0-9, 0,3,5",
    ),
    "--out": dict(
        type=path_arg,
        default=None,
        help="where the command writes",
    ),
    "--variant": dict(default=None, help=variant_help),
    "--framework": dict(default=None, help="keras (ours; the default) or torch (where the experiment has one)"),
    "--matched-init": dict(
        action="store_true",
        help="PyTorch runs start from the Keras networks' initial weights for the same seed",
    ),
    "--overwrite": dict(
        action="store_true",
        help="replace what is there",
    ),
    "--dry-run": dict(
        action="store_true",
        help="print what would run and train nothing",
    ),
    "--tier": dict(
        default="smoke",
        help="the rule tier: smoke (minutes, in `make test`), full, or sensitive (default smoke)",
    ),
    "--against": dict(
        type=Path,
        default=None,
        help="the folder holding <experiment>/baseline, as seed_<n>/ folders or a runs.parquet",
    ),
    "--alpha": dict(
        type=float,
        default=None,
        help="the command's false-alarm bound (default 0.01, the committed designs')",
    ),
    "--write": dict(action="store_true", help="write what it made into the checkout (default: print it)"),
    "--changes": dict(
        action="store_true",
        help="print each row's reading on seeds 0-9 beside its reading on all its seeds "
        "(what growing the sets changed)",
    ),
}
"""Every flag that more than one command takes, declared once: one type and one default wherever
it appears (``tests/test_options.py`` reads every command's parser). Its help text here is what
it means everywhere (a function where the text lists what the tables hold: the variants, the
seed-batched learners); where a command means more, ``COMMAND_HELP`` says it for that command alone.
Where a command reads a None default as a value of its own, ``COMMAND_DEFAULTS`` says which,
and that command's help text says it too."""

COMMAND_HELP: dict[str, dict[str, str]] = {
    "reproduce": {
        "--seeds": "seed list or range: 13, 0-9, 0,3,5 (default 0, or --config's seed)",
        "--out": "the folder of the run folders, one seed_<n>/ per seed (default results/<experiment>/<variant>)",
        "--overwrite": "clear each seed folder that already holds a run, whole, and run it again",
        "--dry-run": "print the resolved config and how each seed folder would start; train nothing",
    },
    "compare": {
        "--matched-init": "the PyTorch arm starts from the Keras networks' initial weights for the same seed "
        "(the report goes under <out>/<experiment>/matched-init)",
        "--seeds": "seed list or range: 13, 0-9, 0,3,5 (default 0-9)",
        "--out": "where the report goes, under <out>/<experiment> (default results/compare)",
    },
    "sweep": {
        "--seeds": "seed list or range for every grid point: 13, 0-9, 0,3,5 (default 0-9)",
        "--out": "the sweep's folder, one folder per grid point (no default: name it)",
    },
    "check": {
        "--seeds": "fresh seeds instead of the rule's own (never the baseline's; the calibrated error "
        "rates are for the rule's own)",
        "--out": "where the fresh seeds and the report go (default check-runs; an earlier check's output "
        "there is replaced, anything else refused)",
        "--dry-run": "print each post's plan (rule, fresh seeds, baseline, calibrated error rates); train nothing",
        "--tier": "smoke (minutes, in `make test`), full, or sensitive (a 10%% move of post 000's median, "
        "about 15 minutes on two workers) (default smoke)",
        "--against": "the folder holding <experiment>/baseline, as seed_<n>/ folders or a runs.parquet "
        "(default: this checkout's results/checks, or the installed package's own)",
        "--alpha": "the false-alarm bound of the whole command, split over its posts and, with "
        "--sequential, their looks (default 0.01, the committed designs')",
    },
    "bisect": {
        "--out": "where each commit's worktree, fresh seeds and reading go (default bisect-runs)",
        "--against": "the folder holding <experiment>/baseline (default: the checkout's results/checks, "
        "copied into --out so that every commit checks against the same runs)",
        "--alpha": "the false-alarm bound of the whole search, split over its steps (default 0.01)",
    },
    "evaluate": {
        "--episodes": "greedy episodes to play (default 5)",
        "--overwrite": "replace an evaluation.json of more episodes than this plays",
    },
    "replay-references": {
        "--episodes": "the episodes of each case rerun against its reference or natively (default 10; not with make)",
        "--write": "save the report of the references rerun as <set>/emulation-<CPU>.md (default: print it)",
    },
}
"""What a shared flag means in one command, where that is more than ``FLAGS`` says."""

COMMAND_DEFAULTS: dict[str, dict[str, Any]] = {
    "compare": {"seeds": "0-9", "variant": "faithful", "out": Path("results/compare")},
    "sweep": {"seeds": "0-9", "variant": "faithful", "framework": "keras"},
    "check": {"out": Path("check-runs")},
    "bisect": {"out": Path("bisect-runs"), "alpha": 0.01},
    "evaluate": {"episodes": 5},
}
"""What a shared flag left at None means in each command (``resolve_defaults``)."""


def resolve_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """``args`` with each shared flag the user left at None set to its command's own default."""
    for dest, value in COMMAND_DEFAULTS.get(getattr(args, "command", ""), {}).items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)
    return args


def shared_flags(command: str, *spellings: str) -> argparse.ArgumentParser:
    """An argparse parent holding the named flags of ``FLAGS``, as declared there, each with
    ``command``'s own help text where it has one (``COMMAND_HELP``)."""
    unknown = set(spellings) - set(FLAGS)
    if unknown:
        raise ValueError(f"unknown shared flags {sorted(unknown)}")
    parent = argparse.ArgumentParser(add_help=False)
    for spelling in spellings:
        parent.add_argument(spelling, **{**FLAGS[spelling], "help": help_for(command, spelling)})
    return parent


def help_for(command: str, spelling: str) -> str:
    """The help text of a shared flag in ``command`` (one made from the tables, where ``FLAGS``
    gives a function, made for that command)."""
    text = COMMAND_HELP.get(command, {}).get(spelling, FLAGS[spelling]["help"])
    return text(command) if callable(text) else text


RUN_FLAGS = ("--workers", "--address", "--seed-batch", "--episodes", "--set", "--no-progress", "--engine")
"""The flags of ``RunOptions``: how a command trains its seeds."""
