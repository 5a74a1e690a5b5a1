"""The options every training command shares (``dispatch/options.py``, its flags in
``commands/flags.py``) and the one ``FIELD=VALUE`` parser (``ExperimentConfig.parse_assignments``):
declared once, checked once, named once."""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

import pytest
from committed import committed_seed

from keras_rl.cli import build_parser, main, parse_args
from keras_rl.commands.flags import COMMAND_DEFAULTS, FLAGS, RUN_FLAGS, help_for, options_from_args, shared_flags
from keras_rl.dispatch.sweep import parse_grid
from keras_rl.errors import ConfigError, as_flags
from keras_rl.posts.pendulum import PendulumDDPGConfig as PendulumConfig

REPO = Path(__file__).resolve().parent.parent


def _subparsers(parser: argparse.ArgumentParser | None = None, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    """Every command's parser by its name, nested ones too (``calibrate rules``)."""
    parser = parser or build_parser()
    out: dict[str, argparse.ArgumentParser] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[prefix + name] = sub
                out.update(_subparsers(sub, prefix + name + " "))
    return out


def _flags() -> dict[str, dict[str, argparse.Action]]:
    """Every ``--flag`` of every command, the maintainers' too: flag -> command -> its action."""
    from maintainers.cli import build_parser as maintainers_parser

    out: dict[str, dict[str, argparse.Action]] = {}
    for name, parser in {**_subparsers(), **_subparsers(maintainers_parser())}.items():
        for action in parser._actions:
            for spelling in action.option_strings:
                if spelling.startswith("--") and spelling != "--help":
                    out.setdefault(spelling, {})[name] = action
    return out


def test_each_shared_flag_has_one_default_everywhere_and_each_commands_help_speaks_of_it_alone():
    """Issue 33: a flag two commands take is one flag (``--alpha`` defaulted to None in one and
    0.01 in the other, ``--workers`` to 1 and 2, ``--seeds`` had three defaults). Its help text is
    the command's own: ``reproduce --help`` says nothing of what ``--out`` means to ``check``."""
    import re

    shared = {spelling: uses for spelling, uses in _flags().items() if len(uses) > 1}
    assert {"--seeds", "--out", "--workers", "--alpha", "--tier", "--against", "--episodes", "--write"} <= set(shared)
    assert {"calibrate rules", "tables findings", "manifest"}.isdisjoint(_subparsers())  # the maintainers' own
    commands = ("reproduce", "compare", "sweep", "check", "bisect", "evaluate", "aggregate")
    for spelling, uses in shared.items():
        assert spelling in FLAGS, f"{spelling} ({', '.join(uses)}) is not declared in commands/flags.FLAGS"
        for what in ("default", "type", "dest", "choices"):
            values = {name: getattr(action, what) for name, action in uses.items()}
            assert len({repr(v) for v in values.values()}) == 1, f"{spelling}'s {what} differs: {values}"
        for name, action in uses.items():
            command = name.split()[0]
            assert action.help == help_for(
                name.split()[-1] if command in ("calibrate", "tables") else command, spelling
            )
            others = [c for c in commands if c != command and re.search(rf"\b{c}\b", action.help)]
            assert not others, f"{name} {spelling}'s help speaks of {others}: {action.help}"


def test_a_command_reads_a_shared_none_as_its_own_default_and_the_help_says_so():
    for command, defaults in COMMAND_DEFAULTS.items():
        args = parse_args(
            [
                command,
                *(["x"] if command in ("compare", "sweep", "evaluate") else []),
                *(["a", "b"] if command == "bisect" else []),
            ]
        )
        for dest, value in defaults.items():
            assert getattr(args, dest) == value
            assert str(value) in help_for(command, "--" + dest.replace("_", "-")), (command, dest)
    given = parse_args(["compare", "x", "--seeds", "3", "--out", "o"])
    assert (given.seeds, given.out, given.variant) == ("3", Path("o"), "faithful")  # what the user gave stays


def test_sweep_without_out_exits_2_naming_it(capsys):
    assert main(["sweep", "pendulum", "--grid", "tau=0.1,0.2"]) == 2
    assert "sweep needs --out FOLDER" in capsys.readouterr().err


def test_run_options_are_checked_with_the_flag_named(capsys):
    """The library names the argument; a command (``as_flags``, as ``cli.main`` sets) its flag."""
    parent = shared_flags("reproduce", *RUN_FLAGS)
    with pytest.raises(ConfigError, match="^episodes must be positive"):
        options_from_args(parent.parse_args(["--episodes", "0"]))
    with as_flags(), pytest.raises(ConfigError, match="--episodes must be positive"):
        options_from_args(parent.parse_args(["--episodes", "0"]))
    with as_flags(), pytest.raises(ConfigError, match="--seed-batch must be at least 1 or auto"):
        options_from_args(parent.parse_args(["--seed-batch", "0"]))
    assert options_from_args(parent.parse_args(["--seed-batch", "auto"])).seed_batch == "auto"
    with pytest.raises(SystemExit) as exit_:  # argparse: usage and exit 2
        parent.parse_args(["--seed-batch", "many"])
    assert exit_.value.code == 2 and "expected a whole number or auto, got 'many'" in capsys.readouterr().err
    with as_flags(), pytest.raises(ConfigError, match="--workers must be at least 1"):
        options_from_args(parent.parse_args(["--workers", "0"]))
    options = options_from_args(parent.parse_args(["--workers", "1000", "--set", "tau=0.1", "--no-progress"]))
    assert options.workers == os.cpu_count() and "more than this machine's" in capsys.readouterr().err
    assert options.progress is False and options.config_changes() == {}  # --set is the command's to parse
    with pytest.raises(ValueError, match="unknown shared flags"):
        shared_flags("reproduce", "--wrokers")
    with as_flags(), pytest.raises(ConfigError, match="--engine compiled runs one seed per program; --seed-batch"):
        options_from_args(parent.parse_args(["--engine", "compiled", "--seed-batch", "2"]))
    assert options_from_args(parent.parse_args(["--engine", "compiled"])).engine == "compiled"
    with pytest.raises(SystemExit):  # argparse names the choices
        parent.parse_args(["--engine", "jax"])
    assert "invalid choice: 'jax'" in capsys.readouterr().err


def test_the_address_falls_back_to_ray_address(monkeypatch):
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")
    options = options_from_args(shared_flags("reproduce", *RUN_FLAGS).parse_args([]))
    assert options.address == "127.0.0.1:1"
    monkeypatch.delenv("RAY_ADDRESS")
    assert options_from_args(shared_flags("reproduce", *RUN_FLAGS).parse_args([])).address is None


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


def test_resume_would_keep_a_completed_run_by_its_summary_status_and_refuses_another_codes(tmp_path, capsys):
    """A completed seed is one ``--resume`` keeps (by its summary's status), so it is checked as
    kept: a committed run that an older code version made is refused, by the dry run as by the
    run (issue 54 item 18), with nothing written for the new seed."""
    out = tmp_path / "runs"
    shutil.copytree(committed_seed("pendulum/faithful/seed_0"), out / "seed_0")
    assert main(["reproduce", "pendulum", "--seeds", "0-1", "--out", str(out), "--resume", "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "--resume keeps completed seeds, but" in err and "was made by code version" in err
    assert not (out / "seed_1").exists()
