"""Typed configs: one dataclass per post, each field saying where in the post it comes from.

A config holds the post's hyperparameters *and* its quirk switches. The faithful
value of every switch is the field default; a post's ``fixed`` variant is a named
set of overrides (``VARIANTS``) that turns the quirks off. See
``reproductions/FIDELITY.md`` for what each switch does and what it costs.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping

from keras_rl.errors import ConfigError


@dataclass(frozen=True)
class ExperimentConfig:
    """Fields every experiment has, plus validation, overrides and (de)serialisation."""

    experiment: ClassVar[str] = ""
    """Registry name, e.g. ``pendulum``."""
    post: ClassVar[str] = ""
    """The seed post this config reproduces."""
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {"faithful": {}}
    """Named sets of overrides. ``faithful`` is always the empty set: the defaults."""
    FRAMEWORKS: ClassVar[tuple[str, ...]] = ("keras", "torch")
    """Frameworks this experiment is implemented in."""

    variant: str = "faithful"
    """Which named variant produced this config (for the record; set by ``for_variant``)."""
    seed: int = 0
    """Seeds Python, NumPy, TensorFlow (or PyTorch) and the env's first ``reset``."""
    framework: str = "keras"
    """``keras`` (ours) or, where the experiment has one, ``torch``."""
    matched_init: bool = False
    """``torch`` only (``--matched-init``): build the Keras networks with the same seed and
    copy their initial weights into the PyTorch ones, so that only the framework differs.
    False: each framework initialises its networks its own default way."""

    # -- construction -------------------------------------------------------------------
    @classmethod
    def for_variant(cls, variant: str, **overrides: Any) -> "ExperimentConfig":
        """The config of a named variant, with further field overrides on top."""
        if variant not in cls.VARIANTS:
            raise ConfigError(
                f"unknown variant {variant!r} for {cls.experiment}; "
                f"choose one of {', '.join(cls.VARIANTS)}"
            )
        values = {**cls.VARIANTS[variant], **overrides, "variant": variant}
        return cls.from_dict(values)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> "ExperimentConfig":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names - {"experiment", "post"})
        if unknown:
            raise ConfigError(f"unknown {cls.experiment} config field(s): {', '.join(unknown)}")
        kwargs = {k: v for k, v in values.items() if k in names}
        hints = typing.get_type_hints(cls)
        for name, value in kwargs.items():
            if typing.get_origin(hints[name]) is tuple and isinstance(value, list):
                kwargs[name] = tuple(value)
        config = cls(**kwargs)
        config.validate()
        return config

    def replace(self, **changes: Any) -> "ExperimentConfig":
        config = dataclasses.replace(self, **changes)
        config.validate()
        return config

    def with_text_overrides(self, assignments: list[str]) -> "ExperimentConfig":
        """Apply ``name=value`` strings from the command line, parsed by the field's type."""
        hints = typing.get_type_hints(type(self))
        changes: dict[str, Any] = {}
        for item in assignments:
            name, sep, text = item.partition("=")
            name = name.strip().replace("-", "_")
            if not sep:
                raise ConfigError(f"--set expects name=value, got {item!r}")
            if name not in hints or name in ("experiment", "post", "VARIANTS"):
                raise ConfigError(f"unknown {self.experiment} config field {name!r}")
            changes[name] = _parse_value(name, hints[name], text.strip())
        return self.replace(**changes)

    def to_dict(self) -> dict[str, Any]:
        return {"experiment": self.experiment, "post": self.post, **dataclasses.asdict(self)}

    # -- validation ---------------------------------------------------------------------
    def validate(self) -> None:
        """Raise ConfigError naming the first field that is out of range."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            kind = f.metadata.get("check")
            if kind is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f"{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ConfigError(f"{f.name} must be finite, got {value!r}")
            if kind == "positive" and not value > 0:
                raise ConfigError(f"{f.name} must be positive, got {value!r}")
            if kind == "non_negative" and not value >= 0:
                raise ConfigError(f"{f.name} must be zero or more, got {value!r}")
            if kind == "unit" and not 0 < value <= 1:
                raise ConfigError(f"{f.name} must be in (0, 1], got {value!r}")
            if kind == "fraction" and not 0 <= value < 1:
                raise ConfigError(f"{f.name} must be in [0, 1), got {value!r}")
        if self.seed < 0:
            raise ConfigError(f"seed must be zero or more, got {self.seed}")
        if self.framework not in self.FRAMEWORKS:
            raise ConfigError(f"{self.experiment} has no {self.framework!r} version; "
                              f"choose one of {', '.join(self.FRAMEWORKS)}")
        if self.matched_init and self.framework != "torch":
            raise ConfigError("matched_init copies Keras' initial weights into the PyTorch networks; "
                              f"it needs framework 'torch', not {self.framework!r}")


def positive(default: Any) -> Any:
    return field(default=default, metadata={"check": "positive"})


def non_negative(default: Any) -> Any:
    return field(default=default, metadata={"check": "non_negative"})


def unit(default: Any) -> Any:
    return field(default=default, metadata={"check": "unit"})


def fraction(default: Any) -> Any:
    return field(default=default, metadata={"check": "fraction"})


def _parse_value(name: str, hint: Any, text: str) -> Any:
    try:
        if hint is bool:
            lowered = text.lower()
            if lowered in ("1", "true", "yes", "on"):
                return True
            if lowered in ("0", "false", "no", "off"):
                return False
            raise ValueError(text)
        if hint is int:
            return int(text)
        if hint is float:
            return float(text)
        if typing.get_origin(hint) is tuple:
            return tuple(int(part) for part in text.split(",") if part.strip())
        return text
    except ValueError:
        raise ConfigError(f"{name} expects a {getattr(hint, '__name__', hint)}, got {text!r}") from None


@dataclass(frozen=True)
class PendulumDDPGConfig(ExperimentConfig):
    """Post 000: DDPG on Gymnasium ``Pendulum-v1`` (g=10), TF2 Keras, GradientTape updates.

    Section numbers refer to ``../shared/seeds/000_97338310014de2ac.txt``.
    """

    experiment: ClassVar[str] = "pendulum"
    post: ClassVar[str] = "000_97338310014de2ac"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "faithful": {},
        "fixed": {
            "noise_restarts_from_zero": False,
            "done_from_truncated": False,
            "broadcast_target": False,
            "target_copy_is_noop": False,
        },
    }

    # -- environment (§2.4 Main) --------------------------------------------------------
    env_id: str = "Pendulum-v1"
    """§2.4: ``gym.make('Pendulum-v1', g = 10)``."""
    gravity: float = positive(10.0)
    """§2.4: ``g = 10`` (Gymnasium's default is 10.0 too)."""

    # -- networks (§2.2) ----------------------------------------------------------------
    hidden_units: tuple[int, ...] = (64, 64)
    """§2.2: Actor and Critic both use ``Dense(64, relu)`` twice."""

    # -- hyperparameters (§2.3.1) -------------------------------------------------------
    actor_lr: float = positive(1e-3)
    """§2.3.1: ``self.actor_optimizer = Adam(learning_rate=0.001)``."""
    critic_lr: float = positive(1e-3)
    """§2.3.1: ``self.critic_optimizer = Adam(learning_rate=0.001)``."""
    gamma: float = unit(0.99)
    """§2.3.1: ``self.gamma = 0.99``."""
    tau: float = unit(0.001)
    """§2.3.1: ``self.tau = 0.001``; used by ``update_target_networks`` after every update."""
    buffer_size: int = positive(2000)
    """§2.3.1: ``self.memory = deque(maxlen=2000)``: FIFO eviction at capacity."""
    batch_size: int = positive(64)
    """§2.3.1: ``self.batch_size = 64``; ``random.sample`` draws without replacement (§2.3.3)."""
    train_start: int = positive(1000)
    """§2.3.1/§2.4: train when ``len(agent.memory) >= agent.train_start`` (1000)."""
    train_every: int = positive(1)
    """§2.4: ``train_model()`` runs once per env step once the buffer holds train_start."""

    # -- exploration (§2.3.2) -----------------------------------------------------------
    noise_theta: float = non_negative(0.15)
    """§2.3.2: ``ou_noise(..., rho=0.15, ...)``: mean reversion rate."""
    noise_mu: float = 0.0
    """§2.3.2: ``mu=0``."""
    noise_dt: float = positive(0.1)
    """§2.3.2: ``dt=1e-1``."""
    noise_sigma: float = non_negative(0.2)
    """§2.3.2: ``sigma=0.2``; each step adds ``sigma*sqrt(dt)*N(0,1)``."""
    action_clip: float = positive(2.0)
    """§2.4: ``np.clip(action + noise, -2, 2)``; the stored action is this clipped one."""

    # -- run protocol (§2.4) ------------------------------------------------------------
    episodes: int = positive(1000)
    """§2.4: ``num_episode = 1000``: the post's own budget."""
    threshold: float = -300.0
    """§2.4: ``if score_avg > -300``: success is the EMA strictly above -300."""
    ema_decay: float = fraction(0.9)
    """§2.4: ``score_avg = 0.9 * score_avg + 0.1 * score if score_avg != 0 else score``."""
    stop_at_threshold: bool = True
    """§2.4: the run saves the actor and ``sys.exit()``s at the first EMA above -300."""

    # -- quirk switches: faithful defaults; see reproductions/FIDELITY.md ----------------
    noise_restarts_from_zero: bool = True
    """P000-NOISE. §2.4: ``pre_noise = np.zeros(...)`` at every episode start and never
    updated inside the episode, so each step's noise starts from zero: i.i.d. Gaussian
    with sigma ``0.2*sqrt(0.1)``. False: a real OU process carried across steps."""
    done_from_truncated: bool = True
    """P000-DONE. §2.4: ``next_state, reward, _, done, _ = env.step(...)`` keeps
    ``truncated`` and drops ``terminated``: the time-limit step is stored as terminal.
    False: only ``terminated`` is terminal, so truncation bootstraps."""
    broadcast_target: bool = True
    """P000-BROADCAST. §2.3.3: rewards (B,1) + gamma * Q' (B,1) * (1 - dones) (B,) gives
    a (B,B) target and the critic loss averages over that matrix. False: (B,1) targets."""
    target_copy_is_noop: bool = True
    """P000-TARGETINIT. §2.4: ``agent.update_target_networks(1.0)`` runs before any model
    is built; ``get_weights()`` of an unbuilt subclassed model is ``[]``, so the copy does
    nothing and the targets start from their own random init. False: a real hard copy."""


@dataclass(frozen=True)
class CartPoleDQNConfig(ExperimentConfig):
    """Post 003: the PyTorch DQN tutorial on ``CartPole-v1``.

    ``In [N]`` refers to the notebook cells of ``../shared/seeds/003_57d1feb4b7fdd940.txt``;
    the training loop after ``optimize_model`` is not in the post's text and follows the
    tutorial as issue #3 gives it.
    """

    experiment: ClassVar[str] = "cartpole"
    post: ClassVar[str] = "003_57d1feb4b7fdd940"

    env_id: str = "CartPole-v1"
    """In [27]: ``env = gym.make("CartPole-v1")``."""
    hidden_units: tuple[int, ...] = (128, 128)
    """In [16]: ``nn.Linear(n_observations, 128)``, ``nn.Linear(128, 128)``, ``nn.Linear(128, n_actions)``."""
    init: str = "torch"
    """``torch``: ``nn.Linear``'s U(-1/sqrt(fan_in), 1/sqrt(fan_in)) for weights and biases,
    as the tutorial's network gets. ``keras``: Keras' Glorot-uniform kernels, zero biases."""
    batch_size: int = positive(128)
    """In [23]: ``BATCH_SIZE = 128``; also the warm-up: ``if len(memory) < BATCH_SIZE: return``."""
    gamma: float = unit(0.99)
    """In [23]: ``GAMMA = 0.99``."""
    eps_start: float = unit(0.9)
    """In [23]: ``EPS_START = 0.9``."""
    eps_end: float = fraction(0.05)
    """In [23]: ``EPS_END = 0.05``."""
    eps_decay: float = positive(1000.0)
    """In [23]: ``EPS_DECAY = 1000``, in env steps: ``exp(-1. * steps_done / EPS_DECAY)`` (In [31])."""
    tau: float = unit(0.005)
    """In [23]: ``TAU = 0.005``; the target is soft-updated after every env step."""
    lr: float = positive(1e-4)
    """In [23]: ``LR = 1e-4``; In [28]: ``optim.AdamW(policy_net.parameters(), lr=LR, amsgrad=True)``."""
    weight_decay: float = non_negative(0.01)
    """torch AdamW's default ``weight_decay=0.01``: the tutorial never sets it, so it gets it."""
    adam_eps: float = positive(1e-8)
    """torch AdamW's default ``eps=1e-8`` (added after the bias-corrected sqrt)."""
    amsgrad: bool = True
    """In [28]: ``amsgrad=True``."""
    grad_clip_value: float = positive(100.0)
    """``torch.nn.utils.clip_grad_value_(policy_net.parameters(), 100)`` before ``optimizer.step()``."""
    buffer_size: int = positive(10000)
    """In [28]: ``memory = ReplayMemory(10000)``: a deque, sampled with ``random.sample``."""
    episodes: int = positive(600)
    """``num_episodes = 600`` when a GPU is available (50 otherwise); we use 600."""
    threshold: float = 475.0
    """CartPole-v1's reward threshold: success is the 100-episode mean duration >= 475."""
    mean_window: int = positive(100)
    """``plot_durations``: ``durations_t.unfold(0, 100, 1).mean(1)``, zeros before 100 episodes."""
    stop_at_threshold: bool = False
    """The tutorial trains all ``num_episodes``; it never stops early."""

    def validate(self) -> None:
        super().validate()
        if self.init not in ("keras", "torch"):
            raise ConfigError(f"init must be 'keras' or 'torch', got {self.init!r}")


@dataclass(frozen=True)
class MountainCarDDPGConfig(ExperimentConfig):
    """Post 001: DDPG on ``MountainCarContinuous-v0``, written in Keras 2 / TF1 graph style.

    Quotes are from ``../shared/seeds/001_98f9c3d244106c52.txt``.
    """

    experiment: ClassVar[str] = "mountaincar"
    post: ClassVar[str] = "001_98f9c3d244106c52"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "faithful": {},
        "faithful-intended": {"actor_gradient": "dpg_intended"},
        "fixed": {
            "actor_gradient": "dpg_intended",
            "dqda_at_buffer_actions": False,
            "store_raw_next_state": False,
            "episode_returns_as_rewards": False,
            "done_includes_truncation": False,
            "popping_buffer": False,
            "exploration": "ou",
            "criterion": "goal",
            "threshold": 0.5,
        },
    }

    env_id: str = "MountainCarContinuous-v0"
    """``env = gym.make("MountainCarContinuous-v0")``: 999-step time limit."""
    critic_hidden: int = positive(32)
    """Critic: BatchNormalization, ``Dense(32, selu)``, concat action, ``Dense(32, selu)``, ``Dense(1)``."""
    actor_hidden: tuple[int, ...] = (32, 32, 32)
    """Actor: ``GaussianNoise(1.0)``, BatchNormalization, 3 x ``Dense(32, selu)``, ``Dense(1, tanh)``."""
    actor_input_noise: float = non_negative(1.0)
    """``layers.GaussianNoise(1.0)`` on the actor's input (inactive at learning phase 0)."""
    critic_lr: float = positive(5e-4)
    """``optimizers.Adam(lr = 0.0005)`` in ``Critic.__build_loss_function``."""
    actor_lr: float = positive(5e-5)
    """``optimizers.Adam(lr=0.00005)`` in ``Actor.__make_loss_function``."""
    tau: float = unit(0.001)
    """``Agent(..., tau = 0.001, ...)``."""
    gamma: float = unit(0.999)
    """``Agent(..., gamma =0.999)``: the bootstrap discount."""
    return_discount: float = unit(0.999)
    """``_compute_discounted_R(R, discount_rate=.999)``: the per-episode returns."""
    batch_size: int = positive(32)
    """``ReplayBuffer(maxlen=20000, batch_size=32)``."""
    train_above: int = positive(1000)
    """``if len(agent.memory)> 1000: agent.train()``, checked every env step."""
    train_down_to: int = non_negative(100)
    """``while (len(self.memory)) > 100:`` pop and train batch after batch."""
    buffer_size: int = positive(100_000)
    """Only for ``popping_buffer=False`` (the fixed variant's ring buffer)."""
    train_start: int = positive(1000)
    """Only for ``popping_buffer=False``: update every step from this many transitions."""
    episodes: int = positive(100)
    """``for iterate in range(100):``."""
    criterion: str = "converged"
    """``converged`` (faithful): the post claims only that it "roughly converged within 100
    trials", so success is the returns of the last ``converge_window`` episodes lying within
    ``threshold`` of each other after all episodes (derived in FIDELITY.md from 10+ seeds).
    ``goal`` (fixed): the share of the last ``goal_window`` episodes that reached the goal
    is at least ``threshold``."""
    converge_window: int = positive(10)
    """``criterion="converged"``: how many final episodes must agree."""
    goal_window: int = positive(50)
    """``criterion="goal"``: the window whose goal share is judged."""
    threshold: float = 2.0
    """``converged``: the largest allowed return spread; ``goal``: the least goal share."""
    stop_at_threshold: bool = False
    """The post runs all 100 iterations."""
    ou_sigma: float = non_negative(0.5)
    """``exploration="ou"`` only: rl-zoo3's OU noise sigma for DDPG on this task."""
    ou_theta: float = non_negative(0.15)
    ou_dt: float = positive(1e-2)

    # -- quirk switches; see reproductions/FIDELITY.md ---------------------------------
    learning_phase_training: bool = False
    """P001-PHASE: Keras 2's learning phase is never fed, so it stays 0: GaussianNoise off,
    BatchNormalization on its never-updated moving statistics (an affine layer with
    trainable gamma and beta). True would call every network in training mode."""
    actor_gradient: str = "dpg_literal"
    """P001-ACTORGRAD: ``dpg_literal`` (what ``get_updates(loss=tf.gradients(...))`` computes:
    the gradient of the sum of the first-order gradients) or ``dpg_intended``."""
    dqda_at_buffer_actions: bool = True
    """P001-DQDA: ``get_gradient(states, actions)`` evaluates dQ/da at the *stored* actions,
    after the critic's update. False: at mu(s)."""
    store_raw_next_state: bool = True
    """P001-NEXTSTATE: the state is normalised to [0,1] but ``next_frame`` is stored raw."""
    episode_returns_as_rewards: bool = True
    """P001-RETURNS: transitions enter the buffer at episode end with their rewards replaced
    by the episode's standardised discounted returns. False: raw rewards, stored each step."""
    done_includes_truncation: bool = True
    """P001-DONE: the old 4-tuple ``done`` is true at the 999-step limit too."""
    popping_buffer: bool = True
    """P001-POP: shuffle-and-pop sampling that consumes the buffer, trained in bursts
    (P001-TRIGGER). False: a ring buffer and one update per env step."""
    exploration: str = "none"
    """P001-NOEXPLORE: the actor acts with no added noise (``none``); ``ou`` adds OU noise."""

    def validate(self) -> None:
        super().validate()
        if self.actor_gradient not in ("dpg_literal", "dpg_intended"):
            raise ConfigError(f"actor_gradient must be dpg_literal or dpg_intended, got {self.actor_gradient!r}")
        if self.criterion not in ("converged", "goal"):
            raise ConfigError(f"criterion must be converged or goal, got {self.criterion!r}")
        if self.exploration not in ("none", "ou"):
            raise ConfigError(f"exploration must be none or ou, got {self.exploration!r}")
        if self.train_down_to >= self.train_above:
            raise ConfigError("train_down_to must be below train_above")


CONFIGS: dict[str, type[ExperimentConfig]] = {
    c.experiment: c for c in (PendulumDDPGConfig, CartPoleDQNConfig, MountainCarDDPGConfig)}
