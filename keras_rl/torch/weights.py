"""Moving weights: Keras into torch (``copy_from_keras``, for ``matched_init`` and the
tutorial's parity), and torch into torch (``soft_update``, ``hard_copy``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from keras_rl.torch import require_torch

require_torch()  # a clear error, naming the extra, when torch is missing
import torch  # noqa: E402


def dense_pairs(linears, denses) -> list:
    """(torch tensor, Keras variable, transpose?) for each Linear/Dense pair."""
    if len(linears) != len(denses):
        raise ValueError(f"{len(linears)} torch layers vs {len(denses)} Keras layers")
    pairs = []
    for linear, dense in zip(linears, denses):
        pairs += [(linear.weight, dense.kernel, True), (linear.bias, dense.bias, False)]
    return pairs


def copy_from_keras(module, keras_model, pairs: list | None = None) -> None:
    """Overwrite ``module``'s weights (and BatchNorm statistics) with ``keras_model``'s.

    ``pairs`` defaults to ``module.keras_pairs(keras_model)``: (tensor, variable, transpose?)."""
    with torch.no_grad():
        for tensor, variable, transpose in pairs if pairs is not None else module.keras_pairs(keras_model):
            value = np.asarray(variable.numpy())
            value = value.T if transpose else value
            if tuple(tensor.shape) != value.shape:
                raise ValueError(
                    f"shape mismatch copying Keras {variable.path} {value.shape} into torch {tuple(tensor.shape)}"
                )
            tensor.copy_(torch.from_numpy(np.ascontiguousarray(value)))


def soft_update(target: Sequence, source: Sequence, tau: float) -> None:
    """``theta' <- tau * theta + (1 - tau) * theta'`` on torch tensors in place (call under
    ``torch.no_grad()``): the same float32 expression as the Keras learners' ``soft_update``,
    so the two frameworks' targets agree bit for bit given equal inputs."""
    for t, s in zip(target, source, strict=True):
        t.copy_(tau * s + (1.0 - tau) * t)


def variables(module) -> list:
    """Parameters, then buffers: Keras variables include BatchNormalization's moving statistics."""
    return [*module.parameters(), *module.buffers()]


def hard_copy(target, source) -> None:
    with torch.no_grad():
        soft_update(variables(target), variables(source), 1.0)


def match_keras(nets: Sequence, keras_nets: Sequence) -> None:
    for net, keras_net in zip(nets, keras_nets, strict=True):
        copy_from_keras(net, keras_net)
