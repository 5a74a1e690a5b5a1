"""The one episode loop: S seeds of one config trained together, over a seed axis.

A solo run is the case S=1 (``run_seed``), not a different program. Each seed keeps
everything of its own: its env (seeded as its solo run seeds it), its agent's parts
(replay buffer, transition rule, schedule, explorer, loss tally), its metric, its counters,
its run folder and summary. One learner holds the seed axis (``SeedAxis``):

- ``SoloAsStack`` around the table's learner (``learners/table.py``) for one seed, Keras
  or PyTorch: call for call the solo learner's calls, so S=1 is bit-identical to the runs
  committed before this loop existed (``tests/test_committed_runs_replay.py``);
- a stacked learner (``learners/stacked.py``) for S>1: one compiled update per env step
  for every seed, each slice stepping as its solo run would to about 1e-7 (XLA's batched
  matmul rounds differently), so long runs drift apart the way chaotic runs do;
- post 003's PyTorch tutorial, which brings its own whole agent (``WholeAgentAxis``; one
  seed: its code is the original).

Every env step is a vector step: each running seed steps its env and stores its
transitions (``Agent.store``); a seed whose episode ended resets its env at once; then one
learner call trains every seed and picks every next action; then ended episodes are
recorded. A seed that finishes (threshold, budget, or a non-finite loss of its own) stops
its env and its records at once; in the learner it is masked (its slice keeps stepping on
rows of zeros, and nothing of it reaches the other slices: the loss is a sum of per-seed
losses, Adam and the soft update are elementwise). (Post 003's stacked learner could also
rebuild its stack without a finished seed; it went with that learner, issue 34.)

Checkpoints (``--resume``): every ``checkpoint_every`` episodes per seed, and when a signal
or the dispatcher stops the batch, every seed writes the state at the current vector step
to its own folder: its parts mid-episode included, its env (pickled, mid-episode), its
slice of the learner, and the generators outside it. A batch's checkpoints carry the
vector step they were taken at and the seeds of the batch; a seed keeps its previous one
beside the current one until the next is written, so a batch killed while writing them
resumes from the newest vector step every seed holds. Resuming replays the rest exactly as
an uninterrupted run of the same batch (``tests/test_resume.py``). A solo run that played
its whole budget keeps its final checkpoint, so ``--resume --episodes N`` extends it to N
episodes exactly as a straight run of N would have played them.
"""

from __future__ import annotations

import datetime
import math
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.config import check_same_but_seed
from keras_rl.errors import ConfigError, NonFiniteLossError, RunFolderError
from keras_rl.experiment import Experiment
from keras_rl.learners.axis import SeedAxisLearner
from keras_rl.learners.table import implementation, stacked_implementation
from keras_rl.rngs import global_rng_state, set_global_rng_state
from keras_rl.runs.checkpoint import delete_checkpoints, read_batch_checkpoints, write_checkpoint
from keras_rl.runs.evaluate import TrainingEvaluator
from keras_rl.runs.files import RunRecorder, atomic_write_text, episode_columns, episodes_csv_text
from keras_rl.runs.lifecycle import check_resume_config
from keras_rl.runs.provenance import command_line, library_versions, provenance
from keras_rl.runs.signals import signal_name, stop_signals_as_flag, stop_signals_deferred
from keras_rl.runs.summary import RunSummary, Status
from keras_rl.seeding import configure_tensorflow, seed_everything
from keras_rl.train.settings import DEFAULT_SETTINGS, TrainSettings


def run_seed(
    experiment: Experiment,
    config,
    out_dir: Path,
    settings: TrainSettings = DEFAULT_SETTINGS,
    env=None,
    should_stop: Callable[[], bool] | None = None,
) -> RunSummary:
    """Train one seed: ``run_seeds`` with a seed axis of one."""
    return run_seeds(
        experiment, [config], [out_dir], settings, envs=None if env is None else [env], should_stop=should_stop
    )[0]


def run_seeds(
    experiment: Experiment,
    configs: Sequence,
    out_dirs: Sequence[Path],
    settings: TrainSettings = DEFAULT_SETTINGS,
    *,
    should_stop: Callable[[], bool] | None = None,
    envs: Sequence | None = None,
) -> list[RunSummary]:
    """Train the seeds of ``configs`` (equal but for the seed) together to the threshold or
    the budget; write each one's folder and return their summaries.

    Ctrl-C, SIGTERM, a non-finite loss or any other error still leaves each seed's
    ``episodes.csv`` with every finished episode and a ``summary.json`` whose ``status``
    says how that seed ended; the summary is rewritten after every episode. ``settings``
    (``train/settings.TrainSettings``) says how: resume, checkpoints, TensorBoard, evaluation
    during training and the command line to record. ``envs`` may be passed in, one per seed
    (tests wrap envs). ``should_stop`` is asked whenever an episode ends; True stops the batch
    as a signal would (a distributed backend's stop flag).
    """
    configs = list(configs)
    check_same_but_seed(configs)
    if len({c.episodes for c in configs}) != 1:
        raise ConfigError("seed-batched runs share one budget")
    configure_tensorflow(settings.threads)
    axis, envs = build_seed_axis(experiment, configs, envs)
    axis.compile()
    seeds = [
        _Seed(experiment, c, env, Path(d), axis.loss_names, settings.command)
        for c, env, d in zip(configs, envs, out_dirs)
    ]
    batch = [c.seed for c in configs]
    for s in seeds:
        if len(seeds) > 1:  # which seeds shared its stacked updates: its bits depend on them
            s.run.provenance["seed_batch"] = batch
    state = _Batch(seeds, axis, settings.checkpoint_every, batch)
    if settings.evaluation is not None:
        for s in seeds:
            s.evaluator = TrainingEvaluator(experiment, s.config, s.recorder.out_dir, settings.evaluation)
    if settings.resume:
        checkpoints = read_batch_checkpoints([s.recorder.out_dir for s in seeds], batch)
        engine = checkpoints[0].get("engine", "gymnasium")
        if engine != "gymnasium":
            raise RunFolderError(
                f"{seeds[0].recorder.out_dir}'s checkpoint was written by the {engine} engine; resume it "
                f"with --engine {engine}, or pass --overwrite to start again"
            )
        state.restore(checkpoints)
        for s in seeds:
            if s.active:  # it goes on, perhaps to a larger budget (--resume --episodes N): config.json says which
                s.recorder.write_config(s.config.to_dict())
            if s.evaluator is not None:
                s.evaluator.resume(len(s.recorder.rows))
    else:
        for s in seeds:
            s.recorder.write_config(s.config.to_dict())
    for s in seeds:
        if s.final is None:  # a summary from the start: no stale one from an earlier run survives
            s.run.summary("running").write(s.recorder.out_dir)
        if settings.tensorboard and s.final is None:
            s.writer = _TensorBoard(settings.tensorboard, s.config)
    bar = _progress_bar(experiment, configs, seeds, settings.position) if settings.progress else None
    try:
        with stop_signals_as_flag() as interrupted:  # checked between vector steps
            state.loop(interrupted, bar, should_stop)
    except Exception as exc:  # keep what was written, record why, re-raise
        for s in seeds:
            if s.active:
                s.finish("error", f"{type(exc).__name__}: {exc}")
        raise
    finally:
        # A second signal (or the one a parent forwards) must not cut the flush short.
        with stop_signals_deferred(reraise=False):
            if bar is not None:
                bar.close()
            state.close()
    missing = [s.run.config.seed for s in seeds if s.final is None]
    if missing:  # close() flushes every seed's summary; a gap here is a bug, not a user's error
        raise RuntimeError(f"seeds {missing} ended without a summary")
    return [s.final for s in seeds if s.final is not None]


def build_seed_axis(experiment: Experiment, configs: list, envs: Sequence | None):
    """The seed axis for ``configs``, and each seed's env, built in the order a solo run
    draws its initial weights (Keras seeded with the seed, env, then the learner)."""
    c = configs[0]
    impl = implementation(experiment.name, c.framework)
    if len(configs) == 1:
        seed_everything(c.seed)
    envs = list(envs) if envs is not None else [experiment.make_env(config) for config in configs]
    for config, env in zip(configs, envs):
        env.action_space.seed(config.seed)
    spec = experiment.env_spec(envs[0])
    if impl.whole_agent:
        if len(configs) > 1:
            raise ConfigError(
                f"{experiment.name}'s {c.framework} version is the original code, one seed per run; "
                "it does not batch (drop --seed-batch)"
            )
        return WholeAgentAxis(impl.load()(c, spec, envs[0].action_space)), envs
    if len(configs) == 1:
        from keras_rl.learners.stacked import SoloAsStack

        learner = SoloAsStack(impl.load()(c, spec))
        return PartsAxis([experiment.assemble(c, spec, learner, envs[0].action_space)], learner), envs
    learner = stacked_implementation(experiment.name, c.framework).load()(configs, spec)
    agents = [experiment.assemble(config, spec, learner, env.action_space) for config, env in zip(configs, envs)]
    return PartsAxis(agents, learner), envs


class PartsAxis:
    """Each seed's agent parts (``agents/skeleton.Agent``'s phases) and one learner that
    holds the seed axis (stacked calls: ``[S, ...]`` in, ``[S, ...]`` out).

    Seed k of the batch is row k of every stacked call, for the whole run (a finished seed
    stays in the stack on rows of zeros)."""

    def __init__(self, agents: list, learner: SeedAxisLearner):
        self.agents, self.learner = agents, learner
        self.loss_names = tuple(learner.loss_names)
        self.batches: list[list] = [[] for _ in agents]
        self.raw: list[Any] = []  # each seed's action from the learner, before exploration

    def compile(self) -> None:
        """The learner traces its compiled steps (once, before the first env step)."""
        self.learner.compile()

    def _act(self, states: np.ndarray) -> None:
        self.raw = list(self.learner.act(states))

    def _states(self) -> np.ndarray:
        return np.stack([agent.state for agent in self.agents])

    def begin(self, k: int, obs) -> None:
        self.agents[k].start_episode(obs)

    def first_actions(self) -> None:
        for agent in self.agents:
            agent.reset_episode_stats()
        self._act(self._states())
        for agent, raw in zip(self.agents, self.raw):
            agent.explore(raw)

    def store(self, k: int, reward: float, obs, terminated: bool, truncated: bool) -> None:
        self.batches[k] = self.agents[k].store(reward, obs, terminated, truncated)

    def learn(self, running: list[bool], any_ended: bool) -> dict[int, str]:
        """Every running seed's updates of this env step and every seed's next action, in
        the calls the solo run makes (``skeleton.run_updates``) with a seed axis; returns
        the seeds whose loss went non-finite, with the message."""
        counts = [len(batches) if t else 0 for batches, t in zip(self.batches, running)]
        n = max(counts, default=0)
        alike = len({c for c, t in zip(counts, running) if t}) <= 1
        if not alike and not self.learner.takes_masks:
            raise ConfigError(
                "seed-batched runs of this learner need the seeds to train the same number of batches on each env step"
            )
        states = self._states()
        if n == 0:
            self.raw = list(self.learner.step_without_batch(states, episode_ended=any_ended))
            return {}
        rounds = []  # (losses [S] by name, which stack slots trained)
        if alike:  # every running seed trains n batches: the solo run's calls, stacked
            separate = any_ended or not self.agents[0].schedule.fuse_act
            for i in range(n - 1):
                rounds.append((_numpy(self.learner.train(self._rows(i, running))), running))
            last, raw = self.learner.train_and_act(self._rows(n - 1, running), states, separate=separate)
            self.raw = list(raw)
            rounds.append((_numpy(last), running))
        else:  # post 001's bursts: round i trains the seeds with more than i batches, the others masked
            for i in range(n):
                mask = [c > i for c in counts]
                rounds.append((_numpy(self.learner.train(self._rows(i, mask), mask=np.array(mask))), mask))
            self._act(states)
        failed = {}
        for k, agent in enumerate(self.agents):
            if running[k]:
                try:
                    agent.record_losses(
                        [{name: v[k] for name, v in losses.items()} for losses, trained in rounds if trained[k]]
                    )
                except NonFiniteLossError as exc:
                    failed[k] = str(exc)
        return failed

    def _rows(self, i: int, trains: list[bool]) -> np.ndarray:
        """Update i's rows ``[S, B, width]`` (one per stack slot); a slot that does not train
        on it gives rows of zeros."""
        shape = next(batches[i].shape for batches, t in zip(self.batches, trains) if t)
        return np.stack([batches[i] if t else np.zeros(shape, np.float32) for batches, t in zip(self.batches, trains)])

    def next_actions(self, running: list[bool], restarted: set[int]) -> None:
        for k, agent in enumerate(self.agents):
            if k in restarted:
                agent.reset_episode_stats()
            if running[k]:
                agent.explore(self.raw[k])

    def greedy(self, k: int, obs):
        """Seed k's policy action for ``obs``, without exploration or update (the others' rows
        are their current states, and their actions are dropped)."""
        states = self._states()
        states[k] = self.agents[k].transitions.observe(obs)
        return self.learner.act(states)[k]

    def restart_actions(self, ks: list[int]) -> None:
        """First actions of seeds that resume past the budget they completed: the updated
        policy's action on each new first state, explored, as ``next_actions`` gives it."""
        self._act(self._states())
        for k in ks:
            self.agents[k].reset_episode_stats()
            self.agents[k].explore(self.raw[k])

    def action(self, k: int):
        return self.agents[k]._action

    def episode_stats(self, k: int):
        return self.agents[k].end_episode()

    def save(self, k: int, run_dir: Path) -> None:
        self.learner.save_slice(k, run_dir)

    def seed_state(self, k: int) -> dict[str, Any]:
        return {"parts": self.agents[k].parts_state(), "learner": self.learner.slice_state(k)}

    def load_seed_state(self, k: int, state: dict[str, Any]) -> None:
        self.agents[k].load_parts_state(state["parts"])
        self.learner.load_slice_state(k, state["learner"])


def _numpy(losses) -> dict[str, np.ndarray]:
    return {name: np.asarray(v) for name, v in losses.items()}  # [S] each


class WholeAgentAxis:
    """A seed axis of one whole agent that trains itself inside its ``step`` (post 003's
    PyTorch tutorial): the loop's phases call its verbs in the solo order."""

    def __init__(self, agent):
        self.agent = agent
        self.loss_names = tuple(agent.loss_names)
        self._obs, self._action, self._failed = None, None, None

    def compile(self) -> None:
        """Nothing to trace: the tutorial's own code runs eagerly."""

    def begin(self, k: int, obs) -> None:
        self._obs = obs  # its begin_episode resets the tally: it runs after the episode is recorded

    def first_actions(self) -> None:
        self._action = self.agent.begin_episode(self._obs)

    def store(self, k: int, reward: float, obs, terminated: bool, truncated: bool) -> None:
        try:
            self._action = self.agent.step(reward, obs, terminated, truncated)
        except NonFiniteLossError as exc:
            self._failed = str(exc)

    def learn(self, running: list[bool], any_ended: bool) -> dict[int, str]:
        failed, self._failed = self._failed, None
        return {} if failed is None else {0: failed}

    def next_actions(self, running: list[bool], restarted: set[int]) -> None:
        if restarted and running[0]:
            self._action = self.agent.begin_episode(self._obs)

    def greedy(self, k: int, obs):
        return self.agent.greedy_action(obs)

    def restart_actions(self, ks: list[int]) -> None:
        self._action = self.agent.begin_episode(self._obs)

    def action(self, k: int):
        return self._action

    def episode_stats(self, k: int):
        return self.agent.end_episode()

    def save(self, k: int, run_dir: Path) -> None:
        self.agent.save(run_dir)

    def seed_state(self, k: int) -> dict[str, Any]:
        tally = self.agent.tally
        return {
            "agent": self.agent.state_dict(),
            "action": self._action,
            "agent_step": {"state": self.agent._state, "action": self.agent._action},
            "tally": {"sums": dict(tally.sums), "updates": tally.updates},
        }

    def load_seed_state(self, k: int, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self._action = state["action"]
        self.agent._state, self.agent._action = state["agent_step"]["state"], state["agent_step"]["action"]
        self.agent.tally.sums, self.agent.tally.updates = dict(state["tally"]["sums"]), int(state["tally"]["updates"])


class SeedRun:
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


class _Seed:
    """One seed's own part of a batch: its env, its records and where its episode stands."""

    def __init__(self, experiment: Experiment, config, env, out_dir: Path, loss_names, command: str | None):
        self.config, self.env = config, env
        self.recorder = RunRecorder(out_dir, loss_names)
        self.run = SeedRun(experiment, config, self.recorder, experiment.make_metric(config), command)
        self.status: Status = "running"
        self.message = ""
        self.score, self.steps, self.episode = 0.0, 0, 0
        self.saved = False
        self.writer: _TensorBoard | None = None
        self.final: RunSummary | None = None
        """The summary written when the seed stopped (its wall time ends there)."""
        self.evaluator: TrainingEvaluator | None = None
        self.extending = False
        """Resumed past the budget it completed (``--resume --episodes N``): its next episode starts the loop."""

    @property
    def ended_on_budget(self) -> bool:
        """Completed by playing its whole budget, not stopped at the threshold: a larger budget continues it."""
        stopped_early = self.run.reached_at is not None and self.config.stop_at_threshold
        return self.status == "completed" and self.episode == self.config.episodes and not stopped_early

    @property
    def active(self) -> bool:
        return self.status == "running"

    def finish(self, status: Status, message: str = "") -> None:
        self.status, self.message = status, message

    def snapshot(self) -> dict[str, Any]:
        return {
            **self.run.snapshot(self.status, self.message),
            "episode": self.episode,
            "score": self.score,
            "steps": self.steps,
            "saved": self.saved,
            "env": self.env,
        }

    def restore(self, state: dict[str, Any]) -> None:
        wanted, theirs = self.config.to_dict(), state["config"]
        check_resume_config(self.recorder.out_dir, wanted, theirs, len(state["rows"]))
        if getattr(self.config, "learning_phase_training", False):
            raise ConfigError(
                "--resume does not cover learning_phase_training=true (its noise layer draws from "
                "TensorFlow's generator, which checkpoints do not hold)"
            )
        run = self.run
        run.restore(state)
        self.status, self.message = state["status"], state["message"]
        self.episode, self.score, self.steps, self.saved = (
            state["episode"],
            state["score"],
            state["steps"],
            state["saved"],
        )
        _load_env_state(self.env, state["env"])
        print(
            f"seed {self.config.seed}: resumed in {self.recorder.out_dir} after episode {len(self.recorder.rows)} "
            f"(its checkpoint; {int(state['total_steps'])} steps)",
            file=sys.stderr,
        )
        budget, stopped_early = int(theirs["episodes"]), run.reached_at is not None and self.config.stop_at_threshold
        if self.status == "completed" and len(self.recorder.rows) == budget < wanted["episodes"] and not stopped_early:
            # it played its whole budget; the larger one continues it from the state it ended in
            self.status, self.message, self.saved, self.extending = "running", "", False, True
        if self.active:  # episodes played after the checkpoint are played again, so they leave the CSV
            atomic_write_text(
                self.recorder.out_dir / "episodes.csv",
                episodes_csv_text(self.recorder.rows, episode_columns(self.recorder.loss_names)),
            )
        else:  # it had finished before the checkpoint: its files stay as they are
            self.final = RunSummary.read(self.recorder.out_dir)


def _load_env_state(env, saved) -> None:
    """``saved`` (the pickled env of a checkpoint) into ``env`` in place, wrapper by wrapper:
    the agent's parts hold references into ``env`` (post 003's explorer samples its action
    space), so its objects stay and take the saved state (a space its generator)."""
    import gymnasium as gym

    mine, theirs = env, saved
    while True:
        for key, value in vars(theirs).items():
            if key == "env":
                continue
            held = vars(mine).get(key)
            if isinstance(value, gym.spaces.Space) and isinstance(held, gym.spaces.Space):
                held._np_random = value._np_random
            else:
                vars(mine)[key] = value
        if not isinstance(theirs, gym.Wrapper):
            return
        mine, theirs = mine.env, theirs.env


class _Batch:
    """The loop's state: the seeds, the seed axis, and the vector-step counter checkpoints carry."""

    def __init__(self, seeds: list[_Seed], axis, checkpoint_every: int, batch: list[int]):
        self.seeds, self.axis, self.checkpoint_every, self.batch = seeds, axis, checkpoint_every, batch
        self.vector_step = 0
        self.since_checkpoint = 0
        self.started = False

    # -- the loop -------------------------------------------------------------------------
    def loop(self, interrupted: list, bar, should_stop) -> None:
        """Vector step after vector step until no seed is running. A seed whose episode ends
        begins its next one at once (its own env reset), so episodes of any length line up;
        the one learner call of the step trains every seed and picks every next action, and
        the ended episode is recorded after it, as the solo agent records it after the
        step's update."""
        seeds, axis = self.seeds, self.axis
        if not self.started:
            for k, s in enumerate(seeds):
                axis.begin(k, s.env.reset(seed=s.config.seed)[0])
                s.episode = 1
            axis.first_actions()
            self.started = True
        extended = [k for k, s in enumerate(seeds) if s.extending]
        if extended:  # as the straight run did when the episode ended: reset, then act on the new state
            for k in extended:
                s = seeds[k]
                axis.begin(k, s.env.reset()[0])
                s.episode += 1
                s.score, s.steps, s.extending = 0.0, 0, False
            axis.restart_actions(extended)
        while any(s.active for s in seeds):
            ended = []
            for k, s in enumerate(seeds):
                if not s.active:
                    continue
                obs, reward, terminated, truncated, _ = s.env.step(axis.action(k))
                s.score += float(reward)
                s.steps += 1
                axis.store(k, float(reward), obs, terminated, truncated)
                if terminated or truncated:
                    ended.append(k)
            records = {k: (seeds[k].score, seeds[k].steps) for k in ended}
            for k in ended:  # the next episode's first state, so that one call acts for every seed
                if seeds[k].episode < seeds[k].config.episodes:
                    axis.begin(k, seeds[k].env.reset()[0])
            running = [s.active for s in seeds]
            for k, message in axis.learn(running, any_ended=bool(ended)).items():
                seeds[k].finish("non_finite_loss", message)
            self.vector_step += 1
            restarted = set()
            for k in ended:
                s = seeds[k]
                if not s.active:
                    continue
                row = s.run.record_episode(s.episode, *records[k], axis.episode_stats(k))
                if s.writer is not None:
                    s.writer.episode(row)
                if s.evaluator is not None and s.evaluator.due(s.episode):
                    s.evaluator.evaluate(
                        s.episode, lambda obs, k=k: axis.greedy(k, obs), lambda d, k=k: axis.save(k, d), s.writer
                    )
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(score=f"{row['score']:.1f}", metric=f"{row['metric']:.1f}", refresh=False)
                self.since_checkpoint += 1
                if (s.run.reached_at is not None and s.config.stop_at_threshold) or s.episode == s.config.episodes:
                    s.finish("completed")
                else:
                    s.episode += 1
                    s.score, s.steps = 0.0, 0
                    restarted.add(k)
            axis.next_actions([s.active for s in seeds], restarted)
            stopped = [k for k, s in enumerate(seeds) if not s.active and s.final is None]
            for k in stopped:  # it stopped on this step: its files and summary now
                self.flush(k)
            # the dispatcher's flag costs a round trip (a Ray actor call): asked when an episode ends
            if interrupted or (ended and should_stop is not None and should_stop()):
                by = signal_name(interrupted) if interrupted else "the dispatcher's stop request (Ctrl-C or SIGTERM)"
                for s in seeds:
                    if s.active:
                        s.finish("interrupted", f"stopped by {by}; the episodes so far are kept (--resume continues)")
                return
            if (
                self.checkpoint_every
                and any(s.active for s in seeds)
                and self.since_checkpoint >= self.checkpoint_every * len(seeds)
            ):
                self.write_checkpoints()

    # -- checkpoints ------------------------------------------------------------------------
    def write_checkpoints(self) -> None:
        """Every seed's state at this vector step, each into its own folder."""
        shared = {
            "version": 2,
            "batch": self.batch,
            "vector_step": self.vector_step,
            "global_rng": global_rng_state(),
        }
        for k, s in enumerate(self.seeds):
            write_checkpoint(s.recorder.out_dir, {**shared, "seed": s.snapshot(), "axis": self.axis.seed_state(k)})
        self.since_checkpoint = 0

    def write_final_checkpoints(self) -> None:
        """The state a solo run ended in when it played its whole budget, kept so that
        ``--resume --episodes N`` can extend it as if it had run N episodes straight. (Not
        in a batch: a seed that finished before the others is masked, and its slice moves
        on.) A failed write costs only that: the run is complete, and says so."""
        try:
            self.write_checkpoints()
        except OSError as exc:
            for s in self.seeds:
                delete_checkpoints(s.recorder.out_dir)
            warnings.warn(f"could not keep the final checkpoint (the run cannot be extended): {exc}", stacklevel=2)

    def restore(self, states: list[dict[str, Any]]) -> None:
        for k, (s, state) in enumerate(zip(self.seeds, states)):
            s.restore(state["seed"])
            self.axis.load_seed_state(k, state["axis"])
        set_global_rng_state(states[0]["global_rng"])
        self.vector_step = int(states[0]["vector_step"])
        self.started = True

    # -- the end ------------------------------------------------------------------------------
    def flush(self, k: int) -> None:
        """A seed's last word: its weights (when it finished or was stopped, before its masked
        slice moves on) and its final summary; a failed write makes the run an error that
        names the file, so no summary claims success for a run whose files are missing."""
        s = self.seeds[k]
        if s.status in ("completed", "interrupted") and not s.saved:
            try:
                self.axis.save(k, s.recorder.out_dir)
                s.saved = True
            except Exception as exc:  # disk full, permissions
                s.finish(
                    "error", f"could not write the run's files in {s.recorder.out_dir}: {type(exc).__name__}: {exc}"
                )
        if s.writer is not None:
            s.writer.close()
            s.writer = None
        s.final = s.run.summary(s.status, s.message)
        s.final.write(s.recorder.out_dir)

    def close(self) -> None:
        """Every seed's final files. Checkpoints: an interrupted batch writes them (every
        seed's, finished ones included, so the batch resumes whole); a batch that ended
        removes them."""
        seeds = self.seeds
        for s in seeds:
            if s.active:  # an error outside any one seed: every seed still running says so
                s.finish("error", "the batch stopped on an error")
        if any(s.status == "interrupted" for s in seeds):
            try:
                self.write_checkpoints()
            except Exception as exc:  # disk full: say so in every interrupted seed's summary
                for s in seeds:
                    if s.status == "interrupted":
                        s.finish(
                            "error",
                            f"could not write the checkpoint in {s.recorder.out_dir}: {type(exc).__name__}: {exc}",
                        )
                        s.final = None
        elif len(seeds) == 1 and seeds[0].ended_on_budget:
            self.write_final_checkpoints()
        elif all(s.status in ("completed", "non_finite_loss") for s in seeds):
            for s in seeds:
                delete_checkpoints(s.recorder.out_dir)
        for k, s in enumerate(seeds):
            if s.final is None:
                self.flush(k)
            s.env.close()
            if s.evaluator is not None:
                s.evaluator.close()


def _progress_bar(experiment: Experiment, configs: list, seeds: Sequence[Any], position: int):
    """A tqdm bar over the seeds' episodes (each seed has a ``recorder``)."""
    from tqdm.auto import tqdm

    c = configs[0]
    who = (
        f"seed {c.seed}"
        if len(configs) == 1
        else f"seeds {configs[0].seed}..{configs[-1].seed} (batch of {len(configs)})"
    )
    return tqdm(
        total=len(seeds) * c.episodes,
        initial=sum(len(s.recorder.rows) for s in seeds),
        position=position,
        leave=position == 0,
        dynamic_ncols=True,
        unit="ep",
        desc=f"{experiment.name}/{c.variant}/{c.framework} {who}",
    )


class _TensorBoard:
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
