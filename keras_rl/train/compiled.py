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

The rest is every engine's one seed life (``train/life.py``: ``episodes.csv``, the metric,
the threshold, ``summary.json``, whose provenance names the engine), checkpoints at episode
boundaries for ``--resume`` (bit for bit), Ctrl-C and SIGTERM between episodes, TensorBoard,
evaluation during training and the final weights.

Posts 000, 003 and 001 (Keras) run here, every quirk switch honoured or refused before it
trains, with the reason and the switch (``CompiledEngine.refusal``); so is anything else. Post
001's episode is its acting alone (it trains only at an episode's end, P001-RETURNS), then its
burst is a second program over the batches the loop's own popping buffer pops (``MountainCarRun``).
Post 003's episodes end when the pole falls, so its program plays a chunk of up to 128 steps
or to the episode's end; the host lays out the chunk's draws (epsilon-greedy's uniform and random action, the sample
indices) in the loop's order, keeps each generator's state after every step, and after the
chunk sets each one where the loop's would stand after the steps played. Its draws depend on
nothing the program computes, so no counter-based generator is needed: the streams are the
loop's own.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import tensorflow as tf

from keras_rl.agents.skeleton import EpisodeStats, LossTally
from keras_rl.errors import ConfigError, NonFiniteLossError, argument
from keras_rl.experiment import Experiment
from keras_rl.learners.common import step_function
from keras_rl.learners.table import implementation
from keras_rl.rngs import rng_state, set_rng_state
from keras_rl.runs.summary import RunSummary
from keras_rl.seeding import configure_tensorflow, seed_everything
from keras_rl.tf_envs import MAX_STEPS, CartPole, MountainCarContinuous, Pendulum
from keras_rl.train.compiled_scope import ENGINE, refusal
from keras_rl.train.life import Checkpoints, SeedLife, close_lives, live, stop_requested
from keras_rl.train.settings import TrainSettings


class CompiledEngine:
    name = ENGINE

    def refusal(self, experiment: Experiment, config) -> str | None:
        return refusal(experiment.name, config)

    def train(
        self,
        experiment: Experiment,
        configs: Sequence,
        out_dirs: Sequence[Path],
        settings: TrainSettings,
        *,
        should_stop: Callable[[], bool] | None = None,
    ) -> list[RunSummary]:
        if len(configs) != 1:
            raise ConfigError(f"the compiled engine runs one seed per program: drop {argument('seed_batch')}")
        why = self.refusal(experiment, configs[0])
        if why is not None:
            raise ConfigError(why)
        run = RUNS[experiment.name](experiment, configs[0], Path(out_dirs[0]), settings)
        return [run.run(should_stop)]


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
        self.episode = step_function(  # kept as a concrete function: no per-call signature dispatch
            self._episode,
            True,
            tf.TensorSpec([2], tf.float64),  # the reset state
            tf.TensorSpec([self.steps, layout.action_dim], tf.float32),  # each step's noise
            tf.TensorSpec([self.steps, c.batch_size], tf.int32),  # each update's sample indices
            step_spec,  # which steps train
            tf.TensorSpec([], tf.int32),  # where the ring writes next
        ).get_concrete_function()

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
                out = learner.update(tf.gather(self.ring, indices[t]))
                return tf.stack([out[name] for name in names])

            losses = losses.write(t, tf.cond(trains[t], update, lambda: tf.zeros([len(names)], tf.float32)))
            obs = next_obs
        return score, losses.stack()

    def reset(self) -> None:
        self.ring.assign(tf.zeros_like(self.ring))


class ProgramCache:
    """The compiled programs of this process, one per program-shaping config, kept for the next
    seed: tracing and compiling a program costs about as much as a post 000 seed's training
    (``docs/performance.md``), and every seed of a command but its seed has the same config.

    A program is traced over one learner's variables and one ring; a later seed with the same
    config takes them over: its freshly built learner's state (weights, target weights, both
    optimizers' slots and step counts: ``state_dict``, the same records a checkpoint restores
    bit for bit) is loaded into the program's learner, and the ring is zeroed. What the seed then
    computes is what a program traced for it alone computes
    (``tests/test_compiled_engine.py::test_a_seed_on_a_kept_program_plays_what_it_plays_alone``).
    """

    UNSHAPING = {"seed": 0, "episodes": 1}
    """Config fields the traced program does not depend on (the host reads them), each set to one
    value in the key."""

    def __init__(self, size: int = 4):
        self.size = size
        self.kept: dict[tuple, tuple[Any, Any]] = {}

    def key(self, experiment: str, config) -> tuple:
        """The typed config itself, but for the fields no program depends on."""
        return (experiment, config.replace(**self.UNSHAPING))

    def take(self, experiment: str, config, fresh, make_program: Callable) -> tuple[Any, Any]:
        """The (learner, program) this seed runs on, the learner holding ``fresh``'s state."""
        key = self.key(experiment, config)
        if key not in self.kept:
            if len(self.kept) >= self.size:
                self.kept.pop(next(iter(self.kept)))  # the oldest
            self.kept[key] = (fresh, make_program(config, fresh))
            return self.kept[key]
        learner, program = self.kept.pop(key)
        self.kept[key] = (learner, program)  # the most recently used last
        learner.load_state_dict(fresh.state_dict())
        program.reset()
        return learner, program

    def clear(self) -> None:
        self.kept.clear()


PROGRAMS = ProgramCache()
"""This process's kept programs (a Ray worker's too: its seeds run one after another in it)."""


class CompiledRun:
    """One seed on the compiled engine: the host's side of each episode and the run's records.
    A post's subclass makes its program and plays an episode (``_play_episode``)."""

    def make_program(self, config, learner):
        raise NotImplementedError

    def _play_episode(self) -> tuple[float, int, EpisodeStats] | str:
        """One episode: its score, its steps and its learner statistics, or why the run stopped."""
        raise NotImplementedError

    def __init__(self, experiment: Experiment, config, out_dir: Path, settings: TrainSettings):
        self.experiment, self.config, self.settings = experiment, config, settings
        c = config
        configure_tensorflow(settings.threads)
        seed_everything(c.seed)  # the solo run's order: Keras seeded, the env, then the learner
        self.env = experiment.make_env(c)
        self.env.action_space.seed(c.seed)
        spec = experiment.env_spec(self.env)
        fresh = implementation(experiment.name, c.framework).load()(c, spec)  # this seed's initial weights
        agent = experiment.assemble(c, spec, fresh, self.env.action_space)
        self.buffer, self.explorer, self.schedule = agent.buffer, agent.explorer, agent.schedule
        self.transitions = agent.transitions
        self.action_space = self.env.action_space
        self.learner, self.program = PROGRAMS.take(experiment.name, c, fresh, self.make_program)
        self.life = SeedLife(experiment, c, out_dir, self.learner.loss_names, settings)
        self.records = self.life.records
        self.records.provenance["engine"] = ENGINE
        self.stored = 0
        """Transitions stored so far (the ring's write position is this modulo its size)."""
        self.played = 0
        """Steps the current episode has played in the chunks before this one (post 003)."""
        self.tally = LossTally(self.learner.loss_names)
        """Each episode's losses and the run's update count, as the loop keeps them."""
        self.checkpoints = Checkpoints(ENGINE, [c.seed], settings.checkpoint_every)

    def _reset_env(self) -> np.ndarray:
        """The next episode's start state, drawn by the Gymnasium env as the loop resets it."""
        self.env.reset(seed=self.config.seed) if self.life.episode == 0 else self.env.reset()
        return np.asarray(self.env.unwrapped.state, np.float64).copy()

    def _trains(self, t: int) -> bool:
        """Whether the chunk's step ``t`` trains: the schedule's rule (``EveryStep``) at the
        buffer size and step count after it."""
        size = min(self.stored + t + 1, self.config.buffer_size)
        total = self.records.total_steps + self.played + t + 1
        return size >= self.schedule.train_start and total % self.schedule.train_every == 0

    def _record_losses(self, losses: np.ndarray, trains: np.ndarray, steps: int) -> str | None:
        """The losses of a chunk's ``steps`` steps (those that trained) into the episode's tally,
        in order, as the loop adds them; the loop's message if one is not finite."""
        trained = np.flatnonzero(trains[:steps])
        first = self.records.total_steps + self.played + 1
        return self._tally(losses[trained], [f"env step {first + t}" for t in trained])

    def _tally(self, losses: np.ndarray, where: list[str]) -> str | None:
        """Each row of ``losses`` (one update's, in ``learner.loss_names`` order) into the
        episode's tally, in order, ``where[k]`` naming its env step; the loop's message at the
        first one that is not finite, the rows after it left out, as the loop stops there."""
        names = self.learner.loss_names
        for row, at in zip(losses, where):
            try:
                self.tally.add(dict(zip(names, np.atleast_1d(row))), at)
            except NonFiniteLossError as exc:
                return str(exc)
        return None

    # -- the run -----------------------------------------------------------------------------
    def run(self, should_stop: Callable[[], bool] | None = None) -> RunSummary:
        c, settings, life = self.config, self.settings, self.life
        if settings.resume:
            self._restore()
        if life.final is not None:  # it had finished before its checkpoint
            return life.final
        (final,) = live(
            self.experiment, [c], [life], settings, lambda flag, bar: self._loop(flag, bar, should_stop), self._close
        )
        return final

    def _loop(self, interrupted: list, bar, should_stop) -> None:
        life = self.life
        while life.active:
            played = self._play_episode()
            if isinstance(played, str):
                life.finish("non_finite_loss", played)
                return
            score, steps, stats = played
            life.episode += 1
            greedy = lambda obs: self.learner.act(self.transitions.observe(obs))  # noqa: E731 as the policy sees it (P001)
            if not life.end_episode(score, steps, stats, greedy, self.learner.save, bar):
                return
            if stop_requested([life], interrupted, should_stop, ask=True):
                return
            self.checkpoints.episode_ended()
            if self.checkpoints.due([life], 1):
                self._write_checkpoint()

    # -- checkpoints: the engine's own state (the envelope and the rest are life.Checkpoints') --
    def _engine_state(self) -> dict[str, Any]:
        return {
            "learner": self.learner.state_dict(),
            **self._replay_state(),
            "updates": self.tally.total_updates,
            "explorer": self.explorer.state_dict(),
            "env_rng": rng_state(self.env.unwrapped.np_random),
            "action_space_rng": rng_state(self.action_space.np_random),
        }

    def _load_engine_state(self, states: list[dict[str, Any]]) -> None:
        (own,) = states
        self.learner.load_state_dict(own["learner"])
        self._load_replay_state(own)
        self.tally.total_updates = int(own["updates"])
        self.explorer.load_state_dict(own["explorer"])
        set_rng_state(self.env.unwrapped.np_random, own["env_rng"])
        set_rng_state(self.action_space.np_random, own["action_space_rng"])

    def _replay_state(self) -> dict[str, Any]:
        """What the replay holds between episodes: the program's ring, how much was stored, and
        the sampling generator's state."""
        return {"ring": self.program.ring.numpy(), "stored": self.stored, "buffer_rng": rng_state(self.buffer.rng)}

    def _load_replay_state(self, own: dict[str, Any]) -> None:
        self.program.ring.assign(own["ring"])
        self.stored = int(own["stored"])
        set_rng_state(self.buffer.rng, own["buffer_rng"])

    def _write_checkpoint(self) -> None:
        self.checkpoints.write(self.life.episode, [(self.life, self._engine_state())])

    def _restore(self) -> None:
        lives = [self.life]
        Checkpoints.resume(lives, self.checkpoints.read(lives), self._load_engine_state)

    # -- the end ---------------------------------------------------------------------------------
    def _close(self) -> None:
        close_lives([self.life], self._write_checkpoint, lambda k: self.life.flush(self.learner.save))
        self.env.close()


class PendulumRun(CompiledRun):
    """Post 000: one program call per episode (200 steps, no termination)."""

    def make_program(self, config, learner):
        return PendulumProgram(config, learner)

    # -- what the Gymnasium loop would draw during the next episode ----------------------------
    def _streams(self):
        c, steps = self.config, self.program.steps
        state = self._reset_env()
        self.explorer.reset()  # post 000 §2.4: pre_noise = np.zeros(action_size)
        noise = np.stack([self.explorer.noise().astype(np.float32) for _ in range(steps)])
        indices = np.zeros((steps, c.batch_size), np.int32)
        trains = np.zeros(steps, bool)
        for t in range(steps):
            if self._trains(t):
                trains[t] = True
                indices[t] = self.buffer.rng.choice(min(self.stored + t + 1, c.buffer_size), c.batch_size, False)
        return state, noise, indices, trains

    def _play_episode(self) -> tuple[float, int, EpisodeStats] | str:
        state, noise, indices, trains = self._streams()
        position = self.stored % self.config.buffer_size
        score, losses = self.program.episode(
            tf.constant(state), tf.constant(noise), tf.constant(indices), tf.constant(trains), tf.constant(position)
        )
        self.tally.reset()
        stopped = self._record_losses(losses.numpy(), trains, self.program.steps)
        if stopped is not None:
            return stopped
        self.stored += self.program.steps
        return float(score.numpy()), self.program.steps, self.tally.stats()


class CartPoleProgram:
    """Post 003's env steps (the tutorial's loop body) as one XLA program, up to ``BLOCK`` steps
    or the episode's end, whichever comes first: act (epsilon-greedy, the draws laid out by the
    host), step, store, ``optimize_model`` and the soft update (or the soft update alone before
    the first batch)."""

    BLOCK = 128

    def __init__(self, config, learner):
        c = self.config = config
        self.learner = learner
        self.env = CartPole()
        self.limit = MAX_STEPS["CartPole-v1"]
        self.ring = tf.Variable(tf.zeros([c.buffer_size, learner.layout.width], tf.float32), trainable=False)
        block = tf.TensorSpec([self.BLOCK], tf.bool)
        self.chunk = step_function(  # kept as a concrete function: no per-call signature dispatch
            self._chunk,
            True,
            tf.TensorSpec([4], tf.float64),  # the state the chunk starts from
            tf.TensorSpec([], tf.int32),  # steps the episode has played before it
            tf.TensorSpec([], tf.int32),  # steps this chunk may play
            block,  # each step explores (the draw was below epsilon)
            tf.TensorSpec([self.BLOCK], tf.int32),  # the random action of each exploring step
            tf.TensorSpec([self.BLOCK, c.batch_size], tf.int32),  # each update's sample indices
            block,  # which steps train
            tf.TensorSpec([], tf.int32),  # where the ring writes next
        ).get_concrete_function()

    def _chunk(self, state, played, allowed, explore, random_actions, indices, trains, position):
        c, learner, env = self.config, self.learner, self.env
        losses = tf.TensorArray(tf.float32, self.BLOCK, element_shape=[])
        t = tf.constant(0)
        ended = tf.constant(False)
        while t < allowed and not ended:
            obs = env.observe(state)
            action = tf.where(explore[t], random_actions[t], learner._greedy(obs))
            state, next_obs, reward, terminated = env.step(state, action)
            row = tf.concat(
                [
                    obs,
                    tf.cast(action, tf.float32)[None],
                    tf.cast(reward, tf.float32)[None],
                    next_obs,
                    tf.cast(terminated, tf.float32)[None],
                ],
                0,
            )
            self.ring.scatter_nd_update([[(position + t) % c.buffer_size]], row[None, :])

            def update(t=t):
                return learner.update(tf.gather(self.ring, indices[t]))["loss"]

            def soft_update_only():
                learner._soft_update()  # the tutorial soft-updates every step, trained or not
                return tf.constant(0.0, tf.float32)

            losses = losses.write(t, tf.cond(trains[t], update, soft_update_only))
            ended = terminated | (played + t + 1 >= self.limit)
            t += 1
        return state, t, ended, losses.stack()

    def reset(self) -> None:
        self.ring.assign(tf.zeros_like(self.ring))


class CartPoleRun(CompiledRun):
    """Post 003 in Keras: an episode in chunks of up to ``CartPoleProgram.BLOCK`` steps. The host
    lays out each chunk's draws from the loop's own generators (one uniform per step for
    epsilon-greedy, a random action where it explores, the sample indices where it trains) and
    keeps each generator's state after every step, so that after the chunk it stands exactly
    where the loop's would after the steps the chunk played."""

    last_length = 16
    """The last episode's length: the first chunk of the next one is laid out for as many steps."""

    def make_program(self, config, learner):
        return CartPoleProgram(config, learner)

    def _draws(self, steps: int):
        c, block = self.config, CartPoleProgram.BLOCK
        explore = np.zeros(block, bool)
        random_actions = np.zeros(block, np.int32)
        indices = np.zeros((block, c.batch_size), np.int32)
        trains = np.zeros(block, bool)
        after = []  # each generator's state after step t's draws
        generators = (self.explorer.rng, self.action_space.np_random, self.buffer.rng)
        for t in range(steps):
            sample = self.explorer.rng.random()
            explore[t] = not sample > self.explorer.epsilon(self.explorer.steps_done + t)
            if explore[t]:
                random_actions[t] = int(self.action_space.sample())
            if self._trains(t):
                trains[t] = True
                indices[t] = self.buffer.rng.choice(min(self.stored + t + 1, c.buffer_size), c.batch_size, False)
            after.append([rng_state(g) for g in generators])
        return explore, random_actions, indices, trains, after, generators

    def _play_episode(self) -> tuple[float, int, EpisodeStats] | str:
        c = self.config
        state = tf.constant(self._reset_env())
        self.tally.reset()
        self.played, ended = 0, False
        while not ended:
            # the first chunk as long as the last episode (draws laid out for steps never played
            # cost host time), the later ones a whole block
            guess = CartPoleProgram.BLOCK if self.played else max(16, self.last_length)
            allowed = min(CartPoleProgram.BLOCK, guess, self.program.limit - self.played)
            explore, random_actions, indices, trains, after, generators = self._draws(allowed)
            state, steps, done, losses = self.program.chunk(
                state,
                tf.constant(self.played, tf.int32),
                tf.constant(allowed, tf.int32),
                tf.constant(explore),
                tf.constant(random_actions),
                tf.constant(indices),
                tf.constant(trains),
                tf.constant(self.stored % c.buffer_size, tf.int32),
            )
            steps, ended = int(steps), bool(done)
            for generator, kept in zip(generators, after[steps - 1]):
                set_rng_state(generator, kept)  # the draws of steps the chunk did not play are undone
            self.explorer.steps_done += steps
            stopped = self._record_losses(losses.numpy(), trains, steps)
            if stopped is not None:
                return stopped
            self.stored += steps
            self.played += steps
        played, self.played = self.played, 0
        self.last_length = played
        return float(played), played, self.tally.stats()


class MountainCarProgram:
    """Post 001's two programs: an episode's acting (up to 999 steps of the actor on the
    normalised state and the env, no training: its transitions reach the buffer only at the
    episode's end, P001-RETURNS) and a training burst (the learner's own update over the
    burst's batches, P001-POP and P001-TRIGGER)."""

    def __init__(self, config, learner):
        c = self.config = config
        self.learner = learner
        self.env = MountainCarContinuous()
        self.steps = MAX_STEPS["MountainCarContinuous-v0"]
        env = self.env
        # the observation space's bounds as Gymnasium keeps them (float32): P001's (s - low) / (high - low)
        self.obs_low = np.array([env.min_position, -env.max_speed], np.float32)
        self.obs_span = np.array([env.max_position, env.max_speed], np.float32) - self.obs_low
        capacity = c.train_start + self.steps + 1  # the most the popping buffer can hold (posts/mountaincar.py)
        self.burst_size = -(-(capacity - c.train_down_to) // c.batch_size)
        """The most batches one burst pops."""
        self.episode = step_function(  # kept as concrete functions: no per-call signature dispatch
            self._episode, True, tf.TensorSpec([2], tf.float64)
        ).get_concrete_function()
        self.burst = step_function(
            self._burst,
            True,
            tf.TensorSpec([self.burst_size, c.batch_size, learner.layout.width], tf.float32),
            tf.TensorSpec([], tf.int32),  # batches this burst pops
        ).get_concrete_function()

    def _episode(self, state):
        learner, env, steps = self.learner, self.env, self.steps
        low, span = tf.constant(self.obs_low), tf.constant(self.obs_span)
        observations = tf.TensorArray(tf.float32, steps, element_shape=[2])
        actions = tf.TensorArray(tf.float32, steps, element_shape=[1])
        rewards = tf.TensorArray(tf.float64, steps, element_shape=[])
        terminals = tf.TensorArray(tf.bool, steps, element_shape=[])
        t = tf.constant(0)
        ended = tf.constant(False)
        while t < steps and not ended:
            action = learner.actor(((env.observe(state) - low) / span)[None, :])[0]
            state, obs, reward, terminated = env.step(state, action, tf.equal(t, 0))
            observations = observations.write(t, obs)
            actions = actions.write(t, action)
            rewards = rewards.write(t, reward)
            terminals = terminals.write(t, terminated)
            ended = terminated
            t += 1
        return t, observations.stack(), actions.stack(), rewards.stack(), terminals.stack()

    def _burst(self, batches, count):
        learner = self.learner
        names = learner.loss_names
        losses = tf.TensorArray(tf.float32, self.burst_size, element_shape=[len(names)])
        for k in tf.range(self.burst_size):

            def update(k=k):
                out = learner.update(batches[k])
                return tf.stack([out[name] for name in names])

            losses = losses.write(k, tf.cond(k < count, update, lambda: tf.zeros([len(names)], tf.float32)))
        return losses.stack()

    def reset(self) -> None:
        """Nothing to clear: the popping buffer is the host's (a fresh one each seed)."""


class MountainCarRun(CompiledRun):
    """Post 001 in Keras: each episode's acting one program call, then, where the buffer holds
    more than ``train_start``, its burst one more. The host stores the episode's transitions as
    the loop stores them (``TransitionRule``: the normalised state, the raw next state, the
    standardised discounted returns) into the loop's own popping buffer, which pops the burst's
    batches from its own generator (no update touches it), so both engines train on the same
    batches."""

    def make_program(self, config, learner):
        return MountainCarProgram(config, learner)

    def _replay_state(self) -> dict[str, Any]:
        return {"buffer": self.buffer.state_dict()}

    def _load_replay_state(self, own: dict[str, Any]) -> None:
        self.buffer.load_state_dict(own["buffer"])

    def _play_episode(self) -> tuple[float, int, EpisodeStats] | str:
        state = self._reset_env()
        steps, observations, actions, rewards, terminals = self.program.episode(tf.constant(state))
        steps = int(steps)
        observations, actions, terminals = observations.numpy(), actions.numpy(), terminals.numpy()
        rewards = rewards.numpy()
        self.tally.reset()
        rule, score = self.transitions, 0.0
        rule.begin_episode()
        acted_on = rule.observe(state.astype(np.float32))  # what Gymnasium's reset returned
        for t in range(steps):
            truncated = t + 1 == self.program.steps
            self.buffer.add_rows(
                rule.rows(acted_on, actions[t], float(rewards[t]), observations[t], bool(terminals[t]), truncated)
            )
            acted_on = rule.observe(observations[t])
            score += float(rewards[t])
        total = self.records.total_steps + steps
        batches = self.schedule.batches(self.buffer, total)  # at the episode's last step, as the loop
        if batches:
            stopped = self._train_burst(batches, total)
            if stopped is not None:
                return stopped
        return score, steps, self.tally.stats()

    def _train_burst(self, batches: list[np.ndarray], total: int) -> str | None:
        program = self.program
        stacked = np.zeros((program.burst_size, *batches[0].shape), np.float32)
        stacked[: len(batches)] = batches
        losses = program.burst(tf.constant(stacked), tf.constant(len(batches), tf.int32)).numpy()
        return self._tally(losses[: len(batches)], [f"env step {total}"] * len(batches))


RUNS: dict[str, type[CompiledRun]] = {"pendulum": PendulumRun, "cartpole": CartPoleRun, "mountaincar": MountainCarRun}
"""The posts the compiled engine runs, each with its host side."""
