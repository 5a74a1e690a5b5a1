"""One seed's life, the same on every engine.

An engine computes the steps (the Gymnasium loop steps envs over a seed axis, ``train/loop.py``;
the compiled engine runs a program per episode or chunk, ``train/compiled.py``; the vectorised
engine steps a batch of seeds in PyTorch, ``train/vectorised.py``) and supplies its own state
for a checkpoint. Everything else a run folder shows, and the whole life around the steps, is
written here, once:

- ``SeedRecords``: the rows of ``episodes.csv``, the metric, the counters and the ``summary.json``
  they make, and their part of a checkpoint;
- ``SeedLife``: a seed's status, its start (``config.json``, a running summary, TensorBoard), its
  resume and the extension rule (``SeedLife.resume``, ``SeedLife.extends``), what the end of
  an episode does (``SeedLife.end_episode``: the row, TensorBoard, evaluation, progress, the
  stop rule), why it stops on a signal (``interruption``), which checkpoint it leaves at the end
  (``checkpoint_at_close``) and its last word (``SeedLife.flush``: weights, final summary);
- ``live``: a job's run under signals, and ``stop_requested``, the interrupt check between steps;
- ``Checkpoints``: a job's checkpoint envelope, its cadence, and reading it back; and
  ``close_lives``: how a job ends, its checkpoints kept, written or removed;
- ``progress_bar`` and ``TensorBoardWriter``.
"""

from __future__ import annotations

import datetime
import math
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal

from keras_rl.atomic import atomic_write_text
from keras_rl.experiment import Experiment
from keras_rl.rngs import global_rng_state, set_global_rng_state
from keras_rl.runs.checkpoint import VERSION, delete_checkpoints, read_batch_checkpoints, write_checkpoint
from keras_rl.runs.evaluate import TrainingEvaluator
from keras_rl.runs.files import RunRecorder, episode_columns, episodes_csv_text
from keras_rl.runs.lifecycle import check_checkpoint_engine, check_resume_config
from keras_rl.runs.provenance import command_line, library_versions, provenance
from keras_rl.runs.signals import signal_name
from keras_rl.runs.summary import RunSummary, Status
from keras_rl.train.settings import TrainSettings


class SeedRecords:
    """One seed's bookkeeping: its rows, its metric, its counters and the summary they make."""

    def __init__(self, experiment: Experiment, config, recorder: RunRecorder, metric, command: str | None = None):
        self.experiment, self.config, self.recorder, self.metric = experiment, config, recorder, metric
        self.command = command or command_line()
        self.start = time.perf_counter()
        self.provenance = {
            **provenance(),
            "started_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        }
        self.versions = library_versions(config.framework)
        if config.framework == "torch":
            from keras_rl.torch import PORTABLE_CAPS, portable_arithmetic

            if portable_arithmetic():  # what the replay tests use where a host has no reference of its own
                self.provenance["portable_torch"] = {**PORTABLE_CAPS, "optimizer_step": "fused"}
        self.reached_at: int | None = None
        self.total_steps = 0

    def record_episode(self, episode: int, score: float, steps: int, stats) -> dict[str, Any]:
        """An episode's row into ``episodes.csv``, the threshold check, and a current
        ``summary.json``; returns the row."""
        self.total_steps += steps
        value = self.metric.update(score)
        row = {
            "episode": episode,
            "steps": steps,
            "total_steps": self.total_steps,
            "score": score,
            "metric": value,
            **stats.mean_losses,
            "wall_seconds": time.perf_counter() - self.start,
        }
        self.recorder.add_episode(row)
        if self.reached_at is None and self.metric.passes(value, self.config.threshold):
            self.reached_at = episode
        self.summary("running").write(self.recorder.out_dir)
        return row

    def snapshot(self, status: Status, message: str) -> dict[str, Any]:
        """The records' part of a checkpoint, any engine's: an interrupted run is running as
        far as the checkpoint goes."""
        return {
            "config": self.config.to_dict(),
            "rows": list(self.recorder.rows),
            "reached_at": self.reached_at,
            "total_steps": self.total_steps,
            "elapsed": time.perf_counter() - self.start,
            "metric": self.metric,
            "status": "running" if status == "interrupted" else status,
            "message": "" if status == "interrupted" else message,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """``snapshot``'s records back (the caller has checked the config: ``check_resume_config``)."""
        self.metric.__dict__.update(state["metric"].__dict__)
        self.recorder.rows = list(state["rows"])
        self.reached_at, self.total_steps = state["reached_at"], int(state["total_steps"])
        self.start = time.perf_counter() - float(state["elapsed"])

    def summary(self, status: Status, message: str = "") -> RunSummary:
        c, rows, metric = self.config, self.recorder.rows, self.metric
        at_end = self.experiment.success_at_end
        finite = [r["metric"] for r in rows if r["metric"] is not None and math.isfinite(r["metric"])]
        best = (min if metric.comparison in ("<", "<=") else max)(finite, default=None)
        return RunSummary(
            experiment=self.experiment.name,
            variant=c.variant,
            seed=c.seed,
            status=status,
            message=message,
            success=(
                metric.passes(rows[-1]["metric"], c.threshold) and len(rows) == c.episodes
                if at_end and rows
                else self.reached_at is not None
            ),
            criterion=(
                f"metric {metric.comparison} {c.threshold:g} "
                + (f"after all {c.episodes} episodes" if at_end else f"within {c.episodes} episodes")
            ),
            reached_at_episode=self.reached_at,
            episodes_run=len(rows),
            budget_episodes=c.episodes,
            total_steps=self.total_steps,
            steps_to_threshold=rows[self.reached_at - 1]["total_steps"] if self.reached_at else None,
            final_metric=rows[-1]["metric"] if rows else None,
            best_metric=best,
            wall_seconds=round(time.perf_counter() - self.start, 3),
            framework=c.framework,
            command=self.command,
            versions=self.versions,
            provenance=self.provenance,
            extras=self.experiment.summary_extras(rows, c),
        )


class SeedLife:
    """One seed's status and files from its start to its last word, whatever engine steps it."""

    def __init__(self, experiment: Experiment, config, out_dir: Path, loss_names, settings: TrainSettings):
        self.experiment, self.config, self.settings = experiment, config, settings
        self.recorder = RunRecorder(out_dir, loss_names)
        self.records = SeedRecords(experiment, config, self.recorder, experiment.make_metric(config), settings.command)
        self.status: Status = "running"
        self.message = ""
        self.episode = 0
        """The episode being played (the loop) or last played (the compiled engine)."""
        self.saved = False
        self.extending = False
        """Resumed past the budget it completed (``--resume --episodes N``)."""
        self.final: RunSummary | None = None
        """The summary written when the seed stopped (its wall time ends there)."""
        self.writer: TensorBoardWriter | None = None
        self.evaluator: TrainingEvaluator | None = (
            TrainingEvaluator(experiment, config, self.recorder.out_dir, settings.evaluation)
            if settings.evaluation is not None
            else None
        )

    @property
    def out_dir(self) -> Path:
        return self.recorder.out_dir

    @property
    def active(self) -> bool:
        return self.status == "running"

    def finish(self, status: Status, message: str = "") -> None:
        self.status, self.message = status, message

    @property
    def stopped_early(self) -> bool:
        """It met its threshold in a run that stops there: a straight run of any budget stops there too."""
        return self.records.reached_at is not None and self.config.stop_at_threshold

    @property
    def ended_on_budget(self) -> bool:
        """Completed by playing its whole budget, not stopped at the threshold: a larger budget continues it."""
        return self.status == "completed" and self.episode == self.config.episodes and not self.stopped_early

    def extends(self, played: int, budget_then: int) -> bool:
        """The extension rule: a run that completed by playing its whole budget (``budget_then``
        episodes, ``played`` of them) goes on when resumed with a larger one, from the state it
        ended in; one stopped at its threshold stays as it is."""
        return self.status == "completed" and played == budget_then < self.config.episodes and not self.stopped_early

    # -- its part of a checkpoint ----------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """The seed's part of a checkpoint: its records (``SeedRecords.snapshot``), the episode
        and whether its weights were saved. An engine that keeps more of a seed outside its own
        state (the loop's env mid-episode) adds it here, and takes it back in ``restore``."""
        return {
            **self.records.snapshot(self.status, self.message),
            "episode": self.episode,
            "saved": self.saved,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """``snapshot``'s part back (``resume``)."""
        self.resume(state)

    # -- start ----------------------------------------------------------------------------------
    def resume(self, state: dict[str, Any]) -> None:
        """The resume rule: a checkpoint's records back (``SeedRecords.snapshot`` with the seed's
        ``episode`` and ``saved``), its config checked against this one (only the budget may
        grow), the extension rule applied, and the episodes played after it removed from
        ``episodes.csv`` (they are played again); a seed that had finished keeps its files."""
        wanted, theirs = self.config.to_dict(), state["config"]
        played = len(state["rows"])
        check_resume_config(self.out_dir, wanted, theirs, played)
        self.records.restore(state)
        self.status, self.message = state["status"], state["message"]
        self.episode, self.saved = int(state["episode"]), bool(state["saved"])
        print(
            f"seed {self.config.seed}: resumed in {self.out_dir} after episode {played} "
            f"(its checkpoint; {int(state['total_steps'])} steps)",
            file=sys.stderr,
        )
        if self.extends(played, int(theirs["episodes"])):
            self.status, self.message, self.saved, self.extending = "running", "", False, True
        if self.active:
            atomic_write_text(
                self.out_dir / "episodes.csv",
                episodes_csv_text(self.recorder.rows, episode_columns(self.recorder.loss_names)),
            )
            if self.evaluator is not None:
                self.evaluator.resume(played)
        else:  # it had finished before the checkpoint: its files stay as they are
            self.final = RunSummary.read(self.out_dir)

    def start(self) -> None:
        """A running seed's ``config.json`` (its budget may have grown), a summary from the start
        (no stale one from an earlier run survives) and its TensorBoard writer."""
        if not self.active:
            return
        self.recorder.write_config(self.config.to_dict())
        self.records.summary("running").write(self.out_dir)
        if self.settings.tensorboard:
            self.writer = TensorBoardWriter(self.settings.tensorboard, self.config)

    # -- each episode -----------------------------------------------------------------------------
    def end_episode(self, score: float, steps: int, stats, greedy, save_policy, bar) -> bool:
        """Episode ``self.episode`` ended: its row, TensorBoard, evaluation, progress, and the
        stop rule (the threshold where the run stops there, or the budget). False where the
        seed has completed."""
        row = self.records.record_episode(self.episode, score, steps, stats)
        if self.writer is not None:
            self.writer.episode(row)
        if self.evaluator is not None and self.evaluator.due(self.episode):
            self.evaluator.evaluate(self.episode, greedy, save_policy, self.writer)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(score=f"{row['score']:.1f}", metric=f"{row['metric']:.1f}", refresh=False)
        if self.stopped_early or self.episode >= self.config.episodes:
            self.finish("completed")
            return False
        return True

    # -- the end ------------------------------------------------------------------------------------
    def flush(self, save: Callable[[Path], None]) -> RunSummary:
        """The seed's last word: its weights (when it finished or was stopped), its TensorBoard
        closed and its final summary; a failed write makes the run an error that names the
        folder, so no summary claims success for a run whose files are missing."""
        if self.status in ("completed", "interrupted") and not self.saved:
            try:
                save(self.out_dir)
                self.saved = True
            except Exception as exc:  # disk full, permissions
                self.finish("error", f"could not write the run's files in {self.out_dir}: {type(exc).__name__}: {exc}")
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        self.final = self.records.summary(self.status, self.message)
        self.final.write(self.out_dir)
        return self.final


def live(
    experiment: Experiment,
    configs: list,
    lives: Sequence[SeedLife],
    settings: TrainSettings,
    loop: Callable[[list, Any], None],
    close: Callable[[], object],
) -> list[RunSummary]:
    """Every engine's run of a job: each seed started, the engine's ``loop(interrupted, bar)``
    under Ctrl-C and SIGTERM taken as a flag (checked between steps), an error recorded in each
    running seed's summary and raised, and ``close()`` run however it ends (a second signal
    cannot cut it short). Each seed's final summary, in order."""
    from keras_rl.runs.signals import stop_signals_as_flag, stop_signals_deferred

    for s in lives:
        s.start()
    bar = progress_bar(experiment, configs, lives, settings.position) if settings.progress else None
    try:
        with stop_signals_as_flag() as interrupted:
            loop(interrupted, bar)
    except Exception as exc:  # keep what was written, record why, re-raise
        for s in lives:
            if s.active:
                s.finish("error", f"{type(exc).__name__}: {exc}")
        raise
    finally:
        with stop_signals_deferred(reraise=False):
            if bar is not None:
                bar.close()
            close()
    missing = [s.config.seed for s in lives if s.final is None]
    if missing:  # close() flushes every seed's summary; a gap here is a bug, not a user's error
        raise RuntimeError(f"seeds {missing} ended without a summary")
    return [s.final for s in lives if s.final is not None]


def stop_requested(
    lives: Sequence[SeedLife], interrupted: list, should_stop: Callable[[], bool] | None, ask: bool
) -> bool:
    """The interrupt check between steps, every engine's: whether the job stops here on a signal
    (``interrupted``, ``live``'s flag) or on its dispatcher's request (``should_stop``, asked
    only where ``ask``: it costs a round trip, a Ray actor call, so engines ask when an episode
    ended). Every seed still running is then finished as interrupted."""
    if not interrupted and not (ask and should_stop is not None and should_stop()):
        return False
    for life in lives:
        if life.active:
            life.finish("interrupted", interruption(interrupted))
    return True


def interruption(interrupted: list) -> str:
    """Why a run stops on a signal (``runs/signals.stop_signals_as_flag``'s flag) or on its
    dispatcher's stop request: the message its summary keeps."""
    by = signal_name(interrupted) if interrupted else "the dispatcher's stop request (Ctrl-C or SIGTERM)"
    return f"stopped by {by}; the episodes so far are kept (--resume continues)"


class Checkpoints:
    """A job's checkpoints on any engine, written and read here alone. Each seed's file holds
    the envelope (the format's version, the engine that wrote it, the batch the job started as,
    the engine's step counter, and Python's and NumPy's global generators), the seed's part
    (``SeedLife.snapshot``) and the engine's own state for that seed (``engine_state``): an
    engine supplies only that state and how to load it. The cadence: every ``every`` episodes
    per seed (``TrainSettings.checkpoint_every``; 0 writes none before the end)."""

    def __init__(self, engine: str, batch: list[int], every: int):
        self.engine, self.batch, self.every = engine, batch, every
        self.since = 0
        """Episodes ended, over the job's seeds, since the last checkpoint."""

    def episode_ended(self) -> None:
        self.since += 1

    def due(self, lives: Sequence[SeedLife], seeds: int) -> bool:
        """Whether a checkpoint is due now: some seed still runs and the ``seeds`` seeds stepped
        together have ended ``every`` episodes each, on average, since the last one."""
        return bool(self.every) and any(life.active for life in lives) and self.since >= self.every * seeds

    def write(self, step: int, seeds: Sequence[tuple[SeedLife, dict[str, Any]]]) -> None:
        """Each seed's checkpoint into its own folder: ``(life, engine_state)`` pairs at the
        engine's step ``step``."""
        envelope = {
            "version": VERSION,
            "engine": self.engine,
            "batch": self.batch,
            "vector_step": step,
            "global_rng": global_rng_state(),
        }
        for life, own in seeds:
            write_checkpoint(life.out_dir, {**envelope, "seed": life.snapshot(), "engine_state": own})
        self.since = 0

    def read(self, lives: Sequence[SeedLife], part: bool = False) -> list[dict[str, Any]]:
        """The checkpoints of ``lives`` (the batch's, in order; ``part``: a batch that shed seeds
        as it went, ``runs/checkpoint.read_batch_checkpoints``), each refused where another
        engine wrote it. Nothing is restored yet: an engine may refuse them first (``resume``)."""
        out_dirs = [life.out_dir for life in lives]
        states = read_batch_checkpoints(out_dirs, self.batch, part=part)
        for out_dir, state in zip(out_dirs, states):
            check_checkpoint_engine(out_dir, state, self.engine)
        return states

    @staticmethod
    def resume(lives: Sequence[SeedLife], states: list[dict[str, Any]], load: Callable[[list], None]) -> int:
        """``read``'s checkpoints restored: each seed's part first (a config the engine's state
        would not fit is refused, naming the field), then the engine's states (``load``, in the
        seeds' order), then the global generators. The engine's step counter they hold."""
        for life, state in zip(lives, states):
            life.restore(state["seed"])
        load([state["engine_state"] for state in states])
        set_global_rng_state(states[0]["global_rng"])
        return int(states[0]["vector_step"])


CloseCheckpoint = Literal["write", "keep", "delete"]


def checkpoint_at_close(lives: Sequence[SeedLife]) -> CloseCheckpoint | None:
    """Which checkpoint a job's seeds leave when it ends: ``write`` where one was interrupted
    (every seed's, so that the job resumes whole); ``keep`` the final one of a solo run that
    played its whole budget (``--resume --episodes N`` extends it as a straight run of N);
    ``delete`` once every seed finished; None after an error (what is there stays)."""
    if any(s.status == "interrupted" for s in lives):
        return "write"
    if len(lives) == 1 and lives[0].ended_on_budget:
        return "keep"
    if all(s.status in ("completed", "non_finite_loss") for s in lives):
        return "delete"
    return None


def close_lives(
    lives: Sequence[SeedLife], write_checkpoints: Callable[[], None], flush: Callable[[int], object]
) -> None:
    """How a job of one or more seeds ends on any engine: a seed still running after an error
    outside any one seed says so; the checkpoints ``checkpoint_at_close`` asks for are written
    (``write_checkpoints``: every seed's) or removed; every seed without a final summary flushes
    (``flush(k)``) and its evaluator closes. A checkpoint an interrupted seed cannot write (a full
    disk) makes that seed an error naming the folder; a solo run's kept final checkpoint that
    cannot be written costs only the extension, with a warning."""
    for life in lives:
        if life.active:
            life.finish("error", f"the {'run' if len(lives) == 1 else 'batch'} stopped on an error")
    action = checkpoint_at_close(lives)
    if action == "write":
        try:
            write_checkpoints()
        except Exception as exc:  # disk full: say so in every interrupted seed's summary
            for life in lives:
                if life.status == "interrupted":
                    life.finish(
                        "error", f"could not write the checkpoint in {life.out_dir}: {type(exc).__name__}: {exc}"
                    )
                    life.final = None
    elif action == "keep":  # a solo run's final state, for --resume --episodes N
        try:
            write_checkpoints()
        except OSError as exc:
            delete_checkpoints(lives[0].out_dir)
            warnings.warn(f"could not keep the final checkpoint (the run cannot be extended): {exc}", stacklevel=2)
    elif action == "delete":
        for life in lives:
            delete_checkpoints(life.out_dir)
    for k, life in enumerate(lives):
        if life.final is None:
            flush(k)
        if life.evaluator is not None:
            life.evaluator.close()


def progress_bar(experiment: Experiment, configs: list, lives: Sequence[SeedLife], position: int):
    """A tqdm bar over the seeds' episodes."""
    from tqdm.auto import tqdm

    c = configs[0]
    who = (
        f"seed {c.seed}"
        if len(configs) == 1
        else f"seeds {configs[0].seed}..{configs[-1].seed} (batch of {len(configs)})"
    )
    return tqdm(
        total=len(lives) * c.episodes,
        initial=sum(len(s.recorder.rows) for s in lives),
        position=position,
        leave=position == 0,
        dynamic_ncols=True,
        unit="ep",
        desc=f"{experiment.name}/{c.variant}/{c.framework} {who}",
    )


class TensorBoardWriter:
    """Per-episode score, metric and losses as TensorBoard scalars, one run folder per seed."""

    def __init__(self, root: Path, config):
        import tensorflow as tf

        self.tf = tf
        self.writer = tf.summary.create_file_writer(
            str(Path(root) / f"{config.experiment}-{config.variant}-{config.framework}-seed{config.seed}")
        )

    def scalars(self, values: dict[str, float], step: int) -> None:
        with self.writer.as_default():
            for key, value in values.items():
                self.tf.summary.scalar(key, value, step=step)
        self.writer.flush()

    def episode(self, row: dict[str, Any]) -> None:
        with self.writer.as_default():
            for key, value in row.items():
                if key not in ("episode", "wall_seconds") and value is not None and math.isfinite(value):
                    self.tf.summary.scalar(key, value, step=row["episode"])
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()
