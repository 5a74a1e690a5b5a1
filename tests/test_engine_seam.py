"""The engine seam (``keras_rl/train/engine.py``): a job reaches training only through its
engine, with one ``TrainSettings``; an unknown engine is a clear error; the loop's learner
is a ``SeedAxisLearner`` whose mask support is declared, not probed."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from committed import committed_seed

from keras_rl.dispatch import jobs
from keras_rl.errors import ConfigError
from keras_rl.runs.summary import RunSummary
from keras_rl.train import engine as engines
from keras_rl.train.settings import TrainSettings

ROOT = Path(__file__).resolve().parent.parent
PENDULUM_SEED = committed_seed("pendulum/faithful/seed_0")


class RecordingEngine:
    """Writes a copy of a committed run into each folder, and remembers what it was given."""

    name = "recording"

    def __init__(self):
        self.calls: list[tuple] = []

    def refusal(self, experiment, config):
        return None

    def train(self, experiment, configs, out_dirs, settings, should_stop=None):
        self.calls.append((experiment.name, [c.seed for c in configs], settings))
        out = []
        for config, folder in zip(configs, out_dirs):
            Path(folder).mkdir(parents=True, exist_ok=True)
            summary = json.loads((PENDULUM_SEED / "summary.json").read_text())
            summary["seed"] = config.seed
            (Path(folder) / "summary.json").write_text(json.dumps(summary))
            shutil.copy(PENDULUM_SEED / "episodes.csv", Path(folder) / "episodes.csv")
            out.append(RunSummary.read(folder))
        return out


def test_a_job_trains_on_its_engine_with_one_settings_object(tmp_path, monkeypatch):
    from keras_rl.registry import get_experiment

    fake = RecordingEngine()
    monkeypatch.setitem(engines.ENGINES, "recording", fake)
    config = get_experiment("pendulum").config_cls.for_variant("faithful", seed=7, episodes=3)
    job = jobs.SeedJob.of(config, tmp_path / "seed_7", engine="recording", checkpoint_every=4, command="cmd")
    outcome = jobs.read_outcome([job], jobs.InProcess().run([job], progress=False))
    assert [s.seed for s in outcome.summaries] == [7] and not outcome.interrupted
    ((name, seeds, settings),) = fake.calls
    assert (name, seeds) == ("pendulum", [7])
    assert settings == TrainSettings(progress=False, checkpoint_every=4, command="cmd")


def test_a_run_without_a_recorded_engine_is_the_loops_and_a_user_gets_auto():
    """Two facts that were one name (``DEFAULT_ENGINE``, tested as "gymnasium" while users got ``auto``):
    the engine of a job or run that names none, and the one default every entry point gives users."""
    import inspect

    from keras_rl import api
    from keras_rl.commands.flags import FLAGS
    from keras_rl.dispatch.options import AUTO, RunOptions

    assert jobs.SeedJob("pendulum", {}, Path("x")).engine == engines.UNRECORDED_ENGINE == "gymnasium"
    assert RunOptions().engine == inspect.signature(RunOptions.checked).parameters["engine"].default == AUTO
    assert inspect.signature(api.reproduce).parameters["engine"].default == FLAGS["--engine"]["default"] == AUTO
    engine = engines.get_engine("gymnasium")
    assert isinstance(engine, engines.GymnasiumEngine) and engine.refusal(None, None) is None


def test_an_unknown_engine_is_named():
    with pytest.raises(ConfigError, match="unknown engine 'xla'; known: compiled, gymnasium"):
        engines.get_engine("xla")


def test_only_learners_that_declare_masks_are_given_them():
    """Every seed-axis learner says whether ``train`` takes a mask; the loop reads the
    attribute (it probed with getattr, defaulting to False, before the Protocol)."""
    from keras_rl.learners import stacked
    from keras_rl.torch import stacked as torch_stacked

    assert stacked.SoloAsStack.takes_masks is False
    assert stacked.StackedDDPGLearner.takes_masks is True
    assert torch_stacked.StackedTorchDDPGLearner.takes_masks is True
    solo = stacked.SoloAsStack(learner=type("L", (), {"loss_names": ("q",), "compile": lambda self: None})())
    with pytest.raises(TypeError, match="has no compile"):
        stacked.SoloAsStack(learner=type("Old", (), {"loss_names": ("q",)})())
    with pytest.raises(ValueError, match="takes no mask"):
        solo.train(None, mask=[True])


def test_train_seeds_packs_picks_the_backend_and_runs(tmp_path, replace_backend):
    from keras_rl.dispatch import backends
    from keras_rl.dispatch.options import RunOptions
    from keras_rl.registry import get_experiment

    seen = {}

    def fake_run_jobs(todo, backend, progress=True, after_job=None):
        seen.update(todo=todo, backend=backend, progress=progress)

    replace_backend(fake_run_jobs)
    config = get_experiment("mountaincar").config_cls.for_variant("faithful", episodes=3)
    todo = [jobs.SeedJob.of(config.replace(seed=s), tmp_path / f"seed_{s}") for s in range(4)]
    backends.train_seeds(todo, RunOptions(seed_batch=2, progress=False))
    assert [len(jobs.members(j)) for j in seen["todo"]] == [2, 2] and isinstance(seen["backend"], jobs.InProcess)
    backends.train_seeds(todo, RunOptions(seed_batch=2), pack=False)
    assert seen["todo"] == todo and seen["progress"] is True
