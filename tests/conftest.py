import os

# Before anything imports Ray: a local Ray instance (and a test Cluster) then listens on
# loopback only. Ray reads the variable when its modules are imported.
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")

import numpy as np
import pytest

import keras_rl  # noqa: F401  (pins KERAS_BACKEND before keras is imported anywhere)
from keras_rl.seeding import configure_tensorflow

configure_tensorflow(1)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
