"""The compiled engine: a post's whole episode as one XLA program, one host call per episode.

Inside the program: the env (``keras_rl/tf_envs.py``), exploration, the replay ring (a
``tf.Variable``), sampling and the learner's own compiled update (``learners/ddpg.py``'s
``update``, traced into the bigger program: there is no second copy of it), and the records
an episode needs (its score, its losses summed in float64, its update count). Outside it,
once per episode, the host lays out what the Gymnasium loop would draw during the episode,
from the same generators in the same order, so that the two engines stay as close as
rounding allows (``tests/test_compiled_engine.py`` measures how close):

- the reset state, from the Gymnasium env's own generator, seeded as the loop seeds it;
- the exploration noise of every step (post 000's OU noise never depends on the actions);
- the sample indices of every update (post 000's buffer size at every step is known).

The rest is the Gymnasium loop's own bookkeeping (``SeedRun``: ``episodes.csv``, the metric,
the threshold, ``summary.json``, whose provenance names the engine), checkpoints at episode
boundaries for ``--resume`` (bit for bit), Ctrl-C and SIGTERM between episodes, TensorBoard,
evaluation during training and the final weights.

Post 000 (Keras) runs here today, every quirk switch honoured; anything else is refused
before it trains, with the reason (``CompiledEngine.refusal``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import tensorflow as tf

from keras_rl.agents.skeleton import EpisodeStats
from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.experiment import Experiment
from keras_rl.learners.table import implementation
from keras_rl.rngs import global_rng_state, rng_state, set_global_rng_state, set_rng_state
from keras_rl.runs.checkpoint import VERSION, delete_checkpoints, read_batch_checkpoints, write_checkpoint
from keras_rl.runs.evaluate import TrainingEvaluator
from keras_rl.runs.files import RunRecorder, atomic_write_text, episode_columns, episodes_csv_text
from keras_rl.runs.lifecycle import check_resume_config
from keras_rl.runs.signals import signal_name, stop_signals_as_flag, stop_signals_deferred
from keras_rl.runs.summary import RunSummary, Status
from keras_rl.seeding import configure_tensorflow, seed_everything
from keras_rl.tf_envs import MAX_STEPS, Pendulum
from keras_rl.train.loop import SeedRun, _progress_bar, _TensorBoard
from keras_rl.train.settings import TrainSettings

ENGINE = "compiled"


class CompiledEngine:
    name = ENGINE

    def refusal(self, experiment: Experiment, config) -> str | None:
        if experiment.name != "pendulum":
            return f"the compiled engine runs pendulum (post 000) so far; run {experiment.name} with --engine gymnasium"
        if config.framework != "keras":
            return "the compiled engine runs the Keras learner; the PyTorch side runs with --engine gymnasium"
        if config.env_id != "Pendulum-v1":
            return f"the compiled engine has Pendulum-v1 in TensorFlow, not env_id {config.env_id!r}"
        return None

    def train(
        self,
        experiment: Experiment,
        configs: Sequence,
        out_dirs: Sequence[Path],
        settings: TrainSettings,
        should_stop: Callable[[], bool] | None = None,
    ) -> list[RunSummary]:
        if len(configs) != 1:
            raise ConfigError("the compiled engine runs one seed per program: drop --seed-batch")
        why = self.refusal(experiment, configs[0])
        if why is not None:
            raise ConfigError(why)
        return [PendulumRun(experiment, configs[0], Path(out_dirs[0]), settings).run(should_stop)]


class PendulumProgram:
    """Post 000's episode (§2.4's inner loop) as one XLA program over the learner's variables."""

    def __init__(self, config, learner):
        c = self.config = config
        self.learner = learner
        self.env = Pendulum(c.gravity)
        self.steps = MAX_STEPS["Pendulum-v1"]
        layout = learner.layout
        self.ring = tf.Variable(tf.zeros([c.buffer_size, layout.width], tf.float32), trainable=False)
        step_spec = tf.TensorSpec([self.steps], tf.bool)
        self.episode = tf.function(
            self._episode,
            jit_compile=True,
            input_signature=[
                tf.TensorSpec([2], tf.float64),  # the reset state
                tf.TensorSpec([self.steps, layout.action_dim], tf.float32),  # each step's noise
                tf.TensorSpec([self.steps, c.batch_size], tf.int32),  # each update's sample indices
                step_spec,  # which steps train
                tf.TensorSpec([], tf.int32),  # where the ring writes next
            ],
        )

    def _episode(self, state, noise, indices, trains, position):
        c, learner, env = self.config, self.learner, self.env
        names = learner.loss_names
        losses = tf.TensorArray(tf.float32, self.steps, element_shape=[len(names)])
        score = tf.constant(0.0, tf.float64)
        obs = env.observe(state)
        for t in tf.range(self.steps):
            action = tf.clip_by_value(learner.actor(obs[None, :])[0] + noise[t], -c.action_clip, c.action_clip)
            state, next_obs, reward, terminated = env.step(state, action)
            truncated = tf.equal(t, self.steps - 1)
            done = truncated if c.done_from_truncated else terminated  # P000-DONE
            row = tf.concat(
                [obs, action, tf.cast(reward, tf.float32)[None], next_obs, tf.cast(done, tf.float32)[None]], 0
            )
            self.ring.scatter_nd_update([[(position + t) % c.buffer_size]], row[None, :])
            score += reward

            def update(t=t):
                out = learner._train_rows(tf.gather(self.ring, indices[t]))
                return tf.stack([out[name] for name in names])

            losses = losses.write(t, tf.cond(trains[t], update, lambda: tf.zeros([len(names)], tf.float32)))
            obs = next_obs
        return score, losses.stack()


class PendulumRun:
    """One seed on the compiled engine: the host's side of each episode and the run's records."""

    def __init__(self, experiment: Experiment, config, out_dir: Path, settings: TrainSettings):
        self.experiment, self.config, self.settings = experiment, config, settings
        c = config
        configure_tensorflow(settings.threads)
        seed_everything(c.seed)  # the solo run's order: Keras seeded, the env, then the learner
        self.env = experiment.make_env(c)
        self.env.action_space.seed(c.seed)
        spec = experiment.env_spec(self.env)
        self.learner = implementation(experiment.name, c.framework).load()(c, spec)
        agent = experiment.assemble(c, spec, self.learner, self.env.action_space)
        self.buffer, self.explorer, self.schedule = agent.buffer, agent.explorer, agent.schedule
        self.program = PendulumProgram(c, self.learner)
        self.recorder = RunRecorder(out_dir, self.learner.loss_names)
        self.run_ = SeedRun(experiment, c, self.recorder, experiment.make_metric(c), settings.command)
        self.run_.provenance["engine"] = ENGINE
        self.stored = 0
        """Transitions stored so far (the ring's write position is this modulo its size)."""
        self.updates = 0
        self.episode = 0
        self.status: Status = "running"
        self.message = ""
        self.saved = False
        self.evaluator = (
            TrainingEvaluator(experiment, c, self.recorder.out_dir, settings.evaluation)
            if settings.evaluation is not None
            else None
        )
        self.writer: _TensorBoard | None = None

    # -- what the Gymnasium loop would draw during the next episode ----------------------------
    def _streams(self):
        c, steps = self.config, self.program.steps
        self.env.reset(seed=c.seed) if self.episode == 0 else self.env.reset()
        state = np.asarray(self.env.unwrapped.state, np.float64).copy()
        self.explorer.reset()  # post 000 §2.4: pre_noise = np.zeros(action_size)
        noise = np.stack([self.explorer.noise().astype(np.float32) for _ in range(steps)])
        indices = np.zeros((steps, c.batch_size), np.int32)
        trains = np.zeros(steps, bool)
        for t in range(steps):
            size = min(self.stored + t + 1, c.buffer_size)
            total = self.run_.total_steps + t + 1
            if size >= self.schedule.train_start and total % self.schedule.train_every == 0:
                trains[t] = True
                indices[t] = self.buffer.rng.choice(size, size=c.batch_size, replace=False)
        return state, noise, indices, trains

    def _play_episode(self) -> tuple[float, EpisodeStats] | str:
        """One episode; its score and learner statistics, or why it stopped (a non-finite loss)."""
        state, noise, indices, trains = self._streams()
        position = self.stored % self.config.buffer_size
        score, losses = self.program.episode(
            tf.constant(state), tf.constant(noise), tf.constant(indices), tf.constant(trains), tf.constant(position)
        )
        losses = losses.numpy()[trains].astype(np.float64)
        names = self.learner.loss_names
        for k, values in enumerate(losses):
            bad = [(name, v) for name, v in zip(names, values) if not np.isfinite(v)]
            if bad:
                step = self.run_.total_steps + int(np.flatnonzero(trains)[k]) + 1
                return (
                    f"{bad[0][0]} became {bad[0][1]} at update {self.updates + k + 1} (env step {step}); "
                    "the run stops here and keeps the episodes already written"
                )
        self.stored += self.program.steps
        self.updates += len(losses)
        sums = [sum(losses[:, i].tolist()) for i in range(len(names))]  # in order, as the loop's tally
        means = {name: (s / len(losses) if len(losses) else None) for name, s in zip(names, sums)}
        return float(score.numpy()), EpisodeStats(len(losses), means)

    # -- the run -----------------------------------------------------------------------------
    def run(self, should_stop: Callable[[], bool] | None = None) -> RunSummary:
        c, settings = self.config, self.settings
        if settings.resume:
            self._restore()
        if self.status == "running":
            self.recorder.write_config(c.to_dict())
            self.run_.summary("running").write(self.recorder.out_dir)
        else:
            return RunSummary.read(self.recorder.out_dir)
        if settings.tensorboard:
            self.writer = _TensorBoard(settings.tensorboard, c)
        bar = _progress_bar(self.experiment, [c], [self], settings.position) if settings.progress else None
        final = None
        try:
            with stop_signals_as_flag() as interrupted:
                self._loop(interrupted, bar, should_stop)
        except Exception as exc:
            if self.status == "running":
                self.status, self.message = "error", f"{type(exc).__name__}: {exc}"
            raise
        finally:
            with stop_signals_deferred(reraise=False):
                if bar is not None:
                    bar.close()
                final = self._close()
        return final

    def _loop(self, interrupted: list, bar, should_stop) -> None:
        c = self.config
        since = 0
        while self.status == "running":
            played = self._play_episode()
            if isinstance(played, str):
                self.status, self.message = "non_finite_loss", played
                return
            score, stats = played
            self.episode += 1
            row = self.run_.record_episode(self.episode, score, self.program.steps, stats)
            if self.writer is not None:
                self.writer.episode(row)
            if self.evaluator is not None and self.evaluator.due(self.episode):
                self.evaluator.evaluate(
                    self.episode,
                    lambda obs: self.learner.act(np.asarray(obs, np.float32)),
                    self.learner.save,
                    self.writer,
                )
            if bar is not None:
                bar.update(1)
                bar.set_postfix(score=f"{row['score']:.1f}", metric=f"{row['metric']:.1f}", refresh=False)
            if (self.run_.reached_at is not None and c.stop_at_threshold) or self.episode >= c.episodes:
                self.status = "completed"
                return
            if interrupted or (should_stop is not None and should_stop()):
                by = signal_name(interrupted) if interrupted else "the dispatcher's stop request (Ctrl-C or SIGTERM)"
                self.status = "interrupted"
                self.message = f"stopped by {by}; the episodes so far are kept (--resume continues)"
                return
            since += 1
            if self.settings.checkpoint_every and since >= self.settings.checkpoint_every:
                self._write_checkpoint()
                since = 0

    # -- checkpoints ---------------------------------------------------------------------------
    def _snapshot(self) -> dict[str, Any]:
        run = self.run_
        return {
            "version": VERSION,
            "engine": ENGINE,
            "batch": [self.config.seed],
            "vector_step": self.episode,
            "global_rng": global_rng_state(),
            "seed": {
                **run.snapshot(self.status, self.message),
                "episode": self.episode,
                "saved": self.saved,
            },
            "engine_state": {
                "learner": self.learner.state_dict(),
                "ring": self.program.ring.numpy(),
                "stored": self.stored,
                "updates": self.updates,
                "buffer_rng": rng_state(self.buffer.rng),
                "explorer": self.explorer.state_dict(),
                "env_rng": rng_state(self.env.unwrapped.np_random),
            },
        }

    def _write_checkpoint(self) -> None:
        write_checkpoint(self.recorder.out_dir, self._snapshot())

    def _restore(self) -> None:
        (state,) = read_batch_checkpoints([self.recorder.out_dir], [self.config.seed])
        if state.get("engine") != ENGINE:
            raise RunFolderError(
                f"{self.recorder.out_dir}'s checkpoint was written by the {state.get('engine', 'gymnasium')} engine; "
                "resume it with that engine (--engine), or pass --overwrite to start again"
            )
        seed, own = state["seed"], state["engine_state"]
        wanted, theirs = self.config.to_dict(), seed["config"]
        played = len(seed["rows"])
        check_resume_config(self.recorder.out_dir, wanted, theirs, played)
        run = self.run_
        run.restore(seed)
        self.status, self.message = seed["status"], seed["message"]
        self.episode, self.saved = int(seed["episode"]), bool(seed["saved"])
        self.learner.load_state_dict(own["learner"])
        self.program.ring.assign(own["ring"])
        self.stored, self.updates = int(own["stored"]), int(own["updates"])
        set_rng_state(self.buffer.rng, own["buffer_rng"])
        self.explorer.load_state_dict(own["explorer"])
        set_rng_state(self.env.unwrapped.np_random, own["env_rng"])
        set_global_rng_state(state["global_rng"])
        stopped_early = run.reached_at is not None and self.config.stop_at_threshold
        if self.status == "completed" and played == int(theirs["episodes"]) < wanted["episodes"] and not stopped_early:
            self.status, self.saved = "running", False  # a larger budget continues it
        if self.status == "running":
            atomic_write_text(
                self.recorder.out_dir / "episodes.csv",
                episodes_csv_text(self.recorder.rows, episode_columns(self.recorder.loss_names)),
            )
            if self.evaluator is not None:
                self.evaluator.resume(played)
        print(
            f"seed {self.config.seed}: resumed in {self.recorder.out_dir} after episode {played} "
            f"(its checkpoint; {run.total_steps} steps)",
            file=sys.stderr,
        )

    # -- the end ---------------------------------------------------------------------------------
    def _close(self) -> RunSummary:
        c = self.config
        if self.status == "running":
            self.status, self.message = "error", "the run stopped on an error"
        if self.status in ("completed", "interrupted") and not self.saved:
            try:
                self.learner.save(self.recorder.out_dir)
                self.saved = True
            except Exception as exc:
                self.status = "error"
                self.message = (
                    f"could not write the run's files in {self.recorder.out_dir}: {type(exc).__name__}: {exc}"
                )
        stopped_early = self.run_.reached_at is not None and c.stop_at_threshold
        if self.status == "interrupted":
            self._write_checkpoint()
        elif self.status == "completed" and self.episode == c.episodes and not stopped_early:
            self._write_checkpoint()  # kept, so --resume --episodes N extends it
        elif self.status in ("completed", "non_finite_loss"):
            delete_checkpoints(self.recorder.out_dir)
        if self.writer is not None:
            self.writer.close()
        if self.evaluator is not None:
            self.evaluator.close()
        self.env.close()
        final = self.run_.summary(self.status, self.message)
        final.write(self.recorder.out_dir)
        return final
