"""Typed configs: one dataclass per post, each field saying where in the post it comes from.

A config holds the post's hyperparameters *and* its quirk switches. The faithful
value of every switch is the field default; a post's ``fixed`` variant is a named
set of overrides (``VARIANTS``) that turns the quirks off. See
``reproductions/FIDELITY.md`` for what each switch does and what it costs.
"""

from __future__ import annotations

import dataclasses
import json
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

    variant: str = "faithful"
    """Which named variant produced this config (for the record; set by ``for_variant``)."""
    seed: int = 0
    """Seeds Python, NumPy, TensorFlow and the env's first ``reset``."""

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

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=False)

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


CONFIGS: dict[str, type[ExperimentConfig]] = {PendulumDDPGConfig.experiment: PendulumDDPGConfig}
