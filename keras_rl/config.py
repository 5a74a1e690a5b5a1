"""The base of every post's typed config: validation, variants, overrides and renamed fields.

A post's config (``keras_rl/posts/``) holds its hyperparameters *and* its quirk switches,
each field citing the post. The faithful value of every switch is the field default; a
post's ``fixed`` variant is a named set of overrides (``VARIANTS``). One concept has one
name in every post:

- ``actor_hidden_units``/``critic_hidden_units``/``q_hidden_units``: layer widths, as tuples;
- ``actor_lr``/``critic_lr``/``q_lr``: each network's learning rate;
- ``train_start``: the warm-up, how many stored transitions training waits for;
- ``noise_theta``/``noise_mu``/``noise_dt``/``noise_sigma``: the OU exploration noise.

``config.json`` files written before these names were unified still load: ``RENAMED``
maps each old field to the new ones.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np

from keras_rl.errors import ConfigError
from keras_rl.learners.table import frameworks

_C = typing.TypeVar("_C", bound=type)


def named_fields(cls: _C) -> _C:
    """A post's config class (a ``dataclass(frozen=True, kw_only=True)``) whose fields are given by
    name only (``PendulumDDPGConfig(0.1)`` set ``variant`` before) and whose unknown field is a
    ConfigError naming it, not a TypeError; its ``__post_init__`` types and checks every field."""
    made = cls.__init__  # type: ignore[misc]

    @functools.wraps(made)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        if args:
            raise ConfigError(
                f"{cls.__name__} takes its fields by name ({cls.__name__}(tau=0.005)), got {len(args)} positional "
                f"value(s): {', '.join(map(repr, args[:3]))}"
            )
        type(self).typed(kwargs)  # an unknown field, named as a ConfigError
        made(self, **kwargs)

    cls.__init__ = __init__  # type: ignore[misc]
    return cls


@named_fields
@dataclass(frozen=True, kw_only=True)
class ExperimentConfig:
    """Fields every experiment has, plus validation, overrides and (de)serialisation."""

    experiment: ClassVar[str] = ""
    """Registry name, e.g. ``pendulum``."""
    post: ClassVar[str] = ""
    """The seed post this config reproduces."""
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {"faithful": {}}
    """Named sets of overrides. ``faithful`` is always the empty set: the defaults."""
    RENAMED: ClassVar[dict[str, Callable[[Any], dict[str, Any]]]] = {}
    """Old field name -> the new fields its value becomes (for ``config.json`` of older runs)."""
    QUIRKS: ClassVar[dict[str, tuple[str, Any]]] = {}
    """Quirk switch -> (ledger ID, the value that turns it off): what ``sweep --ablate`` flips."""
    RUN_FIELDS: ClassVar[dict[str, str]] = {
        "variant": "--variant",
        "seed": "--seeds",
        "framework": "--framework",
        "matched_init": "--matched-init",
    }
    """Fields that have their own command-line flag; ``--set`` refuses them."""

    if TYPE_CHECKING:  # every post's config declares these, with the post's values
        episodes: int
        threshold: float
        stop_at_threshold: bool

    variant: str = "faithful"
    """Which named variant produced this config (for the record; set by ``for_variant``)."""
    seed: int = 0
    """Seeds Python, NumPy, TensorFlow (or PyTorch) and the env's first ``reset``."""
    framework: str = "keras"
    """``keras`` (ours) or, where the experiment has one, ``torch``: the frameworks are the
    ones ``learners/table.py`` lists for the experiment (so not a fixed Literal)."""
    matched_init: bool = False
    """``torch`` only (``--matched-init``): build the Keras networks with the same seed and
    copy their initial weights into the PyTorch ones, so that only the framework differs.
    False: each framework initialises its networks its own default way."""

    # -- construction -------------------------------------------------------------------
    def __post_init__(self) -> None:
        """Every field as its type holds it (``typed``: a list of widths as a tuple, NumPy's numbers
        as Python's), then checked (``validate``): a config built directly is as checked as one
        read back or overridden (issue 72 item 8)."""
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            converted = _as_field_type(f.name, hints[f.name], value)
            if converted is not value:
                object.__setattr__(self, f.name, converted)
        self.validate()

    @classmethod
    def for_variant(cls, variant: str, **overrides: Any) -> ExperimentConfig:
        """The config of a named variant, with further field overrides on top."""
        if variant not in cls.VARIANTS:
            raise ConfigError(
                f"unknown variant {variant!r} for {cls.experiment}; choose one of {', '.join(cls.VARIANTS)}"
            )
        values = {**cls.VARIANTS[variant], **overrides, "variant": variant}
        return cls.from_dict(values)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> ExperimentConfig:
        """A config from ``to_dict``'s output, including ``config.json`` of older runs."""
        values = cls.upgrade(values)
        config = cls(**cls.typed({k: v for k, v in values.items() if k not in ("experiment", "post")}))
        config.validate()
        return config

    @classmethod
    def typed(cls, values: Mapping[str, Any]) -> dict[str, Any]:
        """Field values as their fields' own types, whether read from JSON or passed from Python:
        a list (or NumPy array) of widths as a tuple, NumPy's numbers and booleans as Python's,
        a whole number in a float field as a float. A value of another kind is left as it is,
        for ``validate`` to refuse by name; a name that is not a field is a ConfigError."""
        hints = _hints(cls)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ConfigError(f"unknown {cls.experiment} config field(s): {', '.join(unknown)}")
        return {name: _as_field_type(name, hints[name], value) for name, value in values.items()}

    @classmethod
    def upgrade(cls, values: Mapping[str, Any]) -> dict[str, Any]:
        """Map renamed fields of an older ``config.json`` onto today's names.

        An old field that maps onto a field also given must agree with it, or the file is
        ambiguous and refused."""
        values = dict(values)
        for old, convert in cls.RENAMED.items():
            if old not in values:
                continue
            for new, value in convert(values.pop(old)).items():
                value = tuple(value) if isinstance(value, list) else value
                if new in values and (tuple(values[new]) if isinstance(values[new], list) else values[new]) != value:
                    raise ConfigError(
                        f"old field {old!r} maps to {new}={value!r}, which contradicts "
                        f"{new}={values[new]!r} given beside it"
                    )
                values[new] = value
        return values

    def differs_from(self, other: ExperimentConfig) -> list[str]:
        """The fields, but the seed, where ``other`` differs: the one test of "the same config
        but for the seed" (seeds that share a batch, runs that can be reused or aggregated)."""
        mine, theirs = self.to_dict(), other.to_dict()
        return sorted(k for k in mine.keys() | theirs.keys() if k != "seed" and mine.get(k) != theirs.get(k))

    def replace(self, **changes: Any) -> ExperimentConfig:
        """This config with ``changes``, every field typed (``typed``) and checked (``validate``):
        ``replace()`` with no changes checks a config built directly."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}
        config = dataclasses.replace(self, **self.typed({**fields, **changes}))
        config.validate()
        return config

    def with_text_overrides(self, assignments: list[str] | tuple[str, ...]) -> ExperimentConfig:
        """Apply ``--set FIELD=VALUE`` texts, each parsed by its field's type."""
        return self.replace(**self.parse_assignments(assignments))

    NOT_FIELDS: ClassVar[tuple[str, ...]] = (
        "experiment",
        "post",
        "VARIANTS",
        "RENAMED",
        "RUN_FIELDS",
        "QUIRKS",
        "NOT_FIELDS",
    )

    @classmethod
    def parse_assignments(
        cls, items: list[str] | tuple[str, ...], flag: str = "--set", many: bool = False
    ) -> dict[str, Any]:
        """The one parser of ``FIELD=VALUE`` texts (``--set``; ``--grid`` with ``many``, whose
        values are comma lists, ``;`` between layer widths). Each value is parsed by its
        field's type, so ``tau=5e-3`` and ``tau=0.005`` are the same assignment. A
        ConfigError names a malformed item, a run option, a renamed or unknown field, an
        empty or unparsable value, and a field given twice."""
        parsed: dict[str, Any] = {}
        hints = _hints(cls)
        for item in items:
            name, sep, text = item.partition("=")
            name = name.strip().replace("-", "_")
            if not sep or not name:
                raise ConfigError(f"{flag} expects {'FIELD=V1,V2,...' if many else 'FIELD=VALUE'}, got {item!r}")
            if name in cls.RUN_FIELDS:
                raise ConfigError(f"{flag} {name}=... is not a config field; use {cls.RUN_FIELDS[name]}")
            if name in cls.RENAMED:
                raise ConfigError(
                    f"{cls.experiment} config field {name!r} was renamed; use {', '.join(cls.RENAMED[name](0))}"
                )
            if name not in hints or name in cls.NOT_FIELDS:
                raise ConfigError(f"unknown {cls.experiment} config field {name!r}")
            if name in parsed:
                raise ConfigError(f"{flag} names {name} twice")
            texts = (text.split(";") if "hidden_units" in name else text.split(",")) if many else [text]
            if any(not t.strip() for t in texts):
                raise ConfigError(f"{flag} {item!r} has an empty value")
            values = [_parse_value(name, hints[name], t.strip()) for t in texts]
            parsed[name] = values if many else values[0]
        return parsed

    @classmethod
    def parse_field(cls, name: str, text: str) -> Any:
        """One command-line value for field ``name``, parsed by the field's type."""
        return cls.parse_assignments([f"{name}={text}"])[name.strip().replace("-", "_")]

    def to_dict(self) -> dict[str, Any]:
        return {"experiment": self.experiment, "post": self.post, **dataclasses.asdict(self)}

    # -- validation ---------------------------------------------------------------------
    def validate(self) -> None:
        """Raise ConfigError naming the first field that is out of range or not a choice."""
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if typing.get_origin(hints[f.name]) is Literal and value not in typing.get_args(hints[f.name]):
                raise ConfigError(f"{f.name} must be one of {', '.join(typing.get_args(hints[f.name]))}, got {value!r}")
            if hints[f.name] in (int, float):  # every number, checked or not, is a finite number
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ConfigError(f"{f.name} must be a number, got {value!r}")
                if hints[f.name] is int and not isinstance(value, int):
                    raise ConfigError(f"{f.name} must be a whole number, got {value!r}")
                if hints[f.name] is int and f.name != "seed" and abs(value) > MAX_INT:  # the seed's own range is below
                    raise ConfigError(f"{f.name} must be at most {MAX_INT:,} (a 32-bit count), got {value!r}")
                if not math.isfinite(value):
                    raise ConfigError(f"{f.name} must be finite, got {value!r}")
            if hints[f.name] is bool and not isinstance(value, bool):
                raise ConfigError(f"{f.name} must be true or false, got {value!r}")
            if hints[f.name] is str and not isinstance(value, str):
                raise ConfigError(f"{f.name} must be a string, got {value!r}")
            kind = f.metadata.get("check")
            if kind is None:
                continue
            if kind == "widths":
                if not value or any(isinstance(w, bool) or not isinstance(w, int) or w < 1 for w in value):
                    raise ConfigError(f"{f.name} must be one or more positive layer widths, got {value!r}")
                if max(value) > MAX_INT:
                    raise ConfigError(f"{f.name} must be at most {MAX_INT:,} wide (a 32-bit count), got {value!r}")
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
        if self.variant not in self.VARIANTS:
            raise ConfigError(
                f"unknown variant {self.variant!r} for {self.experiment}; choose one of {', '.join(self.VARIANTS)}"
            )
        if not 0 <= self.seed < 2**32:
            raise ConfigError(f"seed must be in [0, 2**32), got {self.seed}")
        if self.framework not in frameworks(self.experiment):
            raise ConfigError(
                f"{self.experiment} has no {self.framework!r} version; "
                f"choose one of {', '.join(frameworks(self.experiment))}"
            )
        if self.uses_ring_buffer():
            self._check_warmup()
        if self.matched_init and self.framework != "torch":
            raise ConfigError(
                "matched_init copies Keras' initial weights into the PyTorch networks; "
                f"it needs framework 'torch', not {self.framework!r}"
            )

    def uses_ring_buffer(self) -> bool:
        """Whether training samples a ring buffer of ``buffer_size`` from ``train_start`` on."""
        return all(hasattr(self, f) for f in ("buffer_size", "train_start", "batch_size"))

    def _check_warmup(self) -> None:
        """Catch a run that would never train, or fail at its first update, before it starts."""
        buffer_size, train_start, batch_size = (getattr(self, f) for f in ("buffer_size", "train_start", "batch_size"))
        if buffer_size < train_start:
            raise ConfigError(
                f"buffer_size {buffer_size} is below train_start {train_start}: the buffer "
                "never holds enough transitions, so the run would never train"
            )
        if batch_size > train_start:
            raise ConfigError(
                f"batch_size {batch_size} is larger than train_start {train_start}: the "
                "first update samples without replacement from train_start transitions"
            )


MAX_INT = 2**31 - 1
"""The largest whole number a field takes: counts and sizes index 32-bit arrays and tensors."""

RANGES = {"positive": "> 0", "non_negative": ">= 0", "unit": "(0, 1]", "fraction": "[0, 1)", "widths": "widths >= 1"}
"""Each range check in words, as ``ExperimentConfig.validate`` applies it."""


def describe_fields(cls) -> list[dict[str, str]]:
    """Every field of a config class, in order: its name, type, default, range (or choices) and
    its docstring, which cites the post's line (read from the class's source)."""
    import ast
    import inspect
    import textwrap

    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not (isinstance(klass, type) and issubclass(klass, ExperimentConfig)):
            continue
        body = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0].body  # type: ignore[attr-defined]
        for node, after in zip(body, body[1:]):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)
                and isinstance(after.value.value, str)
            ):
                docs[node.target.id] = " ".join(after.value.value.split())
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        kind = f.metadata.get("check")
        if typing.get_origin(hint) is Literal:
            allowed = "one of " + ", ".join(map(str, typing.get_args(hint)))
        else:
            allowed = RANGES.get(str(kind), "")
        name = hint.__name__ if isinstance(hint, type) else str(hint).replace("typing.", "")
        default = getattr(cls(), f.name)
        out.append(
            {
                "field": f.name,
                "type": name,
                "default": value_text(default),
                "range": allowed,
                "post": docs.get(f.name, ""),
            }
        )
    return out


def positive(default: Any) -> Any:
    return field(default=default, metadata={"check": "positive"})


def non_negative(default: Any) -> Any:
    return field(default=default, metadata={"check": "non_negative"})


def unit(default: Any) -> Any:
    return field(default=default, metadata={"check": "unit"})


def fraction(default: Any) -> Any:
    return field(default=default, metadata={"check": "fraction"})


def widths(default: tuple[int, ...]) -> Any:
    return field(default=default, metadata={"check": "widths"})


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints`` of a config class, read once per class."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _as_field_type(name: str, hint: Any, value: Any) -> Any:
    """``value`` as a field of type ``hint`` holds it, where it is of the right kind (see ``typed``)."""
    if isinstance(value, np.bool_):
        return bool(value) if hint is bool else value
    if isinstance(value, bool):
        return value
    if hint is int and isinstance(value, numbers.Integral):
        return int(value)
    if hint is float and isinstance(value, numbers.Real):
        try:
            return float(value)
        except OverflowError:
            raise ConfigError(f"{name} must be finite, got a whole number too large for a float") from None
    if typing.get_origin(hint) is tuple and isinstance(value, (list, tuple, np.ndarray)):
        return tuple(
            int(v) if isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_)) else v
            for v in (value.tolist() if isinstance(value, np.ndarray) else value)
        )
    return value


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
            number = float(text)
            if not math.isfinite(number):
                raise ConfigError(f"{name} must be finite, got {text!r}")
            return number
        if typing.get_origin(hint) is tuple:
            return tuple(int(part) for part in text.split(",") if part.strip())
        if typing.get_origin(hint) is Literal and text not in typing.get_args(hint):
            raise ConfigError(f"{name} must be one of {', '.join(typing.get_args(hint))}, got {text!r}")
        return text
    except ConfigError:
        raise
    except ValueError:
        kind = getattr(hint, "__name__", None) or (
            "comma-separated list of ints" if typing.get_origin(hint) is tuple else str(hint)
        )
        article = "an" if kind[0] in "aeiou" else "a"
        raise ConfigError(f"{name} expects {article} {kind}, got {text!r}") from None


def check_same_but_seed(configs) -> None:
    """Seeds share a batch only when their configs are equal but for the seed."""
    differing = sorted({k for c in configs[1:] for k in configs[0].differs_from(c)})
    if differing:
        raise ConfigError(f"seed-batched configs must be equal but for the seed; these differ: {', '.join(differing)}")


def value_text(value: Any) -> str:
    """A parsed config value as folder names write it: ``0.005``, ``false``, ``400,300``."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return ",".join(str(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


BASE = "base"
"""The name of a sweep's point without overrides."""


def point_name(overrides: Mapping[str, Any]) -> str:
    """A sweep point's folder name: ``overrides_name``, or ``base`` for none."""
    return overrides_name(overrides) or BASE


def overrides_name(overrides: Mapping[str, Any]) -> str:
    """The one name of a set of parsed overrides, sorted by field: ``broadcast_target=false,tau=0.005``
    (empty for none). Sweep points and ``--set`` folders are named by it, so equal values
    written differently name the same folder."""
    return ",".join(f"{k}={value_text(v)}" for k, v in sorted(overrides.items()))
