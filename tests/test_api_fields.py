"""A library that speaks in fields (issue 71, item 3): ``keras_rl.api`` given bad input for every
argument raises a ``KerasRLError`` whose message names the argument as Python passes it
(``workers``, ``engine=compiled``, ``overwrite=True``), never as a command-line flag; the
commands word the same messages as flags (``errors.as_flags``, set by ``cli.main``); and only
``cli.py`` and ``commands/`` import argparse. Nothing here trains."""

from __future__ import annotations

import argparse
import ast
import re
from pathlib import Path

import pytest

from keras_rl import api, study
from keras_rl.cli import build_parser, main
from keras_rl.errors import KerasRLError, argument, as_flags

ROOT = Path(__file__).resolve().parents[1]


def _flags() -> set[str]:
    """Every long option of every ``keras-rl`` command, ``--help`` and ``--version`` aside."""
    flags: set[str] = set()
    parsers = [build_parser()]
    while parsers:
        parser = parsers.pop()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
            flags.update(s for s in action.option_strings if s.startswith("--"))
    return flags - {"--help", "--version"}


FLAGS = _flags()


def named_flags(message: str) -> list[str]:
    return [token for token in re.findall(r"--[a-z][a-z-]*", message) if token in FLAGS]


def test_the_flag_finder_finds_a_flag():
    """The check below can fail: a message worded as the command words it is caught."""
    assert {"--workers", "--seed-batch", "--overwrite", "--against", "--reuse-only"} <= FLAGS
    with as_flags():
        worded = f"{argument('seed_batch', 4)} and {argument('overwrite', True)}"
    assert worded == "--seed-batch 4 and --overwrite" and named_flags(worded) == ["--seed-batch", "--overwrite"]
    assert f"{argument('seed_batch', 4)} and {argument('overwrite', True)}" == "seed_batch=4 and overwrite=True"


@pytest.fixture
def planned(monkeypatch):
    """``study.run`` replaced: a call that passed every check would train nothing."""
    seen: dict = {}

    def fake_run(s, planned, after_job=None):
        seen["study"] = s
        return study.StudyResult(api.RunSet(s.out), [], False, [], [])

    monkeypatch.setattr(study, "run", fake_run)
    return seen


def _a_run_folder(where: Path) -> Path:
    """A seed folder as a run leaves one (its config), for an ``out`` inside it."""
    seed = where / "seed_0"
    seed.mkdir(parents=True)
    (seed / "config.json").write_text('{"experiment": "pendulum"}')
    return seed


PACKED = ROOT / "results" / "pendulum" / "faithful"  # a committed, packed set: never written to

REPRODUCE = [  # (argument, its bad value as keyword arguments, a fragment the message holds)
    ("config", {"config": 3}, "config must be"),
    ("seeds", {"seeds": "0-3"}, "seeds must be"),
    ("seeds", {"seeds": [1, 1]}, "seed 1 is named twice"),
    ("out", {"out": None}, "out must be"),
    ("out", {"out": ROOT / "README.md"}, "is a file"),
    ("out", {"out": "RUN/inner"}, "is inside the run folder"),
    ("out", {"out": PACKED, "seeds": [0]}, "out for a folder of your own"),
    ("variant", {"variant": "nosuch"}, "nosuch"),
    ("framework", {"framework": "jax"}, "jax"),
    ("overrides", {"overrides": 5}, "overrides must be"),
    ("overrides", {"overrides": {"seed": 1}}, "pass seeds="),
    ("overrides", {"overrides": {"tau": -1.0}}, "tau must be"),
    ("episodes", {"episodes": 2.5}, "episodes must be a whole number"),
    ("episodes", {"episodes": 0}, "episodes must be positive"),
    ("engine", {"engine": "warp"}, "unknown engine"),
    ("engine", {"engine": "compiled", "framework": "torch"}, "engine=compiled: it runs the Keras learner"),
    ("engine", {"engine": "vectorised"}, "engine=vectorised"),
    ("workers", {"workers": "two"}, "workers must be a whole number"),
    ("workers", {"workers": 0}, "workers must be at least 1"),
    ("resume", {"resume": "yes"}, "resume must be True or False"),
    ("resume", {"resume": True, "overwrite": True}, "overwrite and resume contradict"),
    ("overwrite", {"overwrite": 1}, "overwrite must be True or False"),
    ("progress", {"progress": "no"}, "progress must be True or False"),
    ("min_success_rate", {"min_success_rate": 2}, "min_success_rate must be in [0, 1]"),
]

COMPARE = [
    ("experiment", {"experiment": 5}, "named by a string"),
    ("seeds", {"seeds": [0.5]}, "seeds must be whole numbers"),
    ("runs", {"runs": None}, "runs must be"),
    ("out", {"out": None}, "out must be"),
    ("matched_init", {"matched_init": "yes"}, "matched_init must be True or False"),
    ("reuse_only", {"reuse_only": 1}, "reuse_only must be True or False"),
    ("reuse_only", {"reuse_only": True, "runs": "EMPTY"}, "run without reuse_only to make them"),
    ("workers", {"workers": 0}, "workers must be at least 1"),
]

CHECK = [
    ("experiments", {"experiments": "nosuch"}, "nosuch"),
    ("experiments", {"experiments": [5]}, "named by a string"),
    ("out", {"out": None}, "out must be"),
    ("out", {"out": ROOT / "README.md"}, "README.md"),
    ("tier", {"tier": "loud"}, "unknown tier"),
    ("workers", {"workers": "x"}, "workers must be a whole number"),
    ("against", {"against": "EMPTY"}, "against names the folder"),
    ("framework", {"framework": "torch", "experiments": "pendulum"}, "framework=torch"),
]


def _call(function, kwargs: dict, tmp_path: Path) -> str:
    """``function``'s message for ``kwargs`` (placeholders made real), asserting that it raised a
    KerasRLError and that nothing appeared in ``tmp_path`` but the placeholders' own files."""
    args = {}
    for name, value in kwargs.items():
        if value == "RUN/inner":
            value = _a_run_folder(tmp_path / "set") / "inner"
        elif value == "EMPTY":
            value = tmp_path / "empty"
            value.mkdir(exist_ok=True)
        args[name] = value
    made = set(tmp_path.rglob("*"))
    with pytest.raises(KerasRLError) as caught:
        function(**args)
    assert set(tmp_path.rglob("*")) == made, "a refused call wrote something"
    return str(caught.value)


@pytest.mark.parametrize(
    "argument_name, kwargs, fragment", REPRODUCE, ids=[f"{a}-{i}" for i, (a, *_) in enumerate(REPRODUCE)]
)
def test_reproduce_names_each_bad_argument_without_a_flag(argument_name, kwargs, fragment, tmp_path, planned):
    given = {"config": "pendulum", "seeds": [0], "out": tmp_path / "o", **kwargs}
    message = _call(lambda **a: api.reproduce(a.pop("config"), **a), given, tmp_path)
    assert fragment in message and not named_flags(message), message
    assert "study" not in planned


@pytest.mark.parametrize(
    "argument_name, kwargs, fragment", COMPARE, ids=[f"{a}-{i}" for i, (a, *_) in enumerate(COMPARE)]
)
def test_compare_names_each_bad_argument_without_a_flag(argument_name, kwargs, fragment, tmp_path):
    given = {"experiment": "pendulum", "seeds": [0], "out": tmp_path / "c", **kwargs}
    message = _call(lambda **a: api.compare(a.pop("experiment"), **a), given, tmp_path)
    assert fragment in message and not named_flags(message), message


@pytest.mark.parametrize("argument_name, kwargs, fragment", CHECK, ids=[f"{a}-{i}" for i, (a, *_) in enumerate(CHECK)])
def test_check_names_each_bad_argument_without_a_flag(argument_name, kwargs, fragment, tmp_path):
    given = {"experiments": ["pendulum"], "out": tmp_path / "k", **kwargs}
    message = _call(lambda **a: api.check(a.pop("experiments"), **a), given, tmp_path)
    assert fragment in message and not named_flags(message), message


def test_load_names_its_bad_argument_without_a_flag(tmp_path):
    for folder in (5, tmp_path / "none"):
        message = _call(api.load, {"folder": folder}, tmp_path)
        assert not named_flags(message), message


def test_every_argument_of_the_api_is_driven():
    """Each public function's every parameter has a bad input above."""
    import inspect

    driven = {
        api.reproduce: {a for a, *_ in REPRODUCE},
        api.compare: {a for a, *_ in COMPARE},
        api.check: {a for a, *_ in CHECK},
    }
    for function, names in driven.items():
        assert set(inspect.signature(function).parameters) == names, function.__name__


def test_a_warning_names_the_argument_too(tmp_path, planned, capsys, monkeypatch):
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    api.reproduce("pendulum", seeds=[0], out=tmp_path / "o", workers=3)
    warning = capsys.readouterr().err
    assert "workers=3 is more than this machine's 2 cores" in warning and not named_flags(warning)


def test_the_command_words_the_same_message_as_flags(tmp_path, capsys):
    code = main(["reproduce", "pendulum", "--framework", "torch", "--engine", "compiled", "--out", str(tmp_path / "o")])
    said = capsys.readouterr().err
    assert code == 2 and "--engine compiled: it runs the Keras learner" in said, said
    assert "--engine gymnasium" in said and not (tmp_path / "o").exists()
    code = main(["reproduce", "pendulum", "--resume", "--overwrite", "--out", str(tmp_path / "o")])
    assert code == 2 and "--overwrite and --resume contradict each other" in capsys.readouterr().err


def test_only_the_commands_import_argparse():
    importers = []
    for path in sorted((ROOT / "keras_rl").rglob("*.py")):
        relative = path.relative_to(ROOT / "keras_rl")
        if relative.parts[0] == "commands" or relative == Path("cli.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if any(n.split(".")[0] == "argparse" for n in names):
                importers.append(str(relative))
    assert importers == []
