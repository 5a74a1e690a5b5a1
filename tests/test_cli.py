"""The command line: seed lists, bad input named with exit 2 (before TensorFlow loads where it can),
help texts, --version, and what the end of a run tells the user."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from clitools import run_cli
from committed import committed_seed

from keras_rl.cli import build_parser, main, parse_seeds


@pytest.mark.parametrize(
    "field, flag",
    [
        ("variant=fixed", "--variant"),
        ("seed=7", "--seeds"),
        ("framework=torch", "--framework"),
        ("matched_init=true", "--matched-init"),
    ],
)
def test_set_of_a_run_field_is_refused_and_points_to_the_flag(field, flag, capsys, tmp_path):
    assert main(["reproduce", "pendulum", "--set", field, "--out", str(tmp_path)]) == 2
    assert f"use {flag}" in capsys.readouterr().err


BEFORE_TF = [
    (["reproduce", "pendulum", "--seeds", "4294967296"], "below 2**32"),
    (["reproduce", "pendulum", "--seeds", "0-100000"], "more than 10000 seeds"),
    (["reproduce", "pendulum", "--set", "actor_hidden_units=0"], "positive layer widths"),
    (["reproduce", "pendulum", "--set", "batch_size=1500"], "larger than train_start"),
    (["reproduce", "pendulum", "--set", "buffer_size=500"], "would never train"),
    (["reproduce", "cartpole", "--set", "buffer_size=100"], "would never train"),
    (["reproduce", "mountaincar", "--set", "batch_size=200"], "train_down_to + 1"),
    (["reproduce", "mountaincar", "--set", "actor_input_noise=2"], "actor_input_noise must be at most 1"),
    (["reproduce", "pendulum", "--out", "/proc/version"], "is a file, not a folder"),
    (["reproduce", "pendulum", "--out", "/proc/no-such-dir/out"], "not a writable folder"),
    (["reproduce", "pendulum", "--set", "hidden_units=32"], "was renamed; use actor_hidden_units"),
    (["evaluate", "results/x", "--seed", "-1"], "--seed must be in [0, 2**32)"),
    (["evaluate", "results/x", "--gif", "/tmp"], "is a folder; name a file"),
    (["evaluate", "results/x", "--gif", "/proc/no-such-dir/a.gif"], "not a writable folder"),
    (["compare", "pendulum", "--workers", "0"], "--workers must be at least 1"),
]


@pytest.mark.parametrize("argv, message", BEFORE_TF, ids=[" ".join(a[:3]) + " " + m for a, m in BEFORE_TF])
def test_bad_input_exits_2_before_tensorflow_is_imported(argv, message):
    code = (
        "import sys; from keras_rl.cli import main; rc = main(sys.argv[1:]); "
        "sys.exit(rc + 10 if 'tensorflow' in sys.modules else rc)"
    )
    proc = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)  # 12: right error, but TensorFlow was loaded
    assert message in proc.stderr


def test_empty_out_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "pendulum", "--out", ""])
    assert exc.value.code == 2 and "--out: is empty" in capsys.readouterr().err


def test_the_end_of_a_run_says_where_pass_or_fail_and_why_exit_1(tiny):
    out, proc = tiny
    # a solo run that played its whole budget keeps its final checkpoint, to be extended (--resume --episodes N)
    files = "checkpoint.pkl, config.json, curve.png, episodes.csv, q_network.weights.h5, summary.json"
    assert f"{out / 'seed_1'}/: {files}" in proc.stdout
    assert "FAIL (metric >= 475 within 2 episodes: not reached" in proc.stdout
    assert "constantly achieves 500 steps" in proc.stdout  # the post's own claim beside it
    assert "criterion not met: 0/1 seeds succeeded, need 100%" in proc.stderr


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("keras-rl ")


def test_every_option_has_help_text():
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = [
        f"{name} {action.option_strings or action.dest}"
        for name, sub in subparsers.choices.items()
        for action in sub._actions
        if action.dest != "help" and not action.help
    ]
    assert missing == []
    assert "faithful-intended" in subparsers.choices["reproduce"].format_help()


def test_parse_seeds():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("5,1,2-3") == [1, 2, 3, 5]
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


def test_torch_framework_without_torch_is_a_clear_error(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "torch", None)  # makes `import torch` fail
    assert main(["reproduce", "cartpole", "--framework", "torch", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "the torch framework needs PyTorch" in err


def test_the_torch_advice_works_for_an_installed_package_first():
    """Issue 54 item 21: from an installed wheel there is no checkout to ``pip install -e``; the
    advice names the package and its extra as setup.cfg declares them, the checkout's second."""
    import configparser

    from keras_rl.torch import NO_TORCH

    setup = configparser.ConfigParser()
    setup.read(Path(__file__).resolve().parents[1] / "setup.cfg")
    assert "torch==2.13.0" in setup["options.extras_require"]["torch"]
    installed = f"pip install '{setup['metadata']['name']}[torch]'"
    assert installed in NO_TORCH and NO_TORCH.index(installed) < NO_TORCH.index("pip install -e")


def test_framework_the_experiment_does_not_have(capsys, tmp_path):
    assert main(["reproduce", "pendulum", "--framework", "jax", "--out", str(tmp_path)]) == 2
    assert "pendulum has no 'jax' version; choose one of keras, torch" in capsys.readouterr().err
    assert main(["reproduce", "pendulum", "--matched-init", "--out", str(tmp_path)]) == 2
    assert "needs framework 'torch', not 'keras'" in capsys.readouterr().err


def test_dqn_on_a_box_action_env_is_refused(capsys, tmp_path):
    assert main(["reproduce", "cartpole", "--set", "env_id=Pendulum-v1", "--no-progress", "--out", str(tmp_path)]) == 2
    assert "needs a Discrete action space" in capsys.readouterr().err


def test_compare_refuses_rerun_with_reuse_only(capsys):
    from keras_rl.cli import main

    assert main(["compare", "pendulum", "--seeds", "0", "--rerun", "--reuse-only"]) == 2
    assert "--rerun and --reuse-only contradict each other" in capsys.readouterr().err


@pytest.mark.slow
def test_reproduce_reruns_a_recorded_config_and_dry_run_trains_nothing(tmp_path):
    """#23.13: `--config RUN/config.json` reruns a recorded run (here a committed seed, its
    first 20 episodes bit for bit), and `--dry-run` prints the config and the folders only."""
    import csv

    committed = committed_seed("cartpole/faithful/seed_0")
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

    from maintainers.replay import why_not_bit_exact

    again = rows(tmp_path / "again" / "seed_0" / "episodes.csv")
    if why_not_bit_exact(json.loads((committed / "summary.json").read_text())["provenance"]) is None:
        assert again == rows(committed / "episodes.csv")[:20]
    else:  # a machine measured to round differently: the counts agree, and the episodes' lengths
        key = ("episode", "steps", "total_steps", "score")
        assert [[r[k] for k in key] for r in again[:5]] == [
            [r[k] for k in key] for r in rows(committed / "episodes.csv")[:5]
        ]
    wrong = run_cli("reproduce", "pendulum", "--config", str(committed), "--dry-run")
    assert wrong.returncode == 2 and "is a config of 'cartpole', not of pendulum" in wrong.stderr


def test_seeds_that_leave_no_summary_fail_the_command_whatever_min_success_rate_says(tmp_path, monkeypatch, capsys):
    """Under Ray, a seed whose worker raised before writing summary.json (Keras refusing a layer
    argument, say) printed its error and left no verdict; reproduce exited 0 with
    --min-success-rate 0 (found running a held-out mutant of issue #21)."""
    import keras_rl.dispatch.backends as backends

    class Silent:  # a backend whose seeds all die before their first file
        def run(self, jobs, progress, after_job=None):
            return False

    monkeypatch.setattr(backends, "backend_for", lambda *a, **k: Silent())
    argv = ["reproduce", "cartpole", "--seeds", "0-1", "--episodes", "2", "--min-success-rate", "0", "--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 1
    assert "seeds 0, 1 left no summary.json" in capsys.readouterr().err


def test_tensorflows_start_up_lines_are_quiet(tmp_path):
    import subprocess
    import sys

    code = "import keras_rl, tensorflow as tf; print(tf.constant(2.0).numpy())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == "2.0"
    assert "absl::InitializeLog" not in done.stderr and "cuda drivers" not in done.stderr, done.stderr


def test_list_with_an_experiment_shows_every_config_field_with_its_type_default_range_and_the_post(capsys):
    """What ``--set FIELD=VALUE`` takes, from ``keras-rl list pendulum``: no field is hidden."""
    import dataclasses

    from keras_rl.posts.pendulum import PendulumDDPGConfig

    assert main(["list", "pendulum"]) == 0
    out = capsys.readouterr().out
    for f in dataclasses.fields(PendulumDDPGConfig):
        assert f"\n  {f.name}: " in out, f.name
    assert "  tau: float = 0.001, (0, 1]\n      §2.3.1: ``self.tau = 0.001``" in out
    assert "  actor_hidden_units: tuple[int, ...] = 64,64, widths >= 1" in out
    assert main(["list", "nosuch"]) == 2


def test_a_seed_judged_at_the_end_says_so_beside_where_it_first_met_the_threshold():
    """Post 001's success is its last episode's metric: "FAIL (... reached at episode 10)" read as a
    contradiction; the line says what decided it and where the threshold was first met."""
    from types import SimpleNamespace

    from keras_rl.commands.reproduce import _reached_text

    failed = SimpleNamespace(reached_at_episode=10, final_metric=3.2)
    assert _reached_text(failed, True) == "judged on the last episode's metric, 3.2; first met at episode 10"
    assert _reached_text(SimpleNamespace(reached_at_episode=None, final_metric=None), True).endswith("never met")
    assert _reached_text(failed, False) == "reached at episode 10"
