"""Seed-batched learners: S seeds' networks stacked on a leading seed axis, one compiled step.

Each layer holds a kernel ``[S, in, out]`` and a bias ``[S, out]`` and is applied with a
batched matmul (``einsum("sbi,sio->sbo")``), so seed k's slice sees only seed k's data.
The loss is the *sum* over seeds of each seed's own loss: the gradient of seed k's slice is
then exactly its solo gradient, and Adam (one step counter per seed, ``SeedAdam``) and the
soft update are elementwise, so each slice steps as its solo run would. Nothing global (a
norm, a mean across seeds) enters the step.

Seed k's slice starts from the very weights seed k's solo run draws: ``stack_post001`` seeds
Keras as a solo run does, builds the solo networks, and stacks them. Posts 000 and 003's
stacked learners were retired by issue 34: their compiled solo runs cost less per seed
(``learners/table.RETIRED``).
A stack of one seed is the solo learner itself (``SoloAsStack``).

The episode loop over a seed axis is ``train/loop.py``; the equivalence tests are
``tests/test_stacked_post001.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import keras
import numpy as np
import tensorflow as tf

from keras_rl.buffers import Layout
from keras_rl.envs import EnvSpec
from keras_rl.errors import argument
from keras_rl.learners.common import save_weights
from keras_rl.learners.ddpg import DDPGLearner, post001_networks
from keras_rl.learners.optimizers import SeedAdam
from keras_rl.seeding import seed_everything

NETWORKS = ("actor", "critic", "target_actor", "target_critic")
"""A DDPG post's networks, as ``slice_weights`` names them."""


def model_variables(model) -> list:
    """A solo network's variables in order, but for a noise layer's seed-generator state
    (post 001's GaussianNoise, the identity at learning phase 0): what a stack holds of it."""
    return [v for v in model.variables if "seed_generator" not in v.path]


class SliceState:
    """A seed's part of a stacked learner's state, for its own checkpoint: every variable
    with a seed axis (the networks' and the optimizer's moments) sliced at k; the scalars
    (the optimizer's step count and learning rate) are the same for every seed. The
    learner lists its variables in ``_stateful()``."""

    _stateful: Callable[[], list]

    def slice_state(self, k: int) -> dict:
        return {"variables": [v.numpy()[k].copy() if len(v.shape) else v.numpy().copy() for v in self._stateful()]}

    def load_slice_state(self, k: int, state: dict) -> None:
        variables, values = self._stateful(), state["variables"]
        if len(variables) != len(values):
            raise ValueError(f"checkpoint holds {len(values)} values for {len(variables)} variables")
        for variable, value in zip(variables, values):
            if len(variable.shape):
                whole = variable.numpy()
                whole[k] = value
                variable.assign(whole)
            else:
                variable.assign(value)


class StackedDense(keras.layers.Layer):
    """``Dense`` for S seeds at once: ``[S, B, in] -> [S, B, out]``."""

    def __init__(self, seeds: int, units_in: int, units: int, activation=None):
        super().__init__()
        self.kernel = self.add_weight(shape=(seeds, units_in, units), initializer="zeros", name="kernel")
        self.bias = self.add_weight(shape=(seeds, units), initializer="zeros", name="bias")
        self.activation = keras.activations.get(activation)

    def call(self, x: tf.Tensor) -> tf.Tensor:
        return self.activation(tf.einsum("sbi,sio->sbo", x, self.kernel) + self.bias[:, None, :])

    def set_from(self, denses: Sequence[keras.layers.Dense]) -> None:
        """Seed k's slice := the k-th solo layer's weights."""
        self.kernel.assign(np.stack([d.kernel.numpy() for d in denses]))
        self.bias.assign(np.stack([d.bias.numpy() for d in denses]))


class StackedBatchNorm(keras.layers.Layer):
    """``BatchNormalization`` at learning phase 0 for S seeds (post 001, P001-PHASE): each
    seed normalises with its own moving statistics, which nothing updates; its gamma and
    beta train. ``[S, B, F] -> [S, B, F]``. Variables in Keras' order (gamma, beta, moving
    mean, moving variance), so a seed's slice is its solo layer's weights."""

    def __init__(self, seeds: int, features: int, epsilon: float):
        super().__init__()
        self.gamma = self.add_weight(shape=(seeds, features), initializer="ones", name="gamma")
        self.beta = self.add_weight(shape=(seeds, features), initializer="zeros", name="beta")
        self.moving_mean = self.add_weight(
            shape=(seeds, features), initializer="zeros", name="moving_mean", trainable=False
        )
        self.moving_variance = self.add_weight(
            shape=(seeds, features), initializer="ones", name="moving_variance", trainable=False
        )
        self.epsilon = float(epsilon)

    def call(self, x: tf.Tensor) -> tf.Tensor:
        return tf.nn.batch_normalization(
            x,
            self.moving_mean[:, None, :],
            self.moving_variance[:, None, :],
            self.beta[:, None, :],
            self.gamma[:, None, :],
            self.epsilon,
        )

    def set_from(self, norms: Sequence[keras.layers.BatchNormalization]) -> None:
        for mine, name in (
            (self.gamma, "gamma"),
            (self.beta, "beta"),
            (self.moving_mean, "moving_mean"),
            (self.moving_variance, "moving_variance"),
        ):
            mine.assign(np.stack([getattr(n, name).numpy() for n in norms]))


def _stacked_dense(solos: Sequence, seeds: int, units_in: int) -> StackedDense:
    """A stack of the k-th solo ``Dense`` of every seed, its activation included."""
    first = solos[0]
    layer = StackedDense(seeds, units_in, first.units, first.activation)
    layer.set_from(solos)
    return layer


class StackedMountainCarActor(keras.Model):
    """Post 001's actor for S seeds at learning phase 0: the noise layer is the identity,
    then BatchNormalization, 3 x Dense 32 selu, Dense(act, tanh)."""

    def __init__(self, solos: Sequence[keras.Model], obs_dim: int):
        super().__init__()
        s, widths = len(solos), [obs_dim, *(d.units for d in solos[0].hidden)]
        self.norm = StackedBatchNorm(s, obs_dim, solos[0].norm.epsilon)
        self.norm.set_from([m.norm for m in solos])
        self.hidden = [_stacked_dense([m.hidden[i] for m in solos], s, w) for i, w in enumerate(widths[:-1])]
        self.out = _stacked_dense([m.out for m in solos], s, widths[-1])

    def call(self, state):  # [S, B, obs] -> [S, B, act]
        x = self.norm(state)
        for layer in self.hidden:
            x = layer(x)
        return self.out(x)


class StackedMountainCarCritic(keras.Model):
    """Post 001's critic for S seeds at learning phase 0: state -> BatchNormalization ->
    Dense selu -> concatenate with the action -> Dense selu -> Dense 1."""

    def __init__(self, solos: Sequence[keras.Model], obs_dim: int, action_dim: int):
        super().__init__()
        s = len(solos)
        self.norm = StackedBatchNorm(s, obs_dim, solos[0].norm.epsilon)
        self.norm.set_from([m.norm for m in solos])
        self.fc1 = _stacked_dense([m.fc1 for m in solos], s, obs_dim)
        self.fc2 = _stacked_dense([m.fc2 for m in solos], s, solos[0].fc1.units + action_dim)
        self.out = _stacked_dense([m.out for m in solos], s, solos[0].fc2.units)

    def call(self, state, action):  # -> [S, B, 1]
        x = self.fc1(self.norm(state))
        x = self.fc2(tf.concat([x, action], axis=-1))
        return self.out(x)


class StackedDDPGLearner(SliceState, DDPGLearner):
    """``DDPGLearner``'s own update (critic tape, actor tape, soft updates; every actor
    update: ``mean_q``, ``dpg_intended``, ``dpg_literal``) for S seeds in one call, through
    its hooks: ``[S, B, ...]`` batches, each seed's loss its own mean, the gradient taken of
    their sum, and Adam per seed (``SeedAdam``) with a mask: a seed that does not train on a
    call keeps its weights, moments and step count (post 001's bursts differ per seed)."""

    takes_masks = True
    """``train(rows, mask)``: the loop may train some seeds and not others on one call."""

    def __init__(self, networks, *, actor_lr: float, critic_lr: float, seeds: int, xla: bool = True, **kwargs):
        actor, critic = networks[0], networks[1]
        self.seeds = seeds
        self._mask = tf.Variable(tf.ones([seeds], tf.bool), trainable=False, name="mask")
        self._mask_now = np.ones(seeds, bool)
        self.solo_policies: list[tuple[keras.Model, keras.Model]] = []  # (actor, critic) per seed, for saving
        target_actor, target_critic = networks[2], networks[3]
        super().__init__(
            actor,
            critic,
            target_actor,
            target_critic,
            SeedAdam(actor.trainable_variables, seeds, actor_lr),
            SeedAdam(critic.trainable_variables, seeds, critic_lr),
            xla=xla,
            **kwargs,
        )

    # -- DDPGLearner's hooks -----------------------------------------------------------------
    def build_optimizers(self) -> None:
        pass  # SeedAdam makes its moments when it is made

    def input_specs(self) -> tuple[tf.TensorSpec, tf.TensorSpec]:
        return (
            tf.TensorSpec([self.seeds, None, self.layout.width], tf.float32),  # [S, B, width]
            tf.TensorSpec([self.seeds, self.layout.obs_dim], tf.float32),
        )  # [S, obs]

    def seed_mean(self, x: tf.Tensor) -> tf.Tensor:
        return tf.reduce_mean(x, axis=list(range(1, len(x.shape))))  # [S]: each seed's own loss

    def total(self, loss: tf.Tensor) -> tf.Tensor:
        return tf.reduce_sum(loss)  # each slice gets its solo gradient

    def apply_gradients(self, optimizer, grads, variables) -> None:
        optimizer.apply(grads, variables, self._mask)

    def seeds_that_train(self) -> tf.Tensor:
        return self._mask

    def _act_one(self, states):
        return self.actor(states[:, None, :])[:, 0]  # [S, act]

    def _stateful(self) -> list:
        return [
            *(v for name in NETWORKS for v in getattr(self, name).variables),
            *self.actor_optimizer.variables,
            *self.critic_optimizer.variables,
        ]

    # -- the stacked interface ---------------------------------------------------------------
    def train(self, rows: np.ndarray, mask: np.ndarray | None = None) -> dict[str, tf.Tensor]:
        """One update of the seeds where ``mask`` is True (all by default) on their own rows
        ``[S, B, width]``; losses ``[S]`` (a masked seed's are not its own: unread)."""
        self._set_mask(mask)
        self.compile()
        return self._train(tf.constant(rows))

    def _set_mask(self, mask: np.ndarray | None) -> None:
        mask = np.ones(self.seeds, bool) if mask is None else np.asarray(mask, bool)
        if not np.array_equal(mask, self._mask_now):
            self._mask.assign(mask)
            self._mask_now = mask

    def act(self, states: np.ndarray) -> np.ndarray:
        """Each seed's action for its state: ``[S, obs] -> [S, act]``."""
        self.compile()
        return self._act(tf.constant(states, tf.float32)).numpy()

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, separate: bool = False):
        """One update of every seed, then each seed's action for ``states``. ``separate``:
        two calls, as the solo run makes after an episode end (it trains, then acts on the
        new episode's first state) and where the post acts through its own predict (XLA
        may round a fused call differently)."""
        self._set_mask(None)
        if separate:
            return self.train(rows), self.act(states)
        self.compile()
        losses, actions = self._train_and_act(tf.constant(rows), tf.constant(states, tf.float32))
        return losses, actions.numpy()

    def step_without_batch(self, states: np.ndarray, episode_ended: bool = False) -> np.ndarray:
        """Before the warm-up ends DDPG only acts (``episode_ended`` changes nothing here)."""
        return self.act(states)

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        """Seed k's weights, as its solo model holds them (its ``variables``, in order)."""
        return {name: [v.numpy()[k] for v in getattr(self, name).variables] for name in NETWORKS}

    def save_slice(self, k: int, run_dir) -> None:
        """Seed k's actor and critic as a solo run saves them (``actor.weights.h5``, ``critic.weights.h5``)."""
        weights = self.slice_weights(k)
        actor, critic = self.solo_policies[k]
        for model, values in ((actor, weights["actor"]), (critic, weights["critic"])):
            for variable, value in zip(model_variables(model), values, strict=True):
                variable.assign(value)
        save_weights(actor, Path(run_dir) / "actor.weights.h5")
        save_weights(critic, Path(run_dir) / "critic.weights.h5")


class SoloAsStack:
    """Any solo learner (Keras or PyTorch) behind the stacked interface, for a seed axis of
    one: XLA rounds a one-row batched matmul differently from Dense's matmul (about 1e-7,
    measured), so S=1 through the stacked layers would not be bit-identical to the solo
    run; this is, call for call (``separate``: the update, then an act of its own, as the
    solo agent makes them after an episode end and where the post does not fuse them)."""

    takes_masks = False

    def __init__(self, learner):
        self.learner = learner
        self.loss_names = tuple(learner.loss_names)
        if not callable(getattr(type(learner), "compile", None)):
            raise TypeError(
                f"{type(learner).__name__} has no compile() (keras_rl/learners/protocol.Learner): a learner "
                "traces its compiled steps there, or defines it to do nothing"
            )

    def compile(self) -> None:
        self.learner.compile()

    @staticmethod
    def _one(losses) -> dict[str, np.ndarray]:
        return {k: np.asarray(v)[None] for k, v in losses.items()}

    def train(self, rows: np.ndarray, mask: np.ndarray | None = None) -> dict[str, np.ndarray]:
        if mask is not None:
            raise ValueError("a seed axis of one trains or does not: it takes no mask")
        return self._one(self.learner.train(rows[0]))

    def act(self, states: np.ndarray) -> np.ndarray:
        return np.asarray(self.learner.act(states[0]))[None]

    def train_and_act(self, rows: np.ndarray, states: np.ndarray, separate: bool = False):
        if separate:
            return self.train(rows), self.act(states)
        losses, action = self.learner.train_and_act(rows[0], states[0])
        return self._one(losses), np.asarray(action)[None]

    def step_without_batch(self, states: np.ndarray, episode_ended: bool = False) -> np.ndarray:
        """``episode_ended``: the episode ended on this step, so the solo run makes no act here
        (the learner may still do its every-step work), then acts on the next first state."""
        action = self.learner.step_without_batch(states[0], want_action=not episode_ended)
        return self.act(states) if episode_ended else np.asarray(action)[None]

    def slice_weights(self, k: int) -> dict[str, list[np.ndarray]]:
        return self.learner.weights()

    def save_slice(self, k: int, run_dir) -> None:
        self.learner.save(run_dir)

    def slice_state(self, k: int) -> dict:
        return self.learner.state_dict()

    def load_slice_state(self, k: int, state: dict) -> None:
        self.learner.load_state_dict(state)


def _per_seed(configs: Sequence, build) -> list:
    """``build(config)`` for each seed, Keras seeded first as that seed's solo run seeds it. The
    configs are equal but for the seed: ``train/loop.run_seeds`` checks it before it builds a seed
    axis, the only way to a stacked learner (``learners/table.STACKED``)."""
    built = []
    for config in configs:
        seed_everything(config.seed)
        built.append(build(config))
    return built


def _stack_ddpg(configs: Sequence, spec: EnvSpec, networks, stacked_actor, stacked_critic, xla: bool, **kwargs):
    """A DDPG post's learner for the seeds of ``configs`` (equal but for the seed): each
    slice starts from the weights its solo run draws (``seed_everything(seed)``, then the
    solo builder ``networks``)."""
    c = configs[0]
    solos = _per_seed(configs, lambda config: networks(config, spec))
    nets = [
        stacked_actor([s[i] for s in solos]) if i in (0, 2) else stacked_critic([s[i] for s in solos]) for i in range(4)
    ]
    learner = StackedDDPGLearner(
        nets,
        actor_lr=c.actor_lr,
        critic_lr=c.critic_lr,
        seeds=len(configs),
        xla=xla,
        gamma=c.gamma,
        tau=c.tau,
        layout=Layout(spec.obs_dim, spec.action_dim),
        **kwargs,
    )
    learner.solo_policies = [(s[0], s[1]) for s in solos]
    return learner


def stack_post001(configs: Sequence, spec: EnvSpec, xla: bool = True):
    """Post 001's learner for the seeds of ``configs``, every actor update (P001-ACTORGRAD,
    P001-DQDA) included; at learning phase 0 only (P001-PHASE on makes every seed NaN at
    its first update, and its noise layer draws from TensorFlow's one generator)."""
    c = configs[0]
    if len(configs) == 1:
        from keras_rl.learners.ddpg import post001_learner

        seed_everything(c.seed)
        return SoloAsStack(post001_learner(c, spec, xla=xla))
    if c.learning_phase_training:
        from keras_rl.errors import ConfigError

        raise ConfigError(
            f"{argument('seed_batch')} does not cover learning_phase_training=true (its noise layer draws from "
            "TensorFlow's one generator, so seeds could not keep their own draws); run it without"
        )
    obs, act = spec.obs_dim, spec.action_dim
    return _stack_ddpg(
        configs,
        spec,
        post001_networks,
        lambda m: StackedMountainCarActor(m, obs),
        lambda m: StackedMountainCarCritic(m, obs, act),
        xla,
        broadcast_target=False,
        actor_gradient=c.actor_gradient,
        dqda_at_buffer_actions=c.dqda_at_buffer_actions,
    )
