"""The one soft-update helper: theta' <- tau * theta + (1 - tau) * theta'."""

from __future__ import annotations

from typing import Any, Sequence


def soft_update(target: Sequence[Any], source: Sequence[Any], tau: float) -> None:
    """Polyak-average ``source`` into ``target`` in place; ``tau=1`` is a hard copy.

    Keras variables are assigned (eagerly or inside ``tf.function``: no host round-trip,
    unlike the posts' ``get_weights``/``set_weights``); PyTorch tensors (parameters and
    buffers) are overwritten in place, under ``torch.no_grad()`` at the caller. Both
    compute the same float32 expression, so the two frameworks' targets agree bit for bit
    given equal inputs. Lists must pair up one to one.
    """
    for t, s in zip(target, source, strict=True):
        if hasattr(t, "assign"):
            t.assign(tau * s + (1.0 - tau) * t)
        else:
            t.copy_(tau * s + (1.0 - tau) * t)
