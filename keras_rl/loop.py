"""The episode loop shared by every post: run one seed, write its folder, evaluate a saved policy."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.errors import NonFiniteLossError, RunFolderError
from keras_rl.experiments import Experiment, get_experiment, metric_label
from keras_rl.results import (RunRecorder, atomic_write_json, library_versions, plot_curve, sigint_as_flag,
                              sigint_deferred)
from keras_rl.seeding import configure_tensorflow, seed_everything


def run_seed(experiment: Experiment, config, out_dir: Path, progress: bool = True,
             position: int = 0, threads: int | None = 1, env=None) -> dict[str, Any]:
    """Train one seed to the threshold or the budget; write and return its summary.

    Ctrl-C, a non-finite loss or any other error still leaves ``episodes.csv`` with every
    finished episode and a ``summary.json`` whose ``status`` says how the run ended.
    ``env`` may be passed in (tests wrap envs); by default the experiment makes it.
    """
    configure_tensorflow(threads)
    seed_everything(config.seed)
    env = env if env is not None else experiment.make_env(config)
    env.action_space.seed(config.seed)
    agent = experiment.make_agent(config, env)
    recorder = RunRecorder(Path(out_dir), agent.loss_names)
    recorder.write_config(config.to_dict())
    metric = experiment.make_metric(config)

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.episodes, position=position, leave=position == 0, dynamic_ncols=True,
                   desc=f"{experiment.name}/{config.variant}/{config.framework} seed {config.seed}", unit="ep")

    start = time.perf_counter()
    # A summary from the start: a run killed outright (SIGKILL, power loss) still says so,
    # and no stale summary from an earlier run in this folder survives.
    recorder.write_summary(_summary(experiment, config, metric, recorder, "running", "", None, 0, 0.0))
    with sigint_as_flag() as interrupted:  # Ctrl-C is checked between env steps (see sigint_as_flag)
        return _train(experiment, config, env, agent, recorder, metric, bar, interrupted, start)


def _train(experiment: Experiment, config, env, agent, recorder: RunRecorder, metric, bar, interrupted: list,
           start: float) -> dict[str, Any]:
    """``run_seed``'s episode loop and its final flush."""
    status, message, reached_at, total_steps = "running", "", None, 0
    try:
        for episode in range(1, config.episodes + 1):
            obs, _ = env.reset(seed=config.seed if episode == 1 else None)
            action = agent.begin_episode(obs)
            score, steps = 0.0, 0
            updates_before = agent.updates
            while action is not None:
                obs, reward, terminated, truncated, _ = env.step(action)
                score += float(reward)
                steps += 1
                action = agent.step(float(reward), obs, terminated, truncated)
                if interrupted:
                    raise KeyboardInterrupt
            total_steps += steps
            value = metric.update(score)
            n_updates = agent.updates - updates_before
            losses = {k: (v / n_updates if n_updates else None) for k, v in agent.episode_losses.items()}
            recorder.add_episode({"episode": episode, "steps": steps, "total_steps": total_steps,
                                  "score": score, "metric": value, **losses,
                                  "wall_seconds": time.perf_counter() - start})
            if bar is not None:
                bar.update(1)
                bar.set_postfix(score=f"{score:.1f}", metric=f"{value:.1f}", steps=total_steps, refresh=False)
            if reached_at is None and metric.passes(value, config.threshold):
                reached_at = episode
                if config.stop_at_threshold:
                    break
        status = "completed"
    except KeyboardInterrupt:
        status, message = "interrupted", "stopped by Ctrl-C; the episodes so far are kept"
    except NonFiniteLossError as exc:
        status, message = "non_finite_loss", str(exc)
    except Exception as exc:  # keep what was written, record why, re-raise below
        status, message = "error", f"{type(exc).__name__}: {exc}"
        raise
    finally:
        # A second Ctrl-C (or the one a parent forwards) must not cut the flush short.
        with sigint_deferred(reraise=False):
            if bar is not None:
                bar.close()
            summary = _summary(experiment, config, metric, recorder, status, message, reached_at,
                               total_steps, time.perf_counter() - start)
            recorder.write_summary(summary)
            if status in ("completed", "interrupted"):
                agent.save(recorder.out_dir)
            if recorder.rows:
                plot_curve(recorder.out_dir / "curve.png", recorder.rows, config.threshold,
                           f"{experiment.name} ({config.variant}, {config.framework}), seed {config.seed}",
                           metric_label(experiment, config), metric_in_score_units=experiment.metric_in_score_units)
            env.close()
    return summary


def _summary(experiment: Experiment, config, metric, recorder: RunRecorder, status: str, message: str,
             reached_at: int | None, total_steps: int, wall: float) -> dict[str, Any]:
    rows = recorder.rows
    return {
        "experiment": experiment.name,
        "variant": config.variant,
        "seed": config.seed,
        "status": status,
        "finished": status == "completed",
        "message": message,
        "success": (metric.passes(rows[-1]["metric"], config.threshold)
                    and len(rows) == config.episodes if experiment.success_at_end and rows
                    else reached_at is not None),
        "criterion": (f"metric {metric.comparison} {config.threshold:g} "
                      + (f"after all {config.episodes} episodes" if experiment.success_at_end
                         else f"within {config.episodes} episodes")),
        "reached_at_episode": reached_at,
        "episodes_run": len(rows),
        "budget_episodes": config.episodes,
        "total_steps": total_steps,
        "steps_to_threshold": rows[reached_at - 1]["total_steps"] if reached_at else None,
        "final_metric": rows[-1]["metric"] if rows else None,
        "best_metric": max((r["metric"] for r in rows), default=None),
        "wall_seconds": round(wall, 3),
        **experiment.summary_extras(rows, config),
        "framework": config.framework,
        "command": recorder.command_line(),
        "versions": library_versions(),
    }


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


def evaluate_run(run_dir: Path, episodes: int = 5, gif: Path | None = None, seed: int | None = None,
                 progress: bool = False) -> dict[str, Any]:
    """Reload the saved policy and play greedy episodes, like post 000 §3's test section."""
    from keras_rl.errors import ConfigError

    if episodes <= 0:
        raise ConfigError(f"--episodes must be positive, got {episodes}")
    experiment, config = load_run_config(run_dir)
    configure_tensorflow(1)
    seed = config.seed + 10_000 if seed is None else seed
    seed_everything(seed)
    env = experiment.make_env(config, render_mode="rgb_array" if gif else None)
    agent = experiment.make_agent(config, env)
    agent.load_policy(run_dir)

    scores, frames = [], []
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
        if progress:
            print(f"episode: {episode:3d} | score: {score:.3f}")
    env.close()
    result = {"run_dir": str(run_dir), "episodes": episodes, "seed": seed, "scores": scores,
              "mean": float(np.mean(scores)), "std": float(np.std(scores))}
    if gif:
        from PIL import Image

        gif = Path(gif)
        gif.parent.mkdir(parents=True, exist_ok=True)
        images = [Image.fromarray(f) for f in frames]
        images[0].save(gif, save_all=True, append_images=images[1:], duration=int(1000 / 30), loop=0)
        result["gif"] = str(gif)
    atomic_write_json(Path(run_dir) / "evaluation.json", result)
    return result
