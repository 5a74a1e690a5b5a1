"""The episode loop shared by every post: train one seed and keep its folder current."""

from __future__ import annotations

import datetime
import math
import time
from pathlib import Path

from keras_rl.errors import NonFiniteLossError
from keras_rl.experiment import Experiment
from keras_rl.registry import build_agent
from keras_rl.runs.files import RunRecorder
from keras_rl.runs.provenance import command_line, library_versions, provenance
from keras_rl.runs.signals import sigint_as_flag, sigint_deferred
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import configure_tensorflow, seed_everything


def run_seed(experiment: Experiment, config, out_dir: Path, progress: bool = True,
             position: int = 0, threads: int | None = 1, env=None) -> RunSummary:
    """Train one seed to the threshold or the budget; write and return its summary.

    Ctrl-C, a non-finite loss or any other error still leaves ``episodes.csv`` with every
    finished episode and a ``summary.json`` whose ``status`` says how the run ended; the
    summary is rewritten after every episode, so even a killed run's summary counts the
    episodes on disk. ``env`` may be passed in (tests wrap envs); by default the
    experiment makes it.
    """
    configure_tensorflow(threads)
    seed_everything(config.seed)
    env = env if env is not None else experiment.make_env(config)
    env.action_space.seed(config.seed)
    agent = build_agent(experiment, config, env)
    recorder = RunRecorder(Path(out_dir), agent.loss_names)
    recorder.write_config(config.to_dict())
    metric = experiment.make_metric(config)
    run = _Run(experiment, config, recorder, metric)

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.episodes, position=position, leave=position == 0, dynamic_ncols=True,
                   desc=f"{experiment.name}/{config.variant}/{config.framework} seed {config.seed}", unit="ep")

    # A summary from the start: no stale summary from an earlier run in this folder survives.
    run.summary("running").write(recorder.out_dir)
    with sigint_as_flag() as interrupted:  # Ctrl-C is checked between env steps (see sigint_as_flag)
        return _train(run, env, agent, bar, interrupted)


class _Run:
    """One seed's bookkeeping: its rows, its metric and the summary they make."""

    def __init__(self, experiment: Experiment, config, recorder: RunRecorder, metric):
        self.experiment, self.config, self.recorder, self.metric = experiment, config, recorder, metric
        self.start = time.perf_counter()
        self.provenance = {**provenance(), "started_at": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds")}
        self.versions = library_versions(config.framework)
        self.reached_at: int | None = None
        self.total_steps = 0

    def summary(self, status: str, message: str = "") -> RunSummary:
        c, rows, metric = self.config, self.recorder.rows, self.metric
        at_end = self.experiment.success_at_end
        finite = [r["metric"] for r in rows if r["metric"] is not None and math.isfinite(r["metric"])]
        best = (min if metric.comparison in ("<", "<=") else max)(finite, default=None)
        return RunSummary(
            experiment=self.experiment.name, variant=c.variant, seed=c.seed, status=status, message=message,
            success=(metric.passes(rows[-1]["metric"], c.threshold) and len(rows) == c.episodes if at_end and rows
                     else self.reached_at is not None),
            criterion=(f"metric {metric.comparison} {c.threshold:g} "
                       + (f"after all {c.episodes} episodes" if at_end else f"within {c.episodes} episodes")),
            reached_at_episode=self.reached_at, episodes_run=len(rows), budget_episodes=c.episodes,
            total_steps=self.total_steps,
            steps_to_threshold=rows[self.reached_at - 1]["total_steps"] if self.reached_at else None,
            final_metric=rows[-1]["metric"] if rows else None, best_metric=best,
            wall_seconds=round(time.perf_counter() - self.start, 3), framework=c.framework,
            command=command_line(), versions=self.versions, provenance=self.provenance,
            extras=self.experiment.summary_extras(rows, c))


def _train(run: _Run, env, agent, bar, interrupted: list) -> RunSummary:
    """``run_seed``'s episode loop and its final flush."""
    config, metric, recorder = run.config, run.metric, run.recorder
    status, message = "running", ""
    try:
        for episode in range(1, config.episodes + 1):
            obs, _ = env.reset(seed=config.seed if episode == 1 else None)
            action = agent.begin_episode(obs)
            score, steps = 0.0, 0
            while action is not None:
                obs, reward, terminated, truncated, _ = env.step(action)
                score += float(reward)
                steps += 1
                action = agent.step(float(reward), obs, terminated, truncated)
                if interrupted:
                    raise KeyboardInterrupt
            stats = agent.end_episode()
            run.total_steps += steps
            value = metric.update(score)
            recorder.add_episode({"episode": episode, "steps": steps, "total_steps": run.total_steps,
                                  "score": score, "metric": value, **stats.mean_losses,
                                  "wall_seconds": time.perf_counter() - run.start})
            if run.reached_at is None and metric.passes(value, config.threshold):
                run.reached_at = episode
            run.summary("running").write(recorder.out_dir)
            if bar is not None:
                bar.update(1)
                bar.set_postfix(score=f"{score:.1f}", metric=f"{value:.1f}", steps=run.total_steps, refresh=False)
            if run.reached_at is not None and config.stop_at_threshold:
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
            if status in ("completed", "interrupted"):
                try:
                    agent.save(recorder.out_dir)
                except Exception as exc:  # disk full, permissions: no summary may claim success
                    status, message = "error", f"could not save the weights in {recorder.out_dir}: {exc}"
            summary = run.summary(status, message)
            summary.write(recorder.out_dir)
            env.close()
    return summary
