"""The state of a random number generator as plain data, for checkpoints (``--resume``)."""

from __future__ import annotations

import random
from typing import Any

import numpy as np


def rng_state(rng) -> Any:
    """A NumPy Generator's bit-generator state, or a ``random.Random``'s ``getstate()``."""
    if isinstance(rng, np.random.Generator):
        return {"numpy": rng.bit_generator.state}
    if isinstance(rng, random.Random):
        return {"python": rng.getstate()}
    raise TypeError(f"no state for {type(rng).__name__}")


def set_rng_state(rng, state: Any) -> None:
    if isinstance(rng, np.random.Generator):
        rng.bit_generator.state = state["numpy"]
    elif isinstance(rng, random.Random):
        rng.setstate(state["python"])
    else:
        raise TypeError(f"no state for {type(rng).__name__}")


def global_rng_state() -> dict[str, Any]:
    """Python's ``random`` and NumPy's legacy global RNG (what ``seed_everything`` seeds)."""
    return {"python": random.getstate(), "numpy": np.random.get_state()}


def set_global_rng_state(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
