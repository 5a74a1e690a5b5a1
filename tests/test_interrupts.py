"""A run that is stopped (Ctrl-C, SIGTERM) or blows up (NaN loss) keeps the episodes it played,
leaves valid files marked unfinished, and exits as the user asked."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest
from clitools import CLI, default_signals, strict_json, wait_for_rows
from wrappers import NaNRewardAfter, SigintAt

from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.registry import get_experiment
from keras_rl.runs.files import read_episodes
from keras_rl.train.loop import run_seed
from keras_rl.train.settings import TrainSettings


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.slow
def test_sigterm_is_handled_like_ctrl_c(tmp_path, workers):
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [
            *CLI,
            "reproduce",
            "pendulum",
            "--seeds",
            "0-2",
            "--workers",
            str(workers),
            "--no-progress",
            "--set",
            "stop_at_threshold=false",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_signals,
    )
    csv = out / "seed_0" / "episodes.csv"
    wait_for_rows(proc, csv, 3)
    proc.send_signal(signal.SIGTERM)  # to the command only, as `timeout` or `docker stop` send it
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    assert "seed 0: interrupted, no verdict" in stdout and "FAIL" not in stdout  # #23.9: it said FAIL
    summary = strict_json(out / "seed_0" / "summary.json")
    assert summary["status"] == "interrupted" and "SIG" in summary["message"]
    assert summary["episodes_run"] == len(read_episodes(csv)) >= 3
    assert (out / "seed_0" / "checkpoint.pkl").is_file()  # so --resume can continue it
    assert not (out / "seed_2").exists()  # the queued seed never started


@pytest.mark.slow
def test_nan_in_a_loss_stops_the_run_and_keeps_the_episodes(tmp_path):
    exp = get_experiment("pendulum")
    config = PendulumDDPGConfig.for_variant("faithful", episodes=10, train_start=64, batch_size=16)
    env = NaNRewardAfter(exp.make_env(config), after_steps=450)
    summary = run_seed(exp, config, tmp_path, TrainSettings(progress=False), env=env)
    assert summary.status == "non_finite_loss" and not summary.finished
    assert "critic_loss became nan" in summary.message
    rows = read_episodes(tmp_path / "episodes.csv")
    assert [r["episode"] for r in rows] == [1, 2]  # the episode that hit NaN is not recorded
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "non_finite_loss"
    # a NaN is this config's outcome: sweep and compare reuse it rather than rerun it each time
    from keras_rl.runs.provenance import code_version
    from keras_rl.runs.reuse import check_reusable

    assert check_reusable(tmp_path, config, code_version()) is None
    stopped = json.loads((tmp_path / "summary.json").read_text()) | {"status": "interrupted"}
    (tmp_path / "summary.json").write_text(json.dumps(stopped))
    assert check_reusable(tmp_path, config, code_version()) == "unfinished (interrupted)"


@pytest.mark.slow
def test_ctrl_c_mid_episode_is_taken_between_env_steps(tmp_path):
    exp = get_experiment("pendulum")
    config = PendulumDDPGConfig.for_variant("faithful", episodes=10, train_start=64, batch_size=16)
    # Python's own Ctrl-C handler, even where the test runner was started with SIGINT ignored
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        summary = run_seed(
            exp, config, tmp_path, TrainSettings(progress=False), env=SigintAt(exp.make_env(config), at=450)
        )
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the run put it back
    finally:
        signal.signal(signal.SIGINT, previous)
    assert summary.status == "interrupted" and summary.episodes_run == 2  # episode 3 was cut short
    assert [r["episode"] for r in read_episodes(tmp_path / "episodes.csv")] == [1, 2]
    assert (tmp_path / "actor.weights.h5").is_file()


def test_stop_signals_as_flag_records_instead_of_raising_and_respects_an_ignored_sigint():
    from keras_rl.runs.signals import stop_signals_as_flag

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with stop_signals_as_flag() as caught:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # let the handler run
        assert caught == [signal.SIGINT]
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with stop_signals_as_flag() as caught:
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # left as the process was told
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        assert caught == []
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.slow
def test_ctrl_c_leaves_valid_files_marked_unfinished_that_resume_only_with_the_same_options(tmp_path):
    """A terminal's Ctrl-C (SIGINT to the whole group) to a run in one process; the same under
    ``--workers 2`` is tests/test_pool.py's pooled sweep. The seed it left resumes with the
    options that made it and no others: one more field is refused, naming it, before anything
    in the folder is touched."""
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    command = [*CLI, "reproduce", "pendulum", "--seeds", "0", "--workers", "1", "--no-progress"]
    command += ["--set", "stop_at_threshold=false", "--out", str(out)]
    # A new session, so that SIGINT can go to the whole group as a terminal's Ctrl-C does.
    # SIGINT back to its default in the child: a test run launched in the background (`cmd &`
    # in a script) inherits SIGINT as ignored, and Python then never raises KeyboardInterrupt.
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    csv = out / "seed_0" / "episodes.csv"
    wait_for_rows(proc, csv, 3, poll=0.2)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr
    summary = json.loads((out / "seed_0" / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["finished"] is False
    rows = read_episodes(csv)
    assert len(rows) >= 3 and summary["episodes_run"] == len(rows)
    assert not list((out / "seed_0").glob(".tmp-*"))  # no half-written temporary files
    assert (out / "seed_0" / "checkpoint.pkl").is_file()

    before = {p.name: p.read_bytes() for p in (out / "seed_0").iterdir()}
    other = subprocess.run([*command, "--resume", "--set", "tau=0.01"], capture_output=True, text=True, timeout=300)
    assert other.returncode == 2 and "was made with tau=0.001" in other.stderr, other.stderr
    assert {p.name: p.read_bytes() for p in (out / "seed_0").iterdir()} == before
