"""keras-rl-repro: faithful, fast, tested reruns of classic deep-RL blog posts.

The public Python API is ``keras_rl.api`` (``load``, ``reproduce``, ``compare``, ``check``;
``docs/api.md``); the command line is ``keras-rl``.

Keras 3 must run on the TensorFlow backend, so the backend is pinned here,
before anything in the package imports keras.
"""

from __future__ import annotations

import os
import sys

if "keras" in sys.modules and os.environ.get("KERAS_BACKEND", "tensorflow") != "tensorflow":
    raise ImportError(
        "keras was imported with KERAS_BACKEND="
        f"{os.environ['KERAS_BACKEND']!r} before keras_rl; keras_rl needs the TensorFlow "
        "backend. Import keras_rl first or set KERAS_BACKEND=tensorflow."
    )
os.environ["KERAS_BACKEND"] = "tensorflow"
# TensorFlow's C++ start-up chatter (CPU feature notices) hides our own output.
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from keras_rl import quiet  # noqa: E402

quiet.install()

__version__ = "0.1.0"
__all__ = ["__version__", "api"]
