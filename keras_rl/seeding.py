"""Seeding and TensorFlow runtime set-up for reproducible runs."""

from __future__ import annotations

import keras
import tensorflow as tf


def configure_tensorflow(threads: int | None = 1) -> None:
    """Op determinism always; thread pools sized once, before TF runs its first op.

    One thread is the fastest setting for these small networks (see benchmarks/) and
    lets ``--workers`` processes share the two cores without contention.
    """
    tf.config.experimental.enable_op_determinism()
    if threads:
        try:
            tf.config.threading.set_intra_op_parallelism_threads(threads)
            tf.config.threading.set_inter_op_parallelism_threads(threads)
        except RuntimeError:
            pass  # TF already initialised in this process (e.g. a second run in one test session)


def seed_everything(seed: int) -> None:
    """Python's ``random``, NumPy's global RNG and TensorFlow/Keras initialisers."""
    keras.utils.set_random_seed(seed)
