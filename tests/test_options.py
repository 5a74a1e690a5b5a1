"""The options every training command shares (``runs/options.py``) and the one ``FIELD=VALUE``
parser (``ExperimentConfig.parse_assignments``): declared once, checked once, named once."""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

import pytest

from keras_rl.cli import build_parser, main
from keras_rl.errors import ConfigError
from keras_rl.posts.pendulum import PendulumDDPGConfig as PendulumConfig
from keras_rl.runs.options import OPTIONS, RunOptions, run_options_parser
from keras_rl.runs.sweep import parse_grid

REPO = Path(__file__).resolve().parent.parent
RUN_COMMANDS = ("reproduce", "compare", "sweep", "check")


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _help(parser: argparse.ArgumentParser, dest: str) -> str | None:
    return next((a.help for a in parser._actions if a.dest == dest), None)


@pytest.mark.parametrize("dest", ["workers", "address", "seed_batch", "episodes", "overrides", "no_progress"])
def test_each_shared_option_has_one_help_text_across_the_commands(dest):
    parsers = _subparsers()
    texts = {name: _help(parsers[name], dest) for name in RUN_COMMANDS}
    given = {name: t for name, t in texts.items() if t is not None}
    assert len(given) >= 2, f"--{dest} should be shared by at least two commands: {texts}"
    if dest == "workers":  # check's default is 2; the rest of the text is the same
        given = {name: t.replace("default 2", "default 1: in this process, no Ray") for name, t in given.items()}
    assert len(set(given.values())) == 1, given


def test_run_options_are_checked_with_the_flag_named(capsys):
    parent = run_options_parser()
    with pytest.raises(ConfigError, match="--episodes must be positive"):
        RunOptions.from_args(parent.parse_args(["--episodes", "0"]))
    with pytest.raises(ConfigError, match="--seed-batch must be at least 1 or auto"):
        RunOptions.from_args(parent.parse_args(["--seed-batch", "0"]))
    assert RunOptions.from_args(parent.parse_args(["--seed-batch", "auto"])).seed_batch == "auto"
    with pytest.raises(SystemExit) as exit_:  # argparse: usage and exit 2
        parent.parse_args(["--seed-batch", "many"])
    assert exit_.value.code == 2 and "expected a whole number or auto, got 'many'" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="--workers must be at least 1"):
        RunOptions.from_args(parent.parse_args(["--workers", "0"]))
    options = RunOptions.from_args(parent.parse_args(["--workers", "1000", "--set", "tau=0.1", "--no-progress"]))
    assert options.workers == os.cpu_count() and "more than this machine's" in capsys.readouterr().err
    assert options.overrides == ("tau=0.1",) and options.progress is False and options.config_changes() == {}
    with pytest.raises(ValueError, match="unknown run options"):
        run_options_parser("wrokers")
    assert set(OPTIONS) == {"workers", "address", "seed_batch", "episodes", "set", "no_progress", "engine"}
    with pytest.raises(ConfigError, match="--engine compiled runs one seed per program"):
        RunOptions.from_args(parent.parse_args(["--engine", "compiled", "--seed-batch", "2"]))
    assert RunOptions.from_args(parent.parse_args(["--engine", "compiled"])).engine == "compiled"
    with pytest.raises(SystemExit):  # argparse names the choices
        parent.parse_args(["--engine", "jax"])
    assert "invalid choice: 'jax'" in capsys.readouterr().err


def test_the_address_falls_back_to_ray_address(monkeypatch):
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")
    options = RunOptions.from_args(run_options_parser().parse_args([]))
    assert options.address == "127.0.0.1:1"
    monkeypatch.delenv("RAY_ADDRESS")
    assert RunOptions.from_args(run_options_parser().parse_args([])).address is None


def test_one_parser_reads_set_and_grid_by_the_fields_type():
    assert PendulumConfig.parse_assignments(["tau=5e-3", "broadcast-target=off"]) == {
        "tau": 0.005,
        "broadcast_target": False,
    }
    assert PendulumConfig.parse_assignments(["tau=0.1,0.2"], flag="--grid", many=True) == {"tau": [0.1, 0.2]}
    for bad, message in [
        (["tau"], "--set expects FIELD=VALUE"),
        (["tau="], "has an empty value"),
        (["tau=0.1", "tau=0.2"], "names tau twice"),
        (["nope=1"], "unknown pendulum config field"),
        (["seed=3"], "not a config field; use --seeds"),
        (["tau=fast"], "tau"),
    ]:
        with pytest.raises(ConfigError, match=message):
            PendulumConfig.parse_assignments(bad)
    assert [p.name for p in parse_grid(PendulumConfig, ["tau=5e-3,0.01"])] == ["tau=0.005", "tau=0.01"]


def test_set_folders_are_named_from_parsed_values(capsys):
    folders = []
    for text in ("tau=5e-3", "tau=0.005", "tau=.0050"):
        assert main(["reproduce", "pendulum", "--set", text, "--dry-run"]) == 0
        folders.append(capsys.readouterr().out.strip().splitlines()[-1])
    assert len(set(folders)) == 1 and "faithful-set-tau=0.005/seed_0" in folders[0]


def test_resume_keeps_a_completed_run_by_its_summary_status(tmp_path, capsys):
    out = tmp_path / "runs"
    shutil.copytree(REPO / "results" / "pendulum" / "faithful" / "seed_0", out / "seed_0")
    assert main(["reproduce", "pendulum", "--seeds", "0-1", "--out", str(out), "--resume", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2].endswith("(completed, kept)") and lines[-1].endswith("seed_1 (new)")
