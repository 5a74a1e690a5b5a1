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

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.config import check_same_but_seed
from keras_rl.errors import ConfigError, NonFiniteLossError, argument
from keras_rl.experiment import Experiment
from keras_rl.learners.axis import SeedAxisLearner
from keras_rl.learners.table import implementation, stacked_implementation
from keras_rl.runs.lifecycle import UNRECORDED_ENGINE as ENGINE
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import configure_tensorflow, seed_everything
from keras_rl.train.life import Checkpoints, SeedLife, close_lives, live, stop_requested
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
        _Seed(experiment, c, env, Path(d), axis.loss_names, settings) for c, env, d in zip(configs, envs, out_dirs)
    ]
    batch = [c.seed for c in configs]
    for s in seeds:
        if len(seeds) > 1:  # which seeds shared its stacked updates: its bits depend on them
            s.records.provenance["seed_batch"] = batch
    state = _Batch(seeds, axis, Checkpoints(ENGINE, batch, settings.checkpoint_every))
    if settings.resume:
        state.restore()
    return live(experiment, configs, seeds, settings, lambda flag, bar: state.loop(flag, bar, should_stop), state.close)


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
                f"it does not batch (drop {argument('seed_batch')})"
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


class _Seed(SeedLife):
    """One seed's own part of a batch: its life (``train/life.py``), its env and where its episode stands."""

    def __init__(self, experiment: Experiment, config, env, out_dir: Path, loss_names, settings: TrainSettings):
        super().__init__(experiment, config, out_dir, loss_names, settings)
        self.env = env
        self.score, self.steps = 0.0, 0

    def snapshot(self) -> dict[str, Any]:
        """``SeedLife.snapshot`` and where this seed's episode stands: its score, steps and env."""
        return {**super().snapshot(), "score": self.score, "steps": self.steps, "env": self.env}

    def restore(self, state: dict[str, Any]) -> None:
        if getattr(self.config, "learning_phase_training", False):
            raise ConfigError(
                f"{argument('resume')} does not cover learning_phase_training=true (its noise layer draws from "
                "TensorFlow's generator, which checkpoints do not hold)"
            )
        self.resume(state)
        self.score, self.steps = state["score"], state["steps"]
        _load_env_state(self.env, state["env"])


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

    def __init__(self, seeds: list[_Seed], axis, checkpoints: Checkpoints):
        self.seeds, self.axis, self.checkpoints = seeds, axis, checkpoints
        self.vector_step = 0
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
                goes_on = s.end_episode(
                    *records[k],
                    axis.episode_stats(k),
                    lambda obs, k=k: axis.greedy(k, obs),
                    lambda d, k=k: axis.save(k, d),
                    bar,
                )
                self.checkpoints.episode_ended()
                if goes_on:
                    s.episode += 1
                    s.score, s.steps = 0.0, 0
                    restarted.add(k)
            axis.next_actions([s.active for s in seeds], restarted)
            stopped = [k for k, s in enumerate(seeds) if not s.active and s.final is None]
            for k in stopped:  # it stopped on this step: its files and summary now
                self.flush(k)
            if stop_requested(seeds, interrupted, should_stop, ask=bool(ended)):
                return
            if self.checkpoints.due(seeds, len(seeds)):
                self.write_checkpoints()

    # -- checkpoints ------------------------------------------------------------------------
    def write_checkpoints(self) -> None:
        """Every seed's state at this vector step, each into its own folder (its slice of the
        seed axis is the engine's state)."""
        self.checkpoints.write(self.vector_step, [(s, self.axis.seed_state(k)) for k, s in enumerate(self.seeds)])

    def restore(self) -> None:
        self.vector_step = Checkpoints.resume(self.seeds, self.checkpoints.read(self.seeds), self._load_axis)
        self.started = True

    def _load_axis(self, states: list[dict[str, Any]]) -> None:
        for k, state in enumerate(states):
            self.axis.load_seed_state(k, state)

    # -- the end ------------------------------------------------------------------------------
    def flush(self, k: int) -> None:
        """A seed's last word (``SeedLife.flush``), before its masked slice moves on."""
        self.seeds[k].flush(lambda d: self.axis.save(k, d))

    def close(self) -> None:
        """Every seed's final files (``life.close_lives``): an interrupted batch writes every
        seed's checkpoint, finished ones included, so the batch resumes whole; a solo run that
        played its whole budget keeps its final one; a batch that ended removes them."""
        close_lives(self.seeds, self.write_checkpoints, self.flush)
        for s in self.seeds:
            s.env.close()
