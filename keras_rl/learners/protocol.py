"""What every learner offers the agent skeleton, the run loop and the tests.

A learner owns the networks, the optimizers and the update; it knows nothing of
environments, buffers or exploration. Keras learners (``keras_rl.learners``) and PyTorch
learners (``keras_rl.torch``) implement the same protocol, so the agents, the loop and
the result files are shared, and a difference in outcome comes from the framework.
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

Losses = Mapping[str, Any]
"""One update's losses by name; values are scalars of the learner's framework (``float()`` works)."""


class Learner(Protocol):
    loss_names: tuple[str, ...]
    """The names ``train`` reports, in ``episodes.csv``'s column order."""

    def compile(self) -> None:
        """Trace the compiled steps, once; a no-op for an eager framework. ``train`` and
        ``act`` call it first, so only a caller that wants the trace at a known moment does
        (the loop, before its first env step)."""

    def train(self, rows: np.ndarray) -> Losses:
        """One update on packed transition rows ``[B, width]`` (``buffers.Layout``)."""

    def act(self, state: np.ndarray) -> np.ndarray:
        """The policy's action for one state, as numpy (an int for a discrete action)."""

    def train_and_act(self, rows: np.ndarray, state: np.ndarray) -> tuple[Losses, Any]:
        """``train(rows)`` then ``act(state)`` with the updated weights, in one call where
        the framework can fuse them (the posts pick step t+1's action after step t's update)."""

    def step_without_batch(self, state: np.ndarray, want_action: bool) -> Any:
        """An env step on which the schedule does not train: whatever the post does every
        step regardless (post 003's soft update), then ``act(state)`` if ``want_action``,
        else None."""

    def save(self, run_dir: Path) -> None:
        """Write the weight files into ``run_dir``."""

    def load_policy(self, run_dir: Path) -> None:
        """Load what greedy play needs (the actor, or the Q-network) from ``run_dir``."""

    def weights(self) -> dict[str, list[np.ndarray]]:
        """Every network's weights as numpy arrays, by network name (for tests)."""

    def state_dict(self) -> dict[str, Any]:
        """Weights, optimizer state and any RNG the learner owns, as plain data (checkpoints)."""

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore ``state_dict()``'s output exactly."""


ActorGradient = Literal["mean_q", "dpg_intended", "dpg_literal"]
"""How a DDPG learner forms the actor's gradient (``keras_rl/learners/ddpg.py`` explains each)."""


def check_actor_gradient(actor_gradient: str) -> str:
    if actor_gradient not in typing.get_args(ActorGradient):
        raise ValueError(
            f"actor_gradient must be one of {', '.join(typing.get_args(ActorGradient))}, got {actor_gradient!r}"
        )
    return actor_gradient


def four_networks(
    make_actor: Callable[[], Any], make_critic: Callable[[], Any], hard_copy: Callable[[Any, Any], None] | None
) -> tuple[Any, Any, Any, Any]:
    """A DDPG post's four networks, built in the order both posts draw their initial
    weights (actor, target actor, critic, target critic), the targets hard-copied from
    their networks when ``hard_copy`` is given. Returned as (actor, critic, target actor,
    target critic), the order the learners take."""
    actor, target_actor = make_actor(), make_actor()
    critic, target_critic = make_critic(), make_critic()
    if hard_copy is not None:
        hard_copy(target_actor, actor)
        hard_copy(target_critic, critic)
    return actor, critic, target_actor, target_critic
