"""The engine seam: what a backend calls (``dispatch/jobs.run_job``) to train a set of seeds.

An engine takes one experiment, the seeds' configs (equal but for the seed), their run
folders and one ``TrainSettings``, trains them, and leaves in each folder what the project's
run folder holds (``config.json``, ``episodes.csv``, ``summary.json``, checkpoints, weights,
``evaluations.csv``, TensorBoard scalars); it returns the seeds' summaries. The commands, the
dispatch (in-process or Ray), resume and the reports read only those folders, so a second
engine lands here without changing them.

``refusal`` answers before anything is trained: a config the engine cannot run faithfully
(a quirk switch it does not honour, say) gets a sentence naming the switch, which the
command turns into exit 2.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Protocol

from keras_rl.errors import ConfigError
from keras_rl.experiment import Experiment
from keras_rl.runs.lifecycle import UNRECORDED_ENGINE
from keras_rl.runs.summary import RunSummary
from keras_rl.train.compiled_scope import ENGINE as COMPILED
from keras_rl.train.settings import TrainSettings
from keras_rl.train.vectorised import COMPILED_ENGINE, VectorisedEngine
from keras_rl.train.vectorised import ENGINE as VECTORISED_EAGER


class Engine(Protocol):
    name: str

    def refusal(self, experiment: Experiment, config) -> str | None:
        """Why this engine cannot run ``config`` of ``experiment``; None if it can."""

    def train(
        self,
        experiment: Experiment,
        configs: Sequence,
        out_dirs: Sequence[Path],
        settings: TrainSettings,
        *,
        should_stop: Callable[[], bool] | None = None,
    ) -> list[RunSummary]:
        """Train the seeds of ``configs`` into ``out_dirs``; their summaries, in order.
        ``should_stop`` is asked between chunks of work (a dispatcher's stop flag)."""


class GymnasiumEngine:
    """The episode loop of ``train/loop.py``: Gymnasium envs stepped in NumPy, one learner
    call per env step over the seed axis. It runs every experiment, framework and quirk."""

    name = UNRECORDED_ENGINE

    def refusal(self, experiment: Experiment, config) -> str | None:
        return None

    def train(
        self,
        experiment: Experiment,
        configs: Sequence,
        out_dirs: Sequence[Path],
        settings: TrainSettings,
        *,
        should_stop: Callable[[], bool] | None = None,
    ) -> list[RunSummary]:
        from keras_rl.train.loop import run_seeds  # TensorFlow loads here

        return run_seeds(experiment, configs, out_dirs, settings, should_stop=should_stop)


def _compiled() -> Engine:
    from keras_rl.train.compiled import CompiledEngine  # TensorFlow loads here

    return CompiledEngine()


_BUILD: dict[str, Callable[[], Engine]] = {
    GymnasiumEngine.name: GymnasiumEngine,
    COMPILED: _compiled,
    VECTORISED_EAGER: VectorisedEngine,
    COMPILED_ENGINE: partial(VectorisedEngine, compiled=True),
}
ENGINE_NAMES = tuple(_BUILD)
"""Every engine, by name: the one list ``--engine`` offers and ``RunOptions`` checks. Naming them
loads neither TensorFlow nor PyTorch (each engine's module loads its framework when it trains)."""
VECTORISED = (VECTORISED_EAGER, COMPILED_ENGINE)
"""The vectorised engine's two programs (``train/vectorised.py``): eager, and its step compiled."""
ENGINES: dict[str, Engine] = {}
"""The engines built so far, by name (``get_engine`` builds each on first use)."""


def get_engine(name: str) -> Engine:
    if name not in ENGINES:
        if name not in _BUILD:
            raise ConfigError(f"unknown engine {name!r}; known: {', '.join(sorted(ENGINE_NAMES))}")
        ENGINES[name] = _BUILD[name]()
    return ENGINES[name]
