"""The options every training command shares, as one typed object: ``RunOptions``, checked once
(``RunOptions.checked``), whether made in code (``api``) or from a command line
(``commands/flags.options_from_args``, where the flags themselves are declared).
Nothing here imports argparse, TensorFlow or Ray.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

from keras_rl.errors import ConfigError, argument
from keras_rl.train.engine import ENGINE_NAMES, VECTORISED

AUTO = "auto"
"""``--engine auto``, the default: ``study.choose_engine`` picks the engine when the study is planned
(the one a set or ``--config``'s run recorded; else compiled where it is certified, else gymnasium)."""


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
    (``dispatch/jobs.auto_batch_size``)."""
    episodes: int | None = None
    """The episode budget; None keeps the post's."""
    progress: bool = True
    address_source: str = "address"
    """Where ``address`` came from, for messages: the argument ``address`` or ``$RAY_ADDRESS``."""
    engine: str = AUTO
    """Which engine trains the seeds (``train/engine.ENGINES``): ``gymnasium``, the reference
    loop, ``compiled``, each episode one XLA program, or ``vectorised``, post 003's PyTorch
    tutorial on a batch of seeds in one program; ``auto`` (the default): ``study.choose_engine``'s."""

    @classmethod
    def checked(
        cls,
        *,
        workers: int = 1,
        episodes: int | None = None,
        seed_batch: int | str = 1,
        engine: str = AUTO,
        address: str | None = None,
        address_source: str = "address",
        progress: bool = True,
    ) -> RunOptions:
        """Options made in code (``api``) or from a command line: each checked, a ConfigError naming
        the first that is wrong (a whole number where one is wanted, not a float or a string)."""
        for name, value in (("workers", workers), ("episodes", episodes)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise ConfigError(f"{argument(name)} must be a whole number, got {value!r}")
        batch = argument("seed_batch")
        if seed_batch != "auto" and (isinstance(seed_batch, bool) or not isinstance(seed_batch, int)):
            raise ConfigError(f"{batch} must be a whole number or auto, got {seed_batch!r}")
        if workers < 1:
            raise ConfigError(f"{argument('workers')} must be at least 1, got {workers}")
        if episodes is not None and episodes <= 0:
            raise ConfigError(f"{argument('episodes')} must be positive, got {episodes}")
        if seed_batch != "auto" and int(seed_batch) < 1:
            raise ConfigError(f"{batch} must be at least 1 or auto, got {seed_batch}")
        if engine not in (AUTO, *ENGINE_NAMES):
            raise ConfigError(f"unknown engine {engine!r}; known: {', '.join((AUTO, *ENGINE_NAMES))}")
        if engine == "compiled" and seed_batch != 1:
            raise ConfigError(
                f"{argument('engine', engine)} runs one seed per program; {batch} is the gymnasium engine's"
            )
        if engine in VECTORISED and seed_batch == "auto":
            raise ConfigError(
                f"{argument('engine', engine)} takes {argument('seed_batch', 'S')}, a whole number: the seeds "
                "stepped in one program (auto is the gymnasium engine's measured size)"
            )
        cores = os.cpu_count() or 1
        if workers > cores:
            print(
                f"warning: {argument('workers', workers)} is more than this machine's {cores} cores; using {cores}",
                file=sys.stderr,
            )
            workers = cores
        return cls(
            workers=workers,
            address=address,
            seed_batch=seed_batch,
            episodes=episodes,
            progress=progress,
            address_source=address_source,
            engine=engine,
        )

    def check_address(self) -> None:
        """A ConfigError unless the cluster at ``address`` (if any) answers; call it once the
        rest of the input is known to be good."""
        if self.address:
            from keras_rl.dispatch.ray_backend import address_parts, check_reachable, require_ray

            address_parts(self.address, self.address_source)  # a malformed address first, Ray or not
            require_ray()
            check_reachable(self.address, source=self.address_source)

    def config_changes(self) -> dict[str, int]:
        """The config fields these options set (``episodes``), for ``for_variant``."""
        return {} if self.episodes is None else {"episodes": self.episodes}
