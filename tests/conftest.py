import keras_rl  # noqa: F401  (pins KERAS_BACKEND before keras is imported anywhere)
import numpy as np
import pytest

from keras_rl.seeding import configure_tensorflow

configure_tensorflow(1)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
