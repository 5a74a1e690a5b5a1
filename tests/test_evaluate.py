"""`keras-rl evaluate`: greedy episodes from a run folder's weights, the GIF, a refused or
corrupt folder, and an evaluation that is interrupted or shorter never replacing a finished one."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from importlib import import_module

import pytest
from clitools import CLI, default_signals, run_cli, strict_json

from keras_rl.cli import main
from keras_rl.runs.files import read_episodes


def test_ctrl_c_during_evaluate_keeps_the_episodes_played(tiny):
    run_dir = tiny[0] / "seed_1"
    proc = subprocess.Popen(
        [*CLI, "evaluate", str(run_dir), "--episodes", "100000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_signals,
    )
    deadline = time.monotonic() + 120
    lines = []
    while time.monotonic() < deadline and len(lines) < 3:
        line = proc.stdout.readline()
        if line.startswith("episode:"):
            lines.append(line)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in stderr, stderr
    result = strict_json(run_dir / "evaluation.json")
    assert result["interrupted"] is True and len(result["scores"]) >= 3 and result["episodes"] == len(result["scores"])


def test_evaluate_refuses_a_folder_without_config(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path)]) == 2
    assert "has no config.json" in capsys.readouterr().err


def test_evaluate_refuses_a_corrupt_config(short_run, tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "config.json").write_text('{"experiment": "pendulum", "tau": ')
    assert main(["evaluate", str(bad)]) == 2
    assert "is corrupt" in capsys.readouterr().err


def test_evaluate_refuses_corrupt_or_missing_weights(short_run, tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "config.json").write_text((short_run / "config.json").read_text())
    assert main(["evaluate", str(bad)]) == 2
    assert "actor.weights.h5 is missing" in capsys.readouterr().err
    (bad / "actor.weights.h5").write_bytes(b"\x89HDF\r\n garbage")
    assert main(["evaluate", str(bad)]) == 2
    assert "could not be loaded" in capsys.readouterr().err


def test_evaluate_plays_greedy_episodes_and_writes_a_gif(short_run, tmp_path):
    """Where no display is set up (no XDG_RUNTIME_DIR, no SDL_VIDEODRIVER), as on a server, the
    GIF is drawn without a word of error (item 21 of the new user's report that
    tests/test_bad_input.py follows: one was printed)."""
    import os

    gif = tmp_path / "pendulum.gif"
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_RUNTIME_DIR", "SDL_VIDEODRIVER")}
    proc = run_cli("evaluate", str(short_run), "--episodes", "2", "--gif", str(gif), env=env)
    assert proc.returncode == 0, proc.stderr
    assert "error" not in (proc.stdout + proc.stderr).lower()
    assert "mean score over 2 greedy episodes" in proc.stdout
    result = json.loads((short_run / "evaluation.json").read_text())
    assert len(result["scores"]) == 2 and all(-2000 < s <= 0 for s in result["scores"])
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    from PIL import Image

    with Image.open(gif) as img:
        assert img.n_frames == 200
    assert "episode:   1 |" in proc.stdout and "episode:   0" not in proc.stdout  # numbered as episodes.csv


def test_evaluate_keeps_a_longer_evaluation_and_refuses_a_gif_named_otherwise(short_run, capsys):
    """#23.4 and #23.10: a 1-episode evaluation replaced a 100-episode one; --gif x.mp4 wrote a GIF."""
    path = short_run / "evaluation.json"
    longer = {"episodes": 100, "episodes_asked": 100, "scores": [-1.0] * 100, "interrupted": False}
    path.write_text(json.dumps(longer))
    assert main(["evaluate", str(short_run), "--episodes", "1"]) == 2
    assert "holds an evaluation of 100 episodes" in capsys.readouterr().err
    assert json.loads(path.read_text()) == longer  # nothing played, nothing replaced
    assert main(["evaluate", str(short_run), "--episodes", "1", "--gif", str(short_run / "x.mp4")]) == 2
    assert "name it *.gif" in capsys.readouterr().err
    assert main(["evaluate", str(short_run), "--episodes", "1", "--overwrite"]) == 0
    assert json.loads(path.read_text())["episodes"] == 1


def test_an_interrupted_evaluation_never_replaces_a_finished_one(short_run, monkeypatch):
    import dataclasses

    import gymnasium as gym

    from keras_rl.runs import evaluate

    class InterruptAt(gym.Wrapper):
        def __init__(self, env, at=250):  # in the second episode
            super().__init__(env)
            self.at, self.steps = at, 0

        def step(self, action):
            self.steps += 1
            if self.steps == self.at:
                raise KeyboardInterrupt
            return self.env.step(action)

    path = short_run / "evaluation.json"
    finished = {"episodes": 3, "scores": [-1.0] * 3, "interrupted": False}
    path.write_text(json.dumps(finished))
    import keras_rl.registry as registry  # evaluate looks the experiment up there when it runs

    real = registry.get_experiment("pendulum")
    wrapped = dataclasses.replace(real, make_env=lambda *a, **k: InterruptAt(real.make_env(*a, **k)))
    monkeypatch.setattr(registry, "get_experiment", lambda name: wrapped)
    result = evaluate.evaluate_run(short_run, episodes=5)
    assert result["interrupted"] and len(result["scores"]) == 1
    assert json.loads(path.read_text()) == finished
    assert json.loads((short_run / "evaluation.interrupted.json").read_text())["episodes"] == 1


@pytest.mark.parametrize("experiment,episodes", [("pendulum", 6), ("mountaincar", 2)])
@pytest.mark.slow
def test_torch_ddpg_run_folder_evaluate_and_corrupt_checkpoint(tmp_path, capsys, experiment, episodes):
    """The run in a subprocess, as a user starts it; its two evaluations in this process
    (``main``, as the Keras ones above), where a process each cost some 6 s of imports."""
    pytest.importorskip("torch", reason="needs the torch extra")
    out = tmp_path / "t"
    proc = run_cli(
        "reproduce",
        experiment,
        "--framework",
        "torch",
        "--matched-init",
        "--seeds",
        "1",
        "--episodes",
        str(episodes),
        "--no-progress",
        "--out",
        str(out),
    )
    assert proc.returncode == 1, proc.stderr  # too few episodes for either criterion
    run_dir = out / "seed_1"
    for name in ("config.json", "episodes.csv", "summary.json", "curve.png", "actor.pt", "critic.pt"):
        assert (run_dir / name).is_file(), name
    config = json.loads((run_dir / "config.json").read_text())
    assert config["framework"] == "torch" and config["matched_init"] is True
    assert len(read_episodes(run_dir / "episodes.csv")) == episodes
    assert main(["evaluate", str(run_dir), "--episodes", "1"]) == 0, capsys.readouterr().err
    assert len(strict_json(run_dir / "evaluation.json")["scores"]) == 1
    (run_dir / "actor.pt").write_bytes(b"\x00garbage")
    capsys.readouterr()
    assert main(["evaluate", str(run_dir), "--episodes", "1"]) == 2
    assert "actor.pt could not be loaded" in capsys.readouterr().err


@pytest.mark.parametrize("framework,weights", [("keras", "q_network.weights.h5"), ("torch", "q_network.pt")])
@pytest.mark.slow
def test_cartpole_run_folder_and_evaluate_with_gif(tmp_path, framework, weights):
    if framework == "torch":
        pytest.importorskip("torch", reason="needs the torch extra")
    out = tmp_path / "c"
    proc = run_cli(
        "reproduce",
        "cartpole",
        "--framework",
        framework,
        "--seeds",
        "2",
        "--episodes",
        "20",
        "--no-progress",
        "--out",
        str(out),
    )
    assert proc.returncode == 1, proc.stderr  # 20 episodes cannot reach a 100-episode mean of 475
    run_dir = out / "seed_2"
    for name in ("config.json", "episodes.csv", "summary.json", "curve.png", weights):
        assert (run_dir / name).is_file(), name
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["framework"] == framework and summary["episodes_run"] == 20
    assert summary["versions"][framework] == import_module(framework).__version__  # the framework it ran on
    assert summary["last_100_share_at_500"] == 0.0
    gif = tmp_path / "cartpole.gif"
    proc = run_cli("evaluate", str(run_dir), "--episodes", "2", "--gif", str(gif))
    assert proc.returncode == 0, proc.stderr
    scores = json.loads((run_dir / "evaluation.json").read_text())["scores"]
    assert len(scores) == 2 and all(1 <= s <= 500 for s in scores)
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
