"""Where a learner is chosen: one table, (experiment, framework) -> factory.

Entries are import paths, so reading the table imports neither TensorFlow nor torch; the
factory's module is imported only when a run asks for it. A learner factory is called as
``factory(config, spec)`` and returns a ``Learner`` (``protocol.py``), which the post's
agent skeleton drives. The one ``whole_agent`` entry is post 003's PyTorch tutorial, whose
verbatim code *is* the original and so brings its own agent behind the same verbs; it is
called as ``factory(config, spec, action_space)``.

Adding a framework, or a seed-batched learner, is one module plus one line here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from keras_rl.errors import argument


@dataclass(frozen=True)
class Implementation:
    path: str
    """``module:callable``."""
    whole_agent: bool = False
    """True: the factory builds the whole agent (its own buffer and exploration), not a learner."""

    def load(self) -> Callable[..., Any]:
        module, _, name = self.path.partition(":")
        return getattr(importlib.import_module(module), name)


IMPLEMENTATIONS: dict[tuple[str, str], Implementation] = {
    ("pendulum", "keras"): Implementation("keras_rl.learners.ddpg:post000_learner"),
    ("pendulum", "torch"): Implementation("keras_rl.torch.ddpg:post000_learner"),
    ("mountaincar", "keras"): Implementation("keras_rl.learners.ddpg:post001_learner"),
    ("mountaincar", "torch"): Implementation("keras_rl.torch.ddpg:post001_learner"),
    ("cartpole", "keras"): Implementation("keras_rl.learners.dqn:post003_learner"),
    ("cartpole", "torch"): Implementation("keras_rl.torch.dqn_tutorial:TutorialDQNAgent", whole_agent=True),
}


STACKED: dict[tuple[str, str], Implementation] = {
    ("mountaincar", "keras"): Implementation("keras_rl.learners.stacked:stack_post001"),
    ("pendulum", "torch"): Implementation("keras_rl.torch.stacked:stack_post000"),
    ("mountaincar", "torch"): Implementation("keras_rl.torch.stacked:stack_post001"),
}
"""Seed-batched learners (``--seed-batch``): ``factory(configs, spec)`` for S seeds at once."""

RETIRED: dict[tuple[str, str], str] = {
    ("pendulum", "keras"): (
        "a compiled solo run costs 0.69x a seed of the Gymnasium loop's batch of 10 (docs/performance.md), "
        "so issue 34 retired post 000's stacked Keras learner"
    ),
    ("cartpole", "keras"): (
        "a compiled solo run costs 0.57x a seed of the Gymnasium loop's batch of 10 (docs/performance.md), "
        "so issue 34 retired post 003's stacked Keras learner"
    ),
}
"""Seed-batched learners retired because the compiled engine (``train/compiled.py``) runs a
seed for less than a batch did (issue 34, item 5): why, in the words ``--seed-batch`` refuses
with. Their committed sets were regenerated on the compiled engine (``results/MANIFEST.md``)."""

NOT_STACKED: dict[str, tuple[str, object, str]] = {
    "mountaincar": (
        "learning_phase_training",
        True,
        "its noise layer draws from one generator, so batched seeds could not keep their own draws",
    ),
}
"""Configs whose seeds cannot share a stacked learner: (field, value, why), per experiment.
``--seed-batch auto`` runs their seeds alone; a fixed ``--seed-batch N`` refuses them before
anything runs (``dispatch.jobs.batched``)."""


def batch_refusal(experiment: str, config) -> str | None:
    """Why a job of this config cannot join a seed batch, or None."""
    if experiment not in NOT_STACKED:
        return None
    field, value, why = NOT_STACKED[experiment]
    return f"{field}={str(value).lower()} ({why})" if getattr(config, field) == value else None


SEED_BATCH_CAP: dict[tuple[str, str], int] = {
    ("mountaincar", "keras"): 16,
    ("pendulum", "torch"): 16,
    ("mountaincar", "torch"): 16,
}
"""The most seeds ``--seed-batch auto`` puts in one batch. Each post's cost per seed still
falls at 16, the largest size measured (2026-11-23, whole batches against one solo seed
over as many steps: post 001 2.38x at 10 seeds, 3.37x at 16; post 000's PyTorch port 4.88x
and 6.31x). Measured with ``benchmarks/seed_batch.py --experiment NAME [--framework torch]
--skip-study`` (docs/performance.md)."""


def seed_batch_cap(experiment: str, framework: str) -> int:
    """``SEED_BATCH_CAP``'s entry; 1 where the post has no seed-batched learner."""
    return SEED_BATCH_CAP.get((experiment, framework), 1) if (experiment, framework) in STACKED else 1


def no_stacked_learner(experiment: str, framework: str) -> str | None:
    """Why ``--seed-batch`` cannot batch this post in this framework (retired, or never built),
    or None where it can: the one wording the CLI and the benchmarks refuse or warn with."""
    if (experiment, framework) in RETIRED:
        instead = argument("engine", "compiled")
        return f"{argument('seed_batch')}: {RETIRED[(experiment, framework)]}; run its seeds with {instead}"
    if (experiment, framework) not in STACKED:
        have = ", ".join(f"{e} ({f})" for e, f in STACKED)
        return f"{argument('seed_batch')} has no {framework} learner for {experiment} yet; it has: {have}"
    return None


def stacked_implementation(experiment: str, framework: str) -> Implementation:
    from keras_rl.errors import ConfigError

    why = no_stacked_learner(experiment, framework)
    if why is not None:
        raise ConfigError(why)
    return STACKED[(experiment, framework)]


def frameworks(experiment: str) -> tuple[str, ...]:
    """The frameworks an experiment is implemented in, in table order."""
    return tuple(fw for (name, fw) in IMPLEMENTATIONS if name == experiment)


def compared_frameworks(experiment: str) -> tuple[str, str]:
    """The two frameworks ``keras-rl compare`` sets side by side (ours first), or a
    ConfigError when the experiment has no second one."""
    from keras_rl.errors import ConfigError

    have = frameworks(experiment)
    if len(have) != 2:
        raise ConfigError(
            f"{experiment} has no PyTorch version yet, so there is nothing to compare it with "
            f"(frameworks: {', '.join(have)})"
        )
    return have[0], have[1]


def implementation(experiment: str, framework: str) -> Implementation:
    from keras_rl.errors import ConfigError

    try:
        return IMPLEMENTATIONS[(experiment, framework)]
    except KeyError:
        raise ConfigError(
            f"{experiment} has no {framework!r} version; choose one of {', '.join(frameworks(experiment))}"
        ) from None
