"""Reload a run folder's config and saved policy, and play greedy episodes with it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.registry import build_agent, get_experiment
from keras_rl.runs.files import atomic_write_bytes, atomic_write_json
from keras_rl.runs.signals import sigterm_as_interrupt
from keras_rl.seeding import configure_tensorflow, seed_everything


def load_run_config(run_dir: Path):
    """The experiment and config a run folder was made with, or a RunFolderError."""
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
        raise ConfigError(f"--episodes must be positive, got {episodes}")
    experiment, config = load_run_config(run_dir)
    held = _held_episodes(Path(run_dir) / EVALUATION)
    if held is not None and held > episodes and not overwrite:
        raise ConfigError(
            f"{Path(run_dir) / EVALUATION} holds an evaluation of {held} episodes; this one of "
            f"{episodes} would replace it. Ask for {held} or more, or pass --overwrite"
        )
    configure_tensorflow(1)
    seed = config.seed + 10_000 if seed is None else seed
    seed_everything(seed)
    env = experiment.make_env(config, render_mode="rgb_array" if gif else None)
    agent = build_agent(experiment, config, env)
    agent.load_policy(run_dir)

    scores, frames, interrupted = [], [], False
    try:
        with sigterm_as_interrupt():
            for episode in range(episodes):
                obs, _ = env.reset(seed=seed if episode == 0 else None)
                score, done = 0.0, False
                while not done:
                    if gif and episode == 0:
                        frames.append(env.render())
                    obs, reward, terminated, truncated, _ = env.step(agent.greedy_action(obs))
                    score += float(reward)
                    done = terminated or truncated
                scores.append(score)
                if progress:  # numbered from 1, as episodes.csv numbers them
                    print(f"episode: {episode + 1:3d} | score: {score:.3f}")
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: keep the episodes played so far
        interrupted = True
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
