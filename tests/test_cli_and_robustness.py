"""Bad input gets a clear error; interrupted or failed runs keep what they wrote."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from wrappers import NaNRewardAfter, SigintAt

from keras_rl.cli import main, parse_seeds
from keras_rl.errors import RunFolderError
from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.registry import get_experiment
from keras_rl.runs.files import read_episodes
from keras_rl.runs.loop import run_seed

CLI = [sys.executable, "-m", "keras_rl"]


def run_cli(*args, **kwargs):
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=600, **kwargs)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
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


def test_parse_seeds():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("5,1,1,2-3") == [1, 2, 3, 5]
    assert parse_seeds("13") == [13]


@pytest.mark.parametrize(
    "argv,message",
    [
        (["reproduce", "cartpool"], "unknown experiment 'cartpool'"),
        (["reproduce", "pendulum", "--seeds", "5-2"], "runs backwards"),
        (["reproduce", "pendulum", "--seeds", "a-b"], "cannot read seeds"),
        (["reproduce", "pendulum", "--episodes", "0"], "--episodes must be positive"),
        (["reproduce", "pendulum", "--episodes", "-3"], "--episodes must be positive"),
        (["reproduce", "pendulum", "--variant", "fastest"], "unknown variant 'fastest'"),
        (["reproduce", "pendulum", "--set", "actor_lr=-0.001"], "actor_lr must be positive"),
        (["reproduce", "pendulum", "--set", "tau=2"], "tau must be in (0, 1]"),
        (["reproduce", "pendulum", "--set", "gamma=nan"], "gamma must be finite"),
        (["reproduce", "pendulum", "--set", "batch_size=lots"], "batch_size expects an int"),
        (["reproduce", "pendulum", "--set", "warp=9"], "unknown pendulum config field 'warp'"),
        (["reproduce", "pendulum", "--workers", "0"], "--workers must be at least 1"),
        (["reproduce", "pendulum", "--set", "env_id=NoSuchEnv-v9"], "unknown environment 'NoSuchEnv-v9'"),
        (
            ["reproduce", "pendulum", "--set", "env_id=CartPole-v1", "--no-progress"],
            "needs a continuous Box action space",
        ),
        (["evaluate", "/no/such/run"], "does not exist"),
    ],
)
def test_bad_input_is_named_and_exits_non_zero(argv, message, capsys, tmp_path):
    if argv[0] == "reproduce":
        argv = [*argv, "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


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


def test_run_folder_has_every_file(short_run):
    for name in ("config.json", "episodes.csv", "summary.json", "curve.png", "actor.weights.h5", "critic.weights.h5"):
        assert (short_run / name).is_file(), name
    summary = json.loads((short_run / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["success"] is False
    assert summary["reached_at_episode"] is None and summary["episodes_run"] == 7
    assert summary["versions"]["keras_backend"] == "tensorflow"
    rows = read_episodes(short_run / "episodes.csv")
    assert [r["episode"] for r in rows] == list(range(1, 8))
    assert all(r["steps"] == 200 for r in rows) and rows[-1]["total_steps"] == 1400
    assert rows[0]["critic_loss"] is None and rows[-1]["critic_loss"] is not None  # training from step 600


def test_evaluate_plays_greedy_episodes_and_writes_a_gif(short_run, tmp_path):
    gif = tmp_path / "pendulum.gif"
    proc = run_cli("evaluate", str(short_run), "--episodes", "2", "--gif", str(gif))
    assert proc.returncode == 0, proc.stderr
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


@pytest.mark.slow
def test_nan_in_a_loss_stops_the_run_and_keeps_the_episodes(tmp_path):
    exp = get_experiment("pendulum")
    config = PendulumDDPGConfig.for_variant("faithful", episodes=10, train_start=64, batch_size=16)
    env = NaNRewardAfter(exp.make_env(config), after_steps=450)
    summary = run_seed(exp, config, tmp_path, progress=False, env=env)
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
        summary = run_seed(exp, config, tmp_path, progress=False, env=SigintAt(exp.make_env(config), at=450))
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


@pytest.mark.parametrize("seeds,workers", [("0", 1), ("0-2", 2)])
@pytest.mark.slow
def test_ctrl_c_leaves_valid_files_marked_unfinished(tmp_path, seeds, workers):
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    # A new session, so that SIGINT can go to the whole group as a terminal's Ctrl-C does.
    # SIGINT back to its default in the child: a test run launched in the background (`cmd &`
    # in a script) inherits SIGINT as ignored, and Python then never raises KeyboardInterrupt.
    proc = subprocess.Popen(
        [
            *CLI,
            "reproduce",
            "pendulum",
            "--seeds",
            seeds,
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
        env=env,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    csv = out / "seed_0" / "episodes.csv"
    deadline = time.time() + 300
    while time.time() < deadline:
        if csv.is_file() and len(csv.read_text().splitlines()) >= 4:
            break
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr
    summary = json.loads((out / "seed_0" / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["finished"] is False
    rows = read_episodes(csv)
    assert len(rows) >= 3 and summary["episodes_run"] == len(rows)
    assert not list((out / "seed_0").glob(".*.tmp"))  # no half-written temporary files
    if workers > 1:
        assert not (out / "seed_2").exists()  # the queued seed never started


def test_torch_framework_without_torch_is_a_clear_error(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "torch", None)  # makes `import torch` fail
    assert main(["reproduce", "cartpole", "--framework", "torch", "--out", str(tmp_path)]) == 2
    assert "the torch framework needs PyTorch" in capsys.readouterr().err


def test_framework_the_experiment_does_not_have(capsys, tmp_path):
    assert main(["reproduce", "pendulum", "--framework", "jax", "--out", str(tmp_path)]) == 2
    assert "pendulum has no 'jax' version; choose one of keras, torch" in capsys.readouterr().err
    assert main(["reproduce", "pendulum", "--matched-init", "--out", str(tmp_path)]) == 2
    assert "needs framework 'torch', not 'keras'" in capsys.readouterr().err


@pytest.mark.parametrize("experiment,episodes", [("pendulum", 6), ("mountaincar", 2)])
@pytest.mark.slow
def test_torch_ddpg_run_folder_evaluate_and_corrupt_checkpoint(tmp_path, experiment, episodes):
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
    proc = run_cli("evaluate", str(run_dir), "--episodes", "1")
    assert proc.returncode == 0, proc.stderr
    (run_dir / "actor.pt").write_bytes(b"\x00garbage")
    proc = run_cli("evaluate", str(run_dir), "--episodes", "1")
    assert proc.returncode == 2 and "actor.pt could not be loaded" in proc.stderr


def test_dqn_on_a_box_action_env_is_refused(capsys, tmp_path):
    assert main(["reproduce", "cartpole", "--set", "env_id=Pendulum-v1", "--no-progress", "--out", str(tmp_path)]) == 2
    assert "needs a Discrete action space" in capsys.readouterr().err


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
    assert summary["last_100_share_at_500"] == 0.0
    gif = tmp_path / "cartpole.gif"
    proc = run_cli("evaluate", str(run_dir), "--episodes", "2", "--gif", str(gif))
    assert proc.returncode == 0, proc.stderr
    scores = json.loads((run_dir / "evaluation.json").read_text())["scores"]
    assert len(scores) == 2 and all(1 <= s <= 500 for s in scores)
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")


@pytest.mark.slow
def test_compare_and_sweep_never_remove_a_seed_folder_they_did_not_make(tmp_path, capsys):
    """Issue #23.1: a seed folder without summary.json (someone's notes in it) is refused
    with its name, not deleted; --rerun is the way to replace it."""
    from keras_rl.posts.pendulum import PendulumDDPGConfig
    from keras_rl.runs.provenance import code_version
    from keras_rl.runs.reuse import check_reusable

    seed_dir = tmp_path / "seed_0"
    seed_dir.mkdir()
    (seed_dir / "NOTES.txt").write_text("mine")
    with pytest.raises(RunFolderError, match="NOTES.txt.*no summary.json.*left as it is"):
        check_reusable(seed_dir, PendulumDDPGConfig(seed=0), code_version())
    assert (seed_dir / "NOTES.txt").read_text() == "mine"
    assert check_reusable(tmp_path / "seed_1", PendulumDDPGConfig(seed=1), code_version()) == "missing"
    (tmp_path / "seed_2").mkdir()  # an empty folder holds nothing to lose
    assert check_reusable(tmp_path / "seed_2", PendulumDDPGConfig(seed=2), code_version()) == "missing"
    pytest.importorskip("torch", reason="compare needs the torch extra")
    argv = ["compare", "pendulum", "--seeds", "0", "--episodes", "2", "--runs", str(tmp_path / "runs"), "--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "R1")]) == 0
    made = tmp_path / "runs" / "pendulum" / "faithful" / "seed_0"
    (made / "summary.json").unlink()
    (made / "NOTES.txt").write_text("mine")
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "R2")]) == 2  # the reproducer exited 0 and lost NOTES.txt
    err = capsys.readouterr().err
    assert f"{made} holds files (NOTES.txt" in err and "no summary.json" in err
    assert (made / "NOTES.txt").read_text() == "mine"


def test_compare_refuses_rerun_with_reuse_only(capsys):
    from keras_rl.cli import main

    assert main(["compare", "pendulum", "--seeds", "0", "--rerun", "--reuse-only"]) == 2
    assert "--rerun and --reuse-only contradict each other" in capsys.readouterr().err


@pytest.mark.slow
def test_a_second_command_writing_the_same_run_folder_is_refused(tmp_path):
    """#23.5: two commands with one --out were not kept apart (the second's --overwrite
    cleared the first's folder under it). The second now exits 2 naming the folder, and the
    first finishes as if alone."""
    out = tmp_path / "out"
    argv = [
        *CLI,
        "reproduce",
        "pendulum",
        "--seeds",
        "4",
        "--episodes",
        "60",
        "--no-progress",
        "--set",
        "stop_at_threshold=false",
        "--set",
        "train_start=64",
        "--min-success-rate",
        "0",
        "--out",
        str(out),
    ]
    first = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    csv_path = out / "seed_4" / "episodes.csv"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and first.poll() is None and not csv_path.is_file():
        time.sleep(0.05)
    assert first.poll() is None, "the first command ended before the second could meet it"
    second = run_cli(*argv[3:], "--overwrite")
    assert first.poll() is None, "the first command ended before the second met it"
    assert second.returncode == 2, second.stderr
    assert f"{out / 'seed_4'} is being written by another keras-rl command (pid {first.pid})" in second.stderr
    _, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert len(read_episodes(csv_path)) == 60
    again = run_cli(*argv[3:], "--episodes", "2", "--overwrite")
    assert again.returncode == 0, again.stderr  # the lock went with the first command


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.write_text("garbage\n"), "is not an episodes.csv (no header with 'score')"),
        (lambda p: p.write_text(""), "is not an episodes.csv"),
        (lambda p: p.write_text(p.read_text()[: p.read_text().rindex(",-") + 2]), "line 8"),  # cut after a minus sign
        (lambda p: p.write_bytes(b"\xff\xfe\x00garbage"), "is not text"),
        (
            lambda p: p.write_text("".join(p.read_text().splitlines(keepends=True)[:4])),
            "holds 3 episodes, but its summary.json counts 7",
        ),
    ],
    ids=["garbage", "empty", "cut-mid-number", "binary", "truncated-rows"],
)
def test_aggregate_names_a_damaged_episodes_csv_and_exits_2(short_run, tmp_path, damage, message, capsys):
    """#23.6 and #23.7: a damaged episodes.csv gave a raw traceback (exit 1); a truncated one
    was accepted silently. Now exit 2, naming the file, and nothing is written."""
    import shutil

    parent = tmp_path / "set"
    shutil.copytree(short_run.parent, parent)
    csv_path = parent / "seed_3" / "episodes.csv"
    damage(csv_path)
    before = {p.name: p.read_bytes() for p in parent.iterdir() if p.is_file()}
    assert main(["aggregate", str(parent)]) == 2
    err = capsys.readouterr().err
    assert str(csv_path) in err and message in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in parent.iterdir() if p.is_file()} == before


def test_aggregate_redraws_curves_against_env_steps(short_run, tmp_path, capsys):
    import shutil

    parent = tmp_path / "set"
    shutil.copytree(short_run.parent, parent)
    (parent / "seed_3" / "curve.png").unlink()
    assert main(["aggregate", str(parent), "--x-axis", "steps"]) == 0
    assert (parent / "seed_3" / "curve.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(SystemExit):
        main(["aggregate", str(parent), "--x-axis", "time"])


@pytest.mark.slow
def test_reproduce_reruns_a_recorded_config_and_dry_run_trains_nothing(tmp_path):
    """#23.13: `--config RUN/config.json` reruns a recorded run (here a committed seed, its
    first 20 episodes bit for bit), and `--dry-run` prints the config and the folders only."""
    import csv

    committed = Path(__file__).resolve().parent.parent / "results" / "cartpole" / "faithful" / "seed_0"
    dry = run_cli(
        "reproduce", "cartpole", "--config", str(committed / "config.json"), "--dry-run", "--out", str(tmp_path / "dry")
    )
    assert dry.returncode == 0, dry.stderr
    assert '"q_lr":' in dry.stdout and f"seed 0: {tmp_path / 'dry' / 'seed_0'} (new)" in dry.stdout
    assert not (tmp_path / "dry").exists()
    proc = run_cli(
        "reproduce",
        "cartpole",
        "--config",
        str(committed),
        "--episodes",
        "20",
        "--no-progress",
        "--min-success-rate",
        "0",
        "--out",
        str(tmp_path / "again"),
    )
    assert proc.returncode == 0, proc.stderr

    def rows(path):
        with open(path, newline="") as fh:
            return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]

    assert rows(tmp_path / "again" / "seed_0" / "episodes.csv") == rows(committed / "episodes.csv")[:20]
    wrong = run_cli("reproduce", "pendulum", "--config", str(committed), "--dry-run")
    assert wrong.returncode == 2 and "is a config of 'cartpole', not of pendulum" in wrong.stderr
