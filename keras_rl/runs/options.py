"""The options every training command shares, declared once: ``RunOptions`` and its argparse parent.

``reproduce``, ``compare``, ``sweep`` and ``check`` all train seeds. Each takes the subset of
``--workers``, ``--address``, ``--seed-batch``, ``--episodes``, ``--set`` and
``--no-progress`` that applies to it, from :func:`run_options_parser`, so the flags and
their help texts are written in one place. :meth:`RunOptions.from_args` checks them (a
``ConfigError`` naming the flag) and resolves ``--address`` against ``$RAY_ADDRESS``.
Nothing here imports TensorFlow or Ray.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass

from keras_rl.errors import ConfigError

OPTIONS = ("workers", "address", "seed_batch", "episodes", "set", "no_progress", "engine")
ENGINE_NAMES = ("gymnasium", "compiled")
"""``train/engine.ENGINES``' names (a test keeps them equal), here so that parsing imports no TensorFlow."""


@dataclass(frozen=True)
class RunOptions:
    """How a command trains its seeds (not what it trains: that is the config)."""

    workers: int = 1
    """Seeds (or batches of seeds) at once on a local Ray instance; 1 runs them in this process."""
    address: str | None = None
    """A Ray cluster's HOST:PORT; None for local."""
    seed_batch: int | str = 1
    """Seeds trained together, one compiled step per env step (``--seed-batch``); ``"auto"``:
    as many as the post's measured cap allows, split evenly over the workers
    (``runs/jobs.auto_batch_size``)."""
    episodes: int | None = None
    """The episode budget; None keeps the post's."""
    overrides: tuple[str, ...] = ()
    """``FIELD=VALUE`` texts from ``--set``, parsed by ``config.parse_assignments``."""
    progress: bool = True
    address_source: str = "--address"
    """Where ``address`` came from, for messages: ``--address`` or ``$RAY_ADDRESS``."""
    engine: str = "gymnasium"
    """Which engine trains the seeds (``train/engine.ENGINES``): ``gymnasium``, the reference
    loop, or ``compiled``, each episode one XLA program."""

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RunOptions:
        """The options a command was given, checked; absent flags take their defaults."""
        workers = getattr(args, "workers", 1)
        episodes = getattr(args, "episodes", None)
        seed_batch = getattr(args, "seed_batch", 1)
        if workers < 1:
            raise ConfigError(f"--workers must be at least 1, got {workers}")
        if episodes is not None and episodes <= 0:
            raise ConfigError(f"--episodes must be positive, got {episodes}")
        if seed_batch != "auto" and seed_batch < 1:
            raise ConfigError(f"--seed-batch must be at least 1 or auto, got {seed_batch}")
        engine = getattr(args, "engine", "gymnasium")
        if engine != "gymnasium" and seed_batch != 1:
            raise ConfigError(f"--engine {engine} runs one seed per program; --seed-batch is the gymnasium engine's")
        cores = os.cpu_count() or 1
        if workers > cores:
            print(
                f"warning: --workers {workers} is more than this machine's {cores} cores; using {cores}",
                file=sys.stderr,
            )
            workers = cores
        address, source = None, "--address"
        if hasattr(args, "address"):
            address = args.address or os.environ.get("RAY_ADDRESS") or None
            source = "--address" if args.address else "$RAY_ADDRESS"
        return cls(
            workers=workers,
            address=address,
            seed_batch=seed_batch,
            episodes=episodes,
            overrides=tuple(getattr(args, "overrides", ())),
            progress=not getattr(args, "no_progress", False),
            address_source=source,
            engine=engine,
        )

    def check_address(self) -> None:
        """A ConfigError unless the cluster at ``address`` (if any) answers; call it once the
        rest of the input is known to be good."""
        if self.address:
            from keras_rl.runs.ray_backend import check_reachable

            check_reachable(self.address, source=self.address_source)

    def config_changes(self) -> dict[str, int]:
        """The config fields these options set (``episodes``), for ``for_variant``."""
        return {} if self.episodes is None else {"episodes": self.episodes}


def seed_batch_arg(text: str) -> int | str:
    """``--seed-batch``'s value: a whole number, or ``auto``."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number or auto, got {text!r}") from None


def run_options_parser(*names: str, workers_default: int = 1, what: str = "seeds") -> argparse.ArgumentParser:
    """An argparse parent with the named options of ``OPTIONS`` (all of them if none are named)."""
    unknown = set(names) - set(OPTIONS)
    if unknown:
        raise ValueError(f"unknown run options {sorted(unknown)}")
    names = names or OPTIONS
    parent = argparse.ArgumentParser(add_help=False)
    if "workers" in names:
        parent.add_argument(
            "--workers",
            type=int,
            default=workers_default,
            help=f"{what} (or seed batches) at once on a local Ray instance "
            f"(default {workers_default}{': in this process, no Ray' if workers_default == 1 else ''})",
        )
    if "address" in names:
        parent.add_argument(
            "--address", default=None, help="run on the Ray cluster at HOST:PORT instead (default: $RAY_ADDRESS if set)"
        )
    if "seed_batch" in names:
        parent.add_argument(
            "--seed-batch",
            type=seed_batch_arg,
            default=1,
            metavar="S",
            help="train S seeds together in one compiled step per env step (default 1: each seed "
            "alone; auto: the post's measured batch size, split evenly over --workers; "
            "`keras-rl list` shows which frameworks batch)",
        )
    if "episodes" in names:
        parent.add_argument("--episodes", type=int, default=None, help="episode budget (default: the post's)")
    if "set" in names:
        parent.add_argument(
            "--set",
            dest="overrides",
            action="append",
            default=[],
            metavar="FIELD=VALUE",
            help="override a config field of every run, e.g. --set tau=0.005 (repeatable)",
        )
    if "no_progress" in names:
        parent.add_argument("--no-progress", action="store_true", help="no progress bars")
    if "engine" in names:
        parent.add_argument(
            "--engine",
            choices=ENGINE_NAMES,
            default="gymnasium",
            help="gymnasium (the reference loop: Gymnasium's envs, one learner call per env step; the default) "
            "or compiled (each episode one XLA program; posts 000 and 003 in Keras so far)",
        )
    return parent
