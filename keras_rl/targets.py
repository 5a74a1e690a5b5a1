"""The one soft-update helper: theta' <- tau * theta + (1 - tau) * theta'."""

from __future__ import annotations

from typing import Sequence

import keras


def soft_update(target: Sequence[keras.Variable], source: Sequence[keras.Variable], tau: float) -> None:
    """Polyak-average ``source`` into ``target`` in place; ``tau=1`` is a hard copy.

    Works eagerly and inside ``tf.function`` (no host round-trip, unlike the posts'
    ``get_weights``/``set_weights``). Lists must pair up one to one.
    """
    for t, s in zip(target, source, strict=True):
        t.assign(tau * s + (1.0 - tau) * t)
