"""The vectorised engine (``--engine vectorised``): post 003's PyTorch tutorial on S seeds in one
program, ``keras_rl/torch/vectorised.VectorisedDQN``, stepped a chunk of env steps per host call.

A job's seeds are the batch: ``--seed-batch S`` packs them (``dispatch/jobs.batched``), and a solo
run is a batch of one. Each seed's results are its own, whichever seeds share its batch (the
core's counter-based streams), so a seed's ``episodes.csv`` and ``q_network.pt`` are the same
alone and in any batch (``tests/test_vectorised_engine.py``), but for the compiled program's loss
column, whose last digits follow the batch's size (its weights and episodes do not;
``benchmarks/vectorised_batch_bits.py``). They are not the Gymnasium loop's: the core's
docstring says what it keeps of the tutorial and what it draws otherwise.

Everything a run folder shows is every engine's one seed life (``train/life.py``): the rows of
``episodes.csv`` (the loss column is the mean of the episode's updates, summed in float64 on the
device), ``summary.json`` (its provenance names the engine, the device and, for S > 1, the
batch), TensorBoard, evaluation during training, the final weights as the tutorial agent saves
them (``q_network.pt``, the state dict of its ``DQN``), Ctrl-C and SIGTERM.

The host and the program:

- The program plays a chunk of up to ``CHUNK`` env steps, then the host reads the episodes that
  ended in it (``VectorisedDQN.play``) and hands each to its seed's life in order. A seed whose
  budget is done (or that stopped at its threshold, or at a non-finite loss) leaves the batch
  after that chunk (``VectorisedDQN.keep``): the batch sheds it instead of stepping it on,
  unrecorded, to the end of its longest seed. Its episodes within the chunk after its last are
  never recorded. The compiled program compiles once per batch size it meets, before and after
  the memory trains (``compiled``), and a process's later batches reuse those programs (cached
  on disk too, so the next process compiles them faster).
- A seed's policy is read between chunks only (``SeedPolicy``): for an evaluation, for its
  ``q_network.pt`` and for ``best/``. So a chunk never runs past the end of an episode after
  which a policy is read (a seed's last episode, one that ``--eval-every`` evaluates after, one
  that could reach the threshold where the run stops there): an episode lasts one env step at
  least, so the chunk is no longer than the episodes left before that one. The policy read is
  then the one at that episode's end, as in the Gymnasium loop, whatever the chunking. Near
  such an episode the chunks are short (one step each during it); for throughput without those
  reads, ``benchmarks/thousand_seeds.py`` drives the core alone.
- Where a signal or the dispatcher's stop request arrives, it is taken after the chunk: every
  running seed ends ``interrupted`` and every seed of the batch writes its checkpoint.
- Checkpoints (``--checkpoint-every N``) count episodes as the Gymnasium loop counts a batch's:
  after the chunk in which the batch has recorded N episodes per seed (N x S in all, S the
  seeds still in it) since the last one. Each seed's ``checkpoint.pkl`` holds its life's records
  (as ``train/compiled.py``'s do), its own part of the core (``VectorisedDQN.seed_states``:
  networks, optimizer, memory, env and episode counters), the batch and the env step ``t`` as
  its vector step; ``--resume`` continues from them bit for bit, and the seeds of a batch resume
  at one ``t``. A seed the batch shed keeps its last checkpoint until the batch writes its next,
  so that a batch killed in between resumes whole from the step they share and sheds it again
  where it did; after that, the seeds of the batch that hold a checkpoint resume without it. A solo run that
  played its whole budget keeps its final checkpoint, taken at its last episode's end, so
  ``--resume --episodes N`` extends it as a straight run of N would have played.

It runs on CUDA where torch sees a GPU, else on the CPU with one thread (as the tutorial's agent
does), eagerly as ``vectorised``; as ``vectorised-compiled`` its step is compiled by
``torch.compile``, which costs 30-95 s per process on a CPU (more than a test or a short run can
wait) and then steps about 2.5x faster there (``docs/performance.md``). The two are two programs
whose bits differ, so each is an engine name of its own, recorded and resumed by itself.

``refusal`` (no torch or TensorFlow imported) names what the engine cannot run faithfully:
anything but post 003 in PyTorch from the tutorial's own initial weights.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from keras_rl.agents.skeleton import EpisodeStats
from keras_rl.config import check_same_but_seed
from keras_rl.dynamics import MAX_STEPS
from keras_rl.errors import ConfigError, RunFolderError, argument
from keras_rl.experiment import Experiment
from keras_rl.runs.checkpoint import delete_checkpoints
from keras_rl.runs.summary import RunSummary
from keras_rl.train.life import Checkpoints, SeedLife, close_lives, live, stop_requested
from keras_rl.train.settings import TrainSettings

ENGINE = "vectorised"
COMPILED_ENGINE = "vectorised-compiled"
"""The same engine with its step compiled by ``torch.compile``: another program, whose rounding
differs from the eager one's (measured: 8 seeds part within 4,000 steps), so it is an engine of
its own name, recorded by its runs and resumed only by itself."""
CHUNK = 500
"""The most env steps of one host call."""


def refusal(experiment: str, config) -> str | None:
    """Why the vectorised engine cannot run ``config`` of ``experiment`` (every reason at once), or
    None. It runs the tutorial's DQN as ``keras_rl/torch/vectorised.py`` writes it: post 003, in
    PyTorch, from the tutorial's torch initialisation, on CartPole-v1, with AMSGrad."""
    if experiment != "cartpole":
        return (
            f"the vectorised engine runs cartpole (post 003's PyTorch tutorial) only; run {experiment} "
            f"with {argument('engine', 'gymnasium')}"
        )
    reasons = []
    if config.framework != "torch":
        reasons.append(
            f"it runs the PyTorch tutorial's DQN ({argument('framework', 'torch')}), not framework "
            f"{config.framework!r}; "
            f"the Keras side runs with {argument('engine', 'compiled')}"
        )
    if config.init != "torch":
        reasons.append(f"it starts from the tutorial's torch initialisation only, not init={config.init!r} (P003-INIT)")
    if config.matched_init:
        reasons.append(
            f"it starts from the tutorial's own initial weights, not the Keras ones (drop {argument('matched_init')})"
        )
    if config.env_id != "CartPole-v1":
        reasons.append(f"it has CartPole-v1 in PyTorch, not env_id {config.env_id!r}")
    if not config.amsgrad:
        reasons.append("its AdamW is the tutorial's, with AMSGrad: amsgrad=false is not there")
    if config.train_start < config.batch_size:
        reasons.append(
            f"a batch is {config.batch_size} distinct memory slots, so training cannot start at "
            f"train_start={config.train_start}"
        )
    if reasons and config.framework == "torch":
        reasons[-1] += f"; run it with {argument('engine', 'gymnasium')}"
    return "; ".join(reasons) or None


class VectorisedEngine:
    def __init__(self, compiled: bool = False):
        self.compiled = compiled
        self.name = COMPILED_ENGINE if compiled else ENGINE

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
        configs = list(configs)
        check_same_but_seed(configs)
        why = self.refusal(experiment, configs[0])
        if why is not None:
            raise ConfigError(why)
        return VectorisedRun(experiment, configs, [Path(d) for d in out_dirs], settings, self.compiled).run(should_stop)


class VectorisedRun:
    """One job on the vectorised engine: its seeds' lives around one ``VectorisedDQN``."""

    def __init__(
        self,
        experiment: Experiment,
        configs: list,
        out_dirs: list[Path],
        settings: TrainSettings,
        compiled: bool = False,
    ):
        from keras_rl.torch import single_threaded
        from keras_rl.torch.vectorised import VectorisedDQN, default_device

        self.experiment, self.configs, self.settings = experiment, configs, settings
        device = default_device()
        if device.type == "cpu":
            single_threaded()
        self.core = VectorisedDQN(configs, device, compile=compiled, chunk=CHUNK)
        self.engine = COMPILED_ENGINE if compiled else ENGINE
        self.batch = [c.seed for c in configs]
        self.life_of = {seed: k for k, seed in enumerate(self.batch)}
        """Each seed's index in ``lives``."""
        self.lives = [SeedLife(experiment, c, d, ("loss",), settings) for c, d in zip(configs, out_dirs)]
        for life in self.lives:
            life.records.provenance.update(engine=self.engine, device=str(device))
            if len(self.lives) > 1:  # one wall clock for the batch (its bits do not depend on it)
                life.records.provenance["seed_batch"] = self.batch
        self.policies: dict[int, Any] = {}
        """Each seed's ``SeedPolicy`` read since the last chunk."""
        self.checkpoints = Checkpoints(self.engine, self.batch, settings.checkpoint_every)

    # -- the run -----------------------------------------------------------------------------
    def run(self, should_stop: Callable[[], bool] | None = None) -> list[RunSummary]:
        if self.settings.resume:
            self._restore()
        return live(
            self.experiment,
            self.configs,
            self.lives,
            self.settings,
            lambda flag, bar: self._loop(flag, bar, should_stop),
            self._close,
        )

    def _loop(self, interrupted: list, bar, should_stop) -> None:
        lives = self.lives
        while any(life.active for life in lives):
            ends = self.core.play(self._chunk_steps())
            self.policies.clear()
            for end in ends:
                k = self.life_of[end.seed]
                life = lives[k]
                if not life.active:  # done with its budget: its later episodes are not its run's
                    continue
                if end.episode != life.episode + 1:
                    raise RuntimeError(f"seed {end.seed} ended episode {end.episode} after {life.episode}")
                life.episode = end.episode
                self.checkpoints.episode_ended()
                if not math.isfinite(end.loss_sum):
                    life.finish(
                        "non_finite_loss",
                        f"loss became {end.loss_sum / max(end.updates, 1)} in episode {end.episode} (the mean of "
                        f"its {end.updates} updates, read at the episode's end); the run stops here and keeps "
                        "the episodes already written",
                    )
                    self._flush(k)
                    continue
                stats = EpisodeStats(end.updates, {"loss": end.loss_sum / end.updates if end.updates else None})
                greedy = lambda obs, k=k: self._policy(k)(obs)  # noqa: E731 the policy at the chunk's end
                save = lambda d, k=k: self._policy(k).save(d)  # noqa: E731
                if not life.end_episode(float(end.steps), end.steps, stats, greedy, save, bar):
                    self._flush(k)
            if stop_requested(lives, interrupted, should_stop, ask=bool(ends)):
                return
            if self.checkpoints.due(lives, len(self.core.seeds)):
                self._write_checkpoints()
            self._shed()

    def _shed(self) -> None:
        """The core keeps only the seeds still running, where some are done but not all: a seed
        done with its budget (or stopped) stepped on with the batch, unrecorded, to its longest
        seed's end (a third of a batch of 8's seed-steps on post 003: ``benchmarks/lockstep_waste.py``)."""
        rows = [k for k, seed in enumerate(self.core.seeds) if self.lives[self.life_of[seed]].active]
        if rows and len(rows) < len(self.core.seeds):
            self.core.keep(rows)
            self.policies.clear()

    def _chunk_steps(self) -> int:
        """The next chunk's length: ``CHUNK``, or fewer, so that no running seed can end an episode
        after which its policy is read before the chunk's last step (each episode lasts a step
        at least)."""
        return max(1, min([CHUNK, *(self._next_read(life) - life.episode for life in self.lives if life.active)]))

    def _next_read(self, life: SeedLife) -> int:
        """The first episode after ``life.episode`` at whose end the seed's policy may be read: its
        last, the next one evaluated after, or the first that could reach its threshold (scoring
        the most an episode can, every episode from the next) where the run stops there."""
        c = life.config
        candidates = [c.episodes]
        if life.evaluator is not None:
            every = life.evaluator.schedule.every
            candidates.append((life.episode // every + 1) * every)
        if c.stop_at_threshold and life.records.reached_at is None:
            metric, best = copy.deepcopy(life.records.metric), float(MAX_STEPS[c.env_id])
            for n in range(life.episode + 1, min(c.episodes, life.episode + CHUNK)):
                if metric.passes(metric.update(best), c.threshold):
                    candidates.append(n)
                    break
        return min(candidates)

    def _policy(self, k: int):
        """Seed ``lives[k]``'s policy, read from its row in the core."""
        from keras_rl.torch.vectorised import SeedPolicy

        if k not in self.policies:
            self.policies[k] = SeedPolicy(self.core, self.core.seeds.index(self.batch[k]))
        return self.policies[k]

    # -- checkpoints ---------------------------------------------------------------------------
    def _write_checkpoints(self) -> None:
        """The checkpoint of every seed in the core at its step ``t``, each into its own folder,
        naming the batch the job started as; then the shed seeds' older ones go, so that the
        batch resumes as it is now. Killed before they go, the batch resumes whole from the step
        its seeds share (the seeds ahead from their previous checkpoint) and sheds them again."""
        self.checkpoints.write(
            self.core.t,
            [(self.lives[self.life_of[seed]], own) for seed, own in zip(self.core.seeds, self.core.seed_states())],
        )
        for seed in set(self.batch) - set(self.core.seeds):  # shed: their older checkpoints go
            delete_checkpoints(self.lives[self.life_of[seed]].out_dir)

    def _restore(self) -> None:
        states = self.checkpoints.read(self.lives, part=True)
        steps = sorted({int(state["engine_state"]["t"]) for state in states})
        if len(steps) != 1:
            raise RunFolderError(
                f"the checkpoints of seeds {self.batch} hold env steps {steps}; the seeds of one vectorised "
                f"batch resume at one step: resume each one alone, or pass {argument('overwrite')} to start again"
            )
        Checkpoints.resume(self.lives, states, self._load_engine_states)

    def _load_engine_states(self, states: list[dict[str, Any]]) -> None:
        for life in self.lives:
            life.extending = False  # the core's next episode has begun (its reset is inside the step)
        self.core.load_seed_states(states)

    # -- the end ---------------------------------------------------------------------------------
    def _flush(self, k: int) -> None:
        """Seed ``k``'s last word, with its policy as it stands (the end of its last episode)."""
        self.lives[k].flush(lambda d: self._policy(k).save(d))

    def _close(self) -> None:
        close_lives(self.lives, self._write_checkpoints, self._flush)
