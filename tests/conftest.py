import os

# Before anything imports Ray: a local Ray instance (and a test Cluster) then listens on
# loopback only. Ray reads the variable when its modules are imported.
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")

import numpy as np
import pytest
from clitools import run_cli

import keras_rl  # noqa: F401  (pins KERAS_BACKEND before keras is imported anywhere)
from keras_rl.seeding import configure_tensorflow

configure_tensorflow(1)


@pytest.fixture
def replace_backend(monkeypatch):
    """``replace_backend(run)``: every command's ``train_seeds`` hands its jobs to
    ``run(jobs, backend, progress, after_job)`` instead of running them (``backend``: the one it
    picked); ``run`` returns True where a Ctrl-C would have stopped them."""
    from keras_rl.dispatch import backends

    picks = backends.backend_for

    class Replaced:
        def __init__(self, run, picked):
            self.do, self.picked = run, picked

        def run(self, jobs, progress, after_job=None):
            return bool(self.do(jobs, self.picked, progress, after_job))

    def install(run):
        monkeypatch.setattr(backends, "backend_for", lambda *a, **k: Replaced(run, picks(*a, **k)))

    return install


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


# Runs that several test modules read, made once per process (their tests share an xdist group,
# below, so one process makes each). Tests that change them work on a copy, but for the
# evaluations of tests/test_evaluate.py, which add evaluation files in their module's order.
@pytest.fixture(scope="session")
def tiny(tmp_path_factory):
    """A 2-episode cartpole run (seconds): (its --out folder, the finished process)."""
    out = tmp_path_factory.mktemp("tiny") / "c"
    proc = run_cli("reproduce", "cartpole", "--seeds", "1", "--episodes", "2", "--no-progress", "--out", str(out))
    assert proc.returncode == 1, proc.stderr
    return out, proc


@pytest.fixture(scope="session")
def short_run(tmp_path_factory):
    """Seed 3 of a 7-episode pendulum run that trains from episode 4: its seed folder."""
    out = tmp_path_factory.mktemp("runs") / "p"
    proc = run_cli(
        "reproduce",
        "pendulum",
        "--seeds",
        "3",
        "--episodes",
        "7",
        "--no-progress",
        "--set",
        "stop_at_threshold=false",
        "--set",
        "train_start=600",
        "--out",
        str(out),
    )
    assert proc.returncode == 1, proc.stderr  # 7 episodes cannot reach -300: criterion fails
    return out / "seed_3"


# `make test` runs the suite in two processes (pytest-xdist, --dist loadgroup). A module- or
# session-scoped fixture that trains is built once per process that runs a test using it, so each such test
# joins its fixture's group; the tests of test_ray.py (clusters, socket checks) keep to one.
GROUP_OF_FIXTURE = {
    "compared": "compare-runs",
    "sweep_dir": "sweep",
    "short_run": "short-run",
    "tiny": "tiny-runs",
    "installed": "installed-wheel",
}


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's hook, which reads the groups set here
def pytest_collection_modifyitems(config, items):
    for item in items:
        groups = [GROUP_OF_FIXTURE[f] for f in getattr(item, "fixturenames", ()) if f in GROUP_OF_FIXTURE]
        if groups:  # those fixtures train (in a subprocess, some under Ray): out of `make test-fast`
            item.add_marker(pytest.mark.slow)
        if item.get_closest_marker("ray") is not None:
            groups.append("ray")
        if groups:
            item.add_marker(pytest.mark.xdist_group(groups[0]))
    # the slow tests first, in their modules' order, then the quick ones: under `-n 2` the quick
    # tests fill the end of the run on whichever process is free, instead of one process running a
    # two-minute test alone at the end (a stable sort: the order is the same in every process)
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
