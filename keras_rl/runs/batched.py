"""The seed-batched episode loop: S seeds of one experiment stepped together, one compiled
update per vector step for all of them (``--seed-batch S``).

Each seed keeps everything of its own: its env (seeded as its solo run seeds it), replay
buffer, noise, transition rule, metric, counters, run folder and summary; only the
networks are stacked (``learners/stacked.py``), so seed k's env steps line up one to one
with its solo run's. A seed that finishes (threshold, budget, or a non-finite loss of its
own) is masked: its slice keeps stepping, so the others stay in lockstep, but nothing of
it is recorded any more, and nothing of it reaches the other slices (the loss is a sum of
per-seed losses; Adam and the soft update are elementwise). Ctrl-C and SIGTERM stop every
seed still running, each with ``"status": "interrupted"``.

Exactness: one seed through this loop (S=1) writes the same ``episodes.csv`` as its solo
run. With S>1 each update agrees with the solo update to about 1e-7 (XLA's batched matmul
rounds differently), so long runs drift apart the way chaotic runs do; the test and
``results/pendulum/seed-batch/`` compare the distributions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from keras_rl.errors import ConfigError, NonFiniteLossError
from keras_rl.experiment import Experiment
from keras_rl.learners.table import stacked_implementation
from keras_rl.runs.files import RunRecorder
from keras_rl.runs.loop import SeedRun
from keras_rl.runs.signals import signal_name, stop_signals_as_flag
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import configure_tensorflow


class _NoLearner:
    """What ``assemble`` needs of a learner to build a seed's parts: the loss names."""

    def __init__(self, loss_names):
        self.loss_names = loss_names


class _Seed:
    """One seed's own part of a batch: env, parts (buffer, rule, schedule, explorer), records."""

    def __init__(self, experiment: Experiment, config, env, parts, out_dir: Path, command: str | None):
        self.config, self.env, self.parts = config, env, parts
        self.recorder = RunRecorder(Path(out_dir), parts.loss_names)
        self.recorder.write_config(config.to_dict())
        self.run = SeedRun(experiment, config, self.recorder, experiment.make_metric(config), command)
        self.status, self.message = "running", ""
        self.score, self.steps, self.episode, self.state, self.action = 0.0, 0, 0, None, None
        self.saved = False
        self.final: RunSummary | None = None
        """The summary written when the seed stopped (its wall time ends there)."""

    @property
    def active(self) -> bool:
        return self.status == "running"

    def finish(self, status: str, message: str = "") -> None:
        self.status, self.message = status, message


def run_seed_batch(experiment: Experiment, configs: list, out_dirs: list[Path], progress: bool = True,
                   threads: int | None = 1, envs: list | None = None, command: str | None = None) -> list[RunSummary]:
    """Train the seeds of ``configs`` (equal but for the seed) together; write each one's folder.
    ``envs`` may be passed in, one per seed (tests wrap envs); by default the experiment makes them."""
    if len({c.episodes for c in configs}) != 1:
        raise ConfigError("seed-batched runs share one budget")
    configure_tensorflow(threads)
    envs = list(envs) if envs is not None else [experiment.make_env(c) for c in configs]
    for config, env in zip(configs, envs):
        env.action_space.seed(config.seed)
    spec = experiment.env_spec(envs[0])
    learner = stacked_implementation(experiment.name, configs[0].framework).load()(configs, spec)
    seeds = [_Seed(experiment, c, env, experiment.assemble(c, spec, _NoLearner(learner.loss_names), env.action_space),
                   d, command) for c, env, d in zip(configs, envs, out_dirs)]
    for s in seeds:  # which seeds shared its stacked updates: its bits depend on them
        s.run.provenance["seed_batch"] = [c.seed for c in configs]
        s.run.summary("running").write(s.recorder.out_dir)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(seeds) * configs[0].episodes, unit="ep", dynamic_ncols=True,
                   desc=f"{experiment.name} seeds {configs[0].seed}..{configs[-1].seed} (batch of {len(seeds)})")
    try:
        with stop_signals_as_flag() as interrupted:
            _loop(seeds, learner, interrupted, bar)
    finally:
        if bar is not None:
            bar.close()
        for k, s in enumerate(seeds):
            if s.active:  # an error outside any one seed: every seed still running says so
                s.finish("error", "the batch stopped on an error")
            if s.final is None:
                _flush(s, learner, k)
            s.env.close()
    return [s.final for s in seeds]


def _loop(seeds: list[_Seed], learner, interrupted: list, bar) -> None:
    """Vector step after vector step until no seed is running. A seed whose episode ends
    begins its next one at once (its own env reset), so episodes of any length line up;
    the one learner call of the step trains every seed and picks every next action, and
    the ended episode is recorded after it, as the solo agent records it after the step's
    update."""
    for s in seeds:
        _begin_episode(s, s.env.reset(seed=s.config.seed)[0])
    raw = learner.act(np.stack([s.state for s in seeds]))
    for k, s in enumerate(seeds):
        s.action = s.parts.explorer(raw[k])
    while any(s.active for s in seeds):
        ended = []
        for k, s in enumerate(seeds):
            if not s.active:
                continue
            obs, reward, terminated, truncated, _ = s.env.step(s.action)
            s.score += float(reward)
            s.steps += 1
            s.parts.total_steps += 1
            s.parts.buffer.add_rows(s.parts.transitions.rows(s.state, s.action, float(reward), obs, terminated,
                                                             truncated))
            s.state = s.parts.transitions.observe(obs)
            if terminated or truncated:
                ended.append(k)
        records = {k: (seeds[k].score, seeds[k].steps) for k in ended}
        for k in ended:  # the next episode's first state, so that one call acts for every seed
            s = seeds[k]
            if s.episode < s.config.episodes:
                s.parts.transitions.begin_episode()
                s.state = s.parts.transitions.observe(s.env.reset()[0])
        raw = _learner_step(seeds, learner, after_episode_end=bool(ended))
        if interrupted:
            for s in seeds:
                if s.active:
                    s.finish("interrupted", f"stopped by {signal_name(interrupted)}; the episodes so far are kept")
            return
        for k in ended:
            s = seeds[k]
            if s.active:
                _end_episode(s, *records[k])
                if s.status != "completed":
                    s.episode += 1
                    s.parts.explorer.reset()
                    s.parts.tally.reset()
                    s.score, s.steps = 0.0, 0
                if bar is not None:
                    bar.update(1)
        for k, s in enumerate(seeds):
            if s.active:
                s.action = s.parts.explorer(raw[k])
            elif s.final is None:  # it stopped on this step: its files and summary now, its wall time its own
                _flush(s, learner, k)


def _begin_episode(s: _Seed, obs) -> None:
    """The agent's ``begin_episode`` for seed s, but for its action (one call acts for all)."""
    s.parts.explorer.reset()
    s.parts.tally.reset()
    s.parts.transitions.begin_episode()
    s.state, s.score, s.steps, s.episode = s.parts.transitions.observe(obs), 0.0, 0, 1


def _learner_step(seeds: list[_Seed], learner, after_episode_end: bool) -> np.ndarray:
    """Every seed's update of this env step and every seed's next greedy action, in one call
    where the solo run makes one. A seed no longer running contributes rows of zeros and
    its last state: its slice moves, but nothing of it is read any more."""
    active = [s for s in seeds if s.active]
    schedule = active[0].parts.schedule
    due = {len(s.parts.buffer) >= schedule.train_start and s.parts.total_steps % schedule.every == 0 for s in active}
    if len(due) != 1:
        raise ConfigError("seed-batched runs need the seeds to train on the same env steps")
    states = np.stack([s.state for s in seeds])
    if not due.pop():
        return learner.act_without_update(states, after_episode_end)
    width = active[0].parts.buffer.layout.width
    rows = np.stack([s.parts.buffer.sample_rows(schedule.batch_size) if s.active
                     else np.zeros((schedule.batch_size, width), np.float32) for s in seeds])  # [S, B, width]
    losses, raw = learner.train_and_act(rows, states, after_episode_end)
    values = {name: np.asarray(v) for name, v in losses.items()}  # [S] each
    for k, s in enumerate(seeds):
        if s.active:
            try:
                s.parts.tally.add({name: v[k] for name, v in values.items()}, f"env step {s.parts.total_steps}")
            except NonFiniteLossError as exc:
                s.finish("non_finite_loss", str(exc))
    return raw


def _end_episode(s: _Seed, score: float, steps: int) -> None:
    s.run.record_episode(s.episode, score, steps, s.parts.end_episode())
    if (s.run.reached_at is not None and s.config.stop_at_threshold) or s.episode == s.config.episodes:
        s.finish("completed")


def _save(s: _Seed, learner, k: int) -> None:
    """Seed k's weights as they are now: at its finish, before its masked slice moves on."""
    try:
        learner.save_slice(k, s.recorder.out_dir)
        s.saved = True
    except Exception as exc:  # disk full, permissions: no summary may claim success
        s.finish("error", f"could not write the run's files in {s.recorder.out_dir}: {type(exc).__name__}: {exc}")


def _flush(s: _Seed, learner, k: int) -> None:
    """A seed's last word: its weights (when it finished or was stopped) and its final summary."""
    if s.status in ("completed", "interrupted") and not s.saved:
        _save(s, learner, k)
    s.final = s.run.summary(s.status, s.message)
    s.final.write(s.recorder.out_dir)
