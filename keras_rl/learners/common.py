"""What every Keras learner uses: the compiled step, the soft update, and weight files."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import tensorflow as tf

from keras_rl.errors import RunFolderError


def step_function(fn, xla: bool, *specs: tf.TensorSpec):
    """``tf.function`` (XLA-compiled when ``xla``) for ``specs``, not yet traced: the caller
    calls ``.get_concrete_function()`` itself, so the trace runs from the caller's frame and
    this helper is not on the stack of what it traces (``tests/test_structure.py`` counts
    the frames from ``main`` to ``soft_update``).

    Learners keep the concrete function: calling it skips tf.function's per-call signature
    dispatch, which costs as much as the update itself at these network sizes (benchmarks/)."""
    return tf.function(fn, jit_compile=xla, input_signature=list(specs))


def soft_update(target: Sequence[Any], source: Sequence[Any], tau: float, seeds: tf.Tensor | None = None) -> None:
    """Polyak-average Keras variables: ``theta' <- tau * theta + (1 - tau) * theta'``; ``tau=1``
    is a hard copy. Assigned in place, eagerly or inside ``tf.function`` (no host round-trip,
    unlike the posts' ``get_weights``/``set_weights``). Lists must pair up one to one.
    ``seeds``: a ``[S]`` bool mask over the variables' leading seed axis (a stacked learner);
    a seed where it is False keeps its target as it is."""
    for t, s in zip(target, source, strict=True):
        new = tau * s + (1.0 - tau) * t
        if seeds is not None:
            new = tf.where(tf.reshape(seeds, [-1] + [1] * (len(t.shape) - 1)), new, t)
        t.assign(new)


def save_weights(model, path: Path) -> None:
    """``model.save_weights``, atomically (``atomic.atomic_replace``)."""
    from keras_rl.atomic import atomic_replace

    atomic_replace(path, lambda tmp: model.save_weights(str(tmp)))


def load_weights(model, path: Path) -> None:
    """``model.load_weights`` with a RunFolderError that names a missing or damaged file."""
    path = Path(path)
    if not path.is_file():
        raise RunFolderError(
            f"{path} is missing: weights are not committed, so run `keras-rl reproduce` "
            "for this seed first (it saves them)"
        )
    try:
        model.load_weights(str(path))
    except Exception as exc:  # h5py/keras raise many kinds for a damaged file
        raise RunFolderError(f"{path} could not be loaded ({type(exc).__name__}: {exc})") from None


def variables_state(variables) -> list:
    return [v.numpy().copy() for v in variables]


def load_variables_state(variables, values) -> None:
    variables = list(variables)
    if len(variables) != len(values):
        raise ValueError(f"checkpoint holds {len(values)} values for {len(variables)} variables")
    for variable, value in zip(variables, values):
        variable.assign(value)


def numpy_weights(model) -> list:
    """A Keras model's variables (trainable or not) as numpy arrays."""
    return [v.numpy() for v in model.variables]
