"""The episode loop shared by every post: train one seed and keep its folder current."""

from __future__ import annotations

import copy
import datetime
import json
import math
import time
from pathlib import Path
from typing import Any, Callable

from keras_rl.errors import ConfigError, NonFiniteLossError
from keras_rl.experiment import Experiment
from keras_rl.registry import build_agent
from keras_rl.rngs import global_rng_state, rng_state, set_global_rng_state, set_rng_state
from keras_rl.runs.checkpoint import CHECKPOINT, read_checkpoint, write_checkpoint
from keras_rl.runs.files import RunRecorder, atomic_write_text, episode_columns, episodes_csv_text
from keras_rl.runs.provenance import command_line, library_versions, provenance
from keras_rl.runs.signals import signal_name, stop_signals_as_flag, stop_signals_deferred
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import configure_tensorflow, seed_everything


def run_seed(experiment: Experiment, config, out_dir: Path, progress: bool = True,
             position: int = 0, threads: int | None = 1, env=None, resume: bool = False,
             checkpoint_every: int = 10, tensorboard: Path | None = None,
             should_stop: Callable[[], bool] | None = None, command: str | None = None) -> RunSummary:
    """Train one seed to the threshold or the budget; write and return its summary.

    Ctrl-C, SIGTERM, a non-finite loss or any other error still leaves ``episodes.csv``
    with every finished episode and a ``summary.json`` whose ``status`` says how the run
    ended; the summary is rewritten after every episode, so even a killed run's summary
    counts the episodes on disk. Every ``checkpoint_every`` episodes, and when a signal
    stops the run, the state at the last episode boundary goes to ``checkpoint.pkl``;
    ``resume=True`` continues from it. ``env`` may be passed in (tests wrap envs).
    ``should_stop`` is asked after every episode; True stops the run as a signal would (a
    distributed backend's stop flag). ``command`` is the command line to record (a job run
    elsewhere carries its driver's; by default this process's).
    """
    configure_tensorflow(threads)
    seed_everything(config.seed)
    env = env if env is not None else experiment.make_env(config)
    env.action_space.seed(config.seed)
    agent = build_agent(experiment, config, env)
    recorder = RunRecorder(Path(out_dir), agent.loss_names)
    metric = experiment.make_metric(config)
    run = SeedRun(experiment, config, recorder, metric, command)
    if resume:
        run.restore(read_checkpoint(recorder.out_dir), agent, env)
    else:
        recorder.write_config(config.to_dict())
    writer = _TensorBoard(tensorboard, config) if tensorboard else None

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.episodes, initial=len(recorder.rows), position=position, leave=position == 0,
                   dynamic_ncols=True, unit="ep",
                   desc=f"{experiment.name}/{config.variant}/{config.framework} seed {config.seed}")

    # A summary from the start: no stale summary from an earlier run in this folder survives.
    run.summary("running").write(recorder.out_dir)
    with stop_signals_as_flag() as interrupted:  # checked between env steps (see stop_signals_as_flag)
        return _train(run, env, agent, bar, interrupted, checkpoint_every, writer, should_stop)


class SeedRun:
    """One seed's bookkeeping: its rows, its metric, its counters and the summary they make."""

    def __init__(self, experiment: Experiment, config, recorder: RunRecorder, metric, command: str | None = None):
        self.experiment, self.config, self.recorder, self.metric = experiment, config, recorder, metric
        self.command = command or command_line()
        self.start = time.perf_counter()
        self.provenance = {**provenance(), "started_at": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds")}
        self.versions = library_versions(config.framework)
        self.reached_at: int | None = None
        self.total_steps = 0
        self.snapshot: dict[str, Any] | None = None

    # -- checkpoints ----------------------------------------------------------------------
    def capture(self, agent, env) -> None:
        """The state at this episode boundary, kept in memory (written by ``save``)."""
        self.snapshot = {
            "config": self.config.to_dict(), "rows": list(self.recorder.rows), "reached_at": self.reached_at,
            "total_steps": self.total_steps, "elapsed": time.perf_counter() - self.start,
            "metric": copy.deepcopy(self.metric), "agent": agent.state_dict(),
            "env_rng": rng_state(env.unwrapped.np_random), "action_space_rng": rng_state(env.action_space.np_random),
            "global_rng": global_rng_state()}

    def save(self) -> None:
        if self.snapshot is not None:
            write_checkpoint(self.recorder.out_dir, self.snapshot)

    def restore(self, state: dict[str, Any], agent, env) -> None:
        wanted = json.loads(json.dumps(self.config.to_dict()))
        theirs = json.loads(json.dumps(state["config"]))
        differing = sorted(k for k in wanted if theirs.get(k) != wanted[k])
        if differing:
            k = differing[0]
            raise ConfigError(f"--resume: the checkpoint in {self.recorder.out_dir} was made with {k}={theirs.get(k)!r}, "
                              f"this command asks for {wanted[k]!r}; resume with the same options")
        if getattr(self.config, "learning_phase_training", False):
            raise ConfigError("--resume does not cover learning_phase_training=true (its noise layer draws from "
                              "TensorFlow's generator, which checkpoints do not hold)")
        agent.load_state_dict(state["agent"])
        self.metric.__dict__.update(state["metric"].__dict__)
        set_rng_state(env.unwrapped.np_random, state["env_rng"])
        set_rng_state(env.action_space.np_random, state["action_space_rng"])
        set_global_rng_state(state["global_rng"])
        self.recorder.rows = list(state["rows"])
        self.reached_at, self.total_steps = state["reached_at"], int(state["total_steps"])
        self.start = time.perf_counter() - float(state["elapsed"])
        # episodes played after the checkpoint are played again, so they leave the CSV
        atomic_write_text(self.recorder.out_dir / "episodes.csv",
                          episodes_csv_text(self.recorder.rows, episode_columns(self.recorder.loss_names)))
        self.snapshot = state

    # -- episodes and the summary ------------------------------------------------------------
    def record_episode(self, episode: int, score: float, steps: int, stats) -> dict[str, Any]:
        """An episode's row into ``episodes.csv``, the threshold check, and a current
        ``summary.json``; returns the row."""
        self.total_steps += steps
        value = self.metric.update(score)
        row = {"episode": episode, "steps": steps, "total_steps": self.total_steps, "score": score, "metric": value,
               **stats.mean_losses, "wall_seconds": time.perf_counter() - self.start}
        self.recorder.add_episode(row)
        if self.reached_at is None and self.metric.passes(value, self.config.threshold):
            self.reached_at = episode
        self.summary("running").write(self.recorder.out_dir)
        return row

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
            command=self.command, versions=self.versions, provenance=self.provenance,
            extras=self.experiment.summary_extras(rows, c))


class _TensorBoard:
    """Per-episode score, metric and losses as TensorBoard scalars, one run folder per seed."""

    def __init__(self, root: Path, config):
        import tensorflow as tf

        self.tf = tf
        self.writer = tf.summary.create_file_writer(
            str(Path(root) / f"{config.experiment}-{config.variant}-{config.framework}-seed{config.seed}"))

    def episode(self, row: dict[str, Any]) -> None:
        with self.writer.as_default():
            for key, value in row.items():
                if key not in ("episode", "wall_seconds") and value is not None and math.isfinite(value):
                    self.tf.summary.scalar(key, value, step=row["episode"])
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


def _train(run: SeedRun, env, agent, bar, interrupted: list, checkpoint_every: int, writer,
           should_stop: Callable[[], bool] | None = None) -> RunSummary:
    """``run_seed``'s episode loop and its final flush."""
    config, recorder = run.config, run.recorder
    status, message = "running", ""
    try:
        for episode in range(len(recorder.rows) + 1, config.episodes + 1):
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
            row = run.record_episode(episode, score, steps, agent.end_episode())
            if writer is not None:
                writer.episode(row)
            run.capture(agent, env)
            if checkpoint_every and episode % checkpoint_every == 0:
                run.save()
            if bar is not None:
                bar.update(1)
                bar.set_postfix(score=f"{score:.1f}", metric=f"{row['metric']:.1f}", steps=run.total_steps,
                                refresh=False)
            if interrupted or (should_stop is not None and should_stop()):
                raise KeyboardInterrupt
            if run.reached_at is not None and config.stop_at_threshold:
                break
        status = "completed"
    except KeyboardInterrupt:
        status = "interrupted"
        by = signal_name(interrupted) if interrupted else "the dispatcher's stop request (Ctrl-C or SIGTERM)"
        message = f"stopped by {by}; the episodes so far are kept (--resume continues)"
    except NonFiniteLossError as exc:
        status, message = "non_finite_loss", str(exc)
    except Exception as exc:  # keep what was written, record why, re-raise below
        status, message = "error", f"{type(exc).__name__}: {exc}"
        raise
    finally:
        # A second signal (or the one a parent forwards) must not cut the flush short.
        with stop_signals_deferred(reraise=False):
            if bar is not None:
                bar.close()
            if writer is not None:
                writer.close()
            status, message = _flush(run, agent, status, message)
            summary = run.summary(status, message)
            summary.write(recorder.out_dir)
            env.close()
    return summary


def _flush(run: SeedRun, agent, status: str, message: str) -> tuple[str, str]:
    """Weights and checkpoint at the end of a run; a failed write makes the run an error
    that names the file, so no summary claims success for a run whose files are missing."""
    out = run.recorder.out_dir
    try:
        if status in ("completed", "interrupted"):
            agent.save(out)
        if status == "interrupted":
            run.save()
        elif status == "completed":
            (out / CHECKPOINT).unlink(missing_ok=True)
    except Exception as exc:  # disk full, permissions
        return "error", f"could not write the run's files in {out}: {type(exc).__name__}: {exc}"
    return status, message
