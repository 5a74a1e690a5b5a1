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


# `make test` runs the suite in two processes (pytest-xdist, --dist loadgroup). A module-scoped
# fixture that trains is built once per process that runs a test using it, so each such test
# joins its fixture's group; the tests of test_ray.py (clusters, socket checks) keep to one.
GROUP_OF_FIXTURE = {"compared": "compare-runs", "sweep_dir": "ray", "short_run": "short-run", "tiny": "tiny-runs"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        groups = [GROUP_OF_FIXTURE[f] for f in getattr(item, "fixturenames", ()) if f in GROUP_OF_FIXTURE]
        if groups:  # those fixtures train (in a subprocess, some under Ray): out of `make test-fast`
            item.add_marker(pytest.mark.slow)
        if item.get_closest_marker("ray") is not None:
            groups.append("ray")
        if groups:
            item.add_marker(pytest.mark.xdist_group(groups[0]))
