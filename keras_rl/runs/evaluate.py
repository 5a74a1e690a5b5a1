"""Greedy episodes of a run's policy: ``evaluate`` on a saved run, and evaluations during
training (``reproduce --eval-every``). Nothing heavy is imported at the top: the CLI reads
``EvalSchedule`` before TensorFlow loads, so bad input is refused at once."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.atomic import atomic_write_bytes, atomic_write_json
from keras_rl.errors import ConfigError, RunFolderError, argument
from keras_rl.runs.files import run_folder_locks
from keras_rl.runs.signals import stop_signals_as_flag


def load_run_config(run_dir: Path):
    """The experiment and config a run folder was made with, or a RunFolderError."""
    from keras_rl.registry import get_experiment

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunFolderError(f"run folder {str(run_dir)!r} does not exist")
    path = run_dir / "config.json"
    if not path.is_file():
        raise RunFolderError(f"{run_dir} has no config.json; is it a run folder (one seed)?")
    try:
        values = json.loads(path.read_text())
        experiment = get_experiment(values["experiment"])
        return experiment, experiment.config_cls.from_dict(values)
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise RunFolderError(f"{path} is corrupt: {exc}") from None


EVALUATION = "evaluation.json"
INTERRUPTED = "evaluation.interrupted.json"


def evaluate_run(
    run_dir: Path,
    episodes: int = 5,
    gif: Path | None = None,
    seed: int | None = None,
    progress: bool = False,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Reload the saved policy and play greedy episodes, like post 000 §3's test section.

    The result goes to ``evaluation.json``. An evaluation of more episodes already there
    (post 001's ``fixed`` criterion reads a 100-episode one) is kept: a shorter one is
    refused before anything plays unless ``overwrite``. An interrupted evaluation never
    replaces a finished one: it goes to ``evaluation.interrupted.json``."""
    if episodes <= 0:
        raise ConfigError(f"{argument('episodes')} must be positive, got {episodes}")
    load_run_config(run_dir)  # a clear error for a folder that is not a run, before any lock file
    with run_folder_locks([Path(run_dir)]):  # a command extending the run would change its weights
        return _evaluate_held(Path(run_dir), episodes, gif, seed, progress, overwrite)


def _stopped_before_weights(run_dir: Path) -> str | None:
    """Why a run holds no weights, where its summary says: it stopped at a NaN loss."""
    from keras_rl.runs.summary import RunSummary

    try:
        summary = RunSummary.read(run_dir)
    except RunFolderError:
        return None
    if summary.status != "non_finite_loss":
        return None
    return (
        f"{run_dir} stopped at a NaN loss ({summary.message or 'non-finite loss'}) before saving "
        "weights: there is no policy to evaluate"
    )


def _evaluate_held(
    run_dir: Path, episodes: int, gif: Path | None, seed: int | None, progress: bool, overwrite: bool
) -> dict[str, Any]:
    from keras_rl.registry import build_agent
    from keras_rl.seeding import configure_tensorflow, seed_everything

    experiment, config = load_run_config(run_dir)
    held = _held_episodes(Path(run_dir) / EVALUATION)
    if held is not None and held > episodes and not overwrite:
        raise ConfigError(
            f"{Path(run_dir) / EVALUATION} holds an evaluation of {held} episodes; this one of "
            f"{episodes} would replace it. Ask for {held} or more, or pass {argument('overwrite')}"
        )
    configure_tensorflow(1)
    if gif:  # off-screen frames: SDL needs no display, and says nothing about XDG_RUNTIME_DIR
        import os

        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    seed = config.seed + 10_000 if seed is None else seed
    seed_everything(seed)
    env = experiment.make_env(config, render_mode="rgb_array" if gif else None)
    agent = build_agent(experiment, config, env)
    try:
        agent.load_policy(run_dir)
    except RunFolderError:
        why = _stopped_before_weights(run_dir)
        if why is None:
            raise
        raise RunFolderError(why) from None

    scores, frames, raised = [], [], False
    # Ctrl-C or SIGTERM is taken between env steps, as training takes it (one raised inside
    # TensorFlow's C++ code would surface as a SystemError): the episodes played so far are kept.
    # A KeyboardInterrupt raised all the same (outside the main thread, signals are not ours) too.
    with stop_signals_as_flag() as stopped:
        try:
            for episode in range(episodes):
                obs, _ = env.reset(seed=seed if episode == 0 else None)
                score, done = 0.0, False
                while not done and not stopped:
                    if gif and episode == 0:
                        frames.append(env.render())
                    obs, reward, terminated, truncated, _ = env.step(agent.greedy_action(obs))
                    score += float(reward)
                    done = terminated or truncated
                if stopped:  # the episode cut short is not one of the played ones
                    break
                scores.append(score)
                if progress:  # numbered from 1, as episodes.csv numbers them
                    print(f"episode: {episode + 1:3d} | score: {score:.3f}")
        except KeyboardInterrupt:
            raised = True
    interrupted = bool(stopped) or raised
    env.close()
    result = {
        "run_dir": str(run_dir),
        "episodes": len(scores),
        "episodes_asked": episodes,
        "seed": seed,
        "scores": scores,
        "mean": float(np.mean(scores)) if scores else None,
        "std": float(np.std(scores)) if scores else None,
        "interrupted": interrupted,
    }
    if gif and frames and (scores or interrupted):
        import io

        from PIL import Image

        buf = io.BytesIO()
        images = [Image.fromarray(f) for f in frames]
        images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / 30), loop=0)
        atomic_write_bytes(Path(gif), buf.getvalue())
        result["gif"] = str(gif)
    target = Path(run_dir) / (INTERRUPTED if interrupted and held is not None else EVALUATION)
    atomic_write_json(target, result)
    result["written"] = str(target)
    return result


def _held_episodes(path: Path) -> int | None:
    """How many episodes the finished evaluation at ``path`` played (None: none there)."""
    if not path.is_file():
        return None
    try:
        held = json.loads(path.read_text())
        return None if held.get("interrupted") else int(held["episodes"])
    except (ValueError, KeyError, TypeError, AttributeError):
        raise RunFolderError(f"{path} is corrupt; move it aside to evaluate again") from None


# -- evaluation during training (``reproduce --eval-every N --eval-episodes K``) ----------------

EVALUATIONS = "evaluations.csv"
BEST = "best"
EVAL_SEED_OFFSET = 10_000  # the same start states as ``evaluate`` plays by default


@dataclass(frozen=True)
class EvalSchedule:
    """Greedy evaluations during training: ``episodes`` greedy episodes after every ``every``-th
    training episode, on an env of their own."""

    every: int
    episodes: int = 10

    def __post_init__(self) -> None:
        if self.every < 1:
            raise ConfigError(f"{argument('eval_every')} must be at least 1, got {self.every}")
        if self.episodes < 1:
            raise ConfigError(f"{argument('eval_episodes')} must be at least 1, got {self.episodes}")


class TrainingEvaluator:
    """One seed's evaluations during training.

    Each evaluation plays ``episodes`` greedy episodes on an env of its own, reset with seeds
    ``seed + 10000 + i`` (the same start states every time, so evaluations compare), through
    the training agent's greedy action (no exploration, no update). Nothing of the training
    streams is touched: its env, buffers, explorers and learner are not used but to read the
    policy, and Python's and NumPy's global generators are restored afterwards
    (``tests/test_evaluation_during_training.py`` shows ``episodes.csv`` unchanged). Each
    evaluation is a row of ``evaluations.csv``; the best mean so far keeps its weights in
    ``best/`` (with ``best.json``), beside the final ones."""

    COLUMNS = ("episode", "mean", "std", "min", "max", "best")

    def __init__(self, experiment, config, run_dir: Path, schedule: EvalSchedule):
        if getattr(config, "learning_phase_training", False):
            raise ConfigError(
                f"{argument('eval_every')} does not cover learning_phase_training=true: its noise layer draws from "
                "TensorFlow's generator when the policy acts, which would change the training run"
            )
        self.schedule, self.run_dir = schedule, Path(run_dir)
        self.seed = config.seed + EVAL_SEED_OFFSET
        from keras_rl.rngs import global_rng_state, set_global_rng_state

        held = global_rng_state()
        self.env = experiment.make_env(config)  # its own env: the training env's generators stay untouched
        set_global_rng_state(held)
        self.rows: list[dict[str, Any]] = []

    @property
    def best_mean(self) -> float | None:
        return max((r["mean"] for r in self.rows), default=None)

    def due(self, episode: int) -> bool:
        return episode % self.schedule.every == 0

    def evaluate(self, episode: int, greedy, save_policy, writer=None) -> dict[str, Any]:
        """Play the greedy episodes after training episode ``episode``; ``greedy(obs)`` is the
        policy's action, ``save_policy(folder)`` writes its weights there."""
        from keras_rl.rngs import global_rng_state, set_global_rng_state

        held = global_rng_state()
        scores = []
        try:
            for i in range(self.schedule.episodes):
                obs, _ = self.env.reset(seed=self.seed + i)
                score, done = 0.0, False
                while not done:
                    obs, reward, terminated, truncated, _ = self.env.step(greedy(obs))
                    score += float(reward)
                    done = terminated or truncated
                scores.append(score)
        finally:
            set_global_rng_state(held)
        mean = float(np.mean(scores))
        best = self.best_mean is None or mean > self.best_mean
        row = {
            "episode": episode,
            "mean": mean,
            "std": float(np.std(scores)),
            "min": float(np.min(scores)),
            "max": float(np.max(scores)),
            "best": int(best),
        }
        self.rows.append(row)
        self._write_rows()
        if best:
            self._keep_best(row, scores, save_policy)
        if writer is not None:
            writer.scalars({"eval_mean": mean}, episode)
        return row

    def _write_rows(self) -> None:
        from keras_rl.atomic import atomic_write_text

        lines = [",".join(self.COLUMNS)] + [",".join(repr(r[c]) for c in self.COLUMNS) for r in self.rows]
        atomic_write_text(self.run_dir / EVALUATIONS, "\n".join(lines) + "\n")

    def _keep_best(self, row: dict[str, Any], scores: list[float], save_policy) -> None:
        """The weights into a fresh folder, then swapped in for ``best/``: never half of two."""
        import shutil
        import tempfile

        staging = Path(tempfile.mkdtemp(prefix=".tmp-best-", dir=self.run_dir))
        save_policy(staging)
        atomic_write_json(staging / "best.json", {**row, "scores": scores, "seed": self.seed})
        target = self.run_dir / BEST
        old = self.run_dir / ".tmp-best-old"
        if target.exists():
            target.rename(old)
        staging.rename(target)
        shutil.rmtree(old, ignore_errors=True)

    def resume(self, episodes_played: int) -> None:
        """After ``--resume``: the evaluations of the episodes the checkpoint holds (later ones
        are played again, so they leave the file), and ``best/`` only if it is one of them."""
        path = self.run_dir / EVALUATIONS
        if path.is_file():
            import csv

            with open(path, newline="") as fh:
                parsed = [
                    {"episode": int(r["episode"]), **{c: float(r[c]) for c in ("mean", "std", "min", "max")}}
                    for r in csv.DictReader(fh)
                ]
            best: float | None = None
            for r in parsed:
                if r["episode"] <= episodes_played:
                    r["best"] = int(best is None or r["mean"] > best)
                    best = r["mean"] if r["best"] else best
                    self.rows.append(r)
            self._write_rows()
        marker = self.run_dir / BEST / "best.json"
        if marker.is_file() and json.loads(marker.read_text())["episode"] > episodes_played:
            import shutil

            shutil.rmtree(self.run_dir / BEST)

    def close(self) -> None:
        self.env.close()
