"""The Python API on the typed library (``keras_rl/api.py`` over ``keras_rl/study.py``): typed
configs in, typed results out, bad input refused with a ConfigError that names it, no argv."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from keras_rl import api, study
from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.posts.pendulum import PendulumDDPGConfig

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def planned(monkeypatch):
    """``api.reproduce`` up to its plan: the Study it would run, nothing trained."""
    seen = {}

    def fake_run(s, planned, after_job=None):
        seen["study"], seen["plan"] = s, planned
        return study.StudyResult(api.RunSet(s.out), [], False, [], [])

    monkeypatch.setattr(study, "run", fake_run)
    return seen


def test_a_typed_config_travels_as_itself(planned, tmp_path):
    config = PendulumDDPGConfig(tau=0.005)
    api.reproduce(config, seeds=np.arange(2), out=tmp_path / "o", overrides={"actor_hidden_units": (32, 32)})
    made = planned["study"]
    assert made.config == config.replace(actor_hidden_units=(32, 32)) and made.seeds == (0, 1)
    assert planned["plan"].modes == ["new", "new"] and made.out == tmp_path / "o"
    assert planned["plan"].engine == "compiled"  # auto, as the command: certified for post 000
    api.reproduce("pendulum", seeds=np.int64(3), out=tmp_path / "p", variant="fixed", episodes=4)
    assert planned["study"].config == PendulumDDPGConfig.for_variant("fixed", episodes=4)
    assert planned["study"].seeds == (3,)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"seeds": [0.0, 1.5]}, "seeds must be whole numbers, got 0.0"),
        ({"seeds": [True]}, "seeds must be whole numbers, got True"),
        ({"seeds": "0-3"}, "seeds must be a whole number or several"),
        ({"seeds": [1, 1]}, "seed 1 is named twice"),
        ({"seeds": [2**32]}, "seeds must be in [0, 2**32)"),
        ({"workers": "two"}, "workers must be a whole number, got 'two'"),
        ({"episodes": 2.5}, "episodes must be a whole number, got 2.5"),
        ({"out": None}, "out must be a folder's path, got None"),
        ({"min_success_rate": 2}, "min_success_rate must be in [0, 1]"),
        ({"overrides": {"tau": -1.0}}, "tau must be in (0, 1]"),
        ({"engine": "warp"}, "unknown engine 'warp'"),
    ],
)
def test_bad_input_is_a_config_error_that_names_it_and_writes_nothing(kwargs, message, tmp_path, planned):
    args = {"seeds": [0], "out": tmp_path / "o", **kwargs}
    with pytest.raises(ConfigError) as caught:
        api.reproduce("pendulum", **args)
    assert message in str(caught.value)
    assert "study" not in planned and not (tmp_path / "o").exists()


def test_load_names_a_path_that_holds_no_run_set(tmp_path):
    for where in (tmp_path / "nonexistent", ROOT / "README.md", tmp_path):
        with pytest.raises(RunFolderError, match=str(where)):
            api.load(where)
    assert api.load(ROOT / "results" / "pendulum" / "faithful").seeds == list(range(30))  # packed


def test_check_takes_one_name_or_several_and_names_an_unknown_one_whole(tmp_path):
    with pytest.raises(ConfigError, match="unknown experiment 'nosuch'"):
        api.check("nosuch", out=tmp_path)
    with pytest.raises(ConfigError, match="unknown tier"):
        api.check(["pendulum"], out=tmp_path, tier="loud")


def test_the_command_and_the_api_share_one_default_success_rate_and_no_argv_is_built():
    import inspect

    from keras_rl.cli import parse_args

    assert (
        inspect.signature(api.reproduce).parameters["min_success_rate"].default
        == parse_args(["reproduce", "pendulum"]).min_success_rate
    )
    for module in ("api.py", "study.py"):
        tree = ast.parse((ROOT / "keras_rl" / module).read_text())
        names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | {
            n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
        }
        imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
        assert not {"parse_args", "build_parser", "argv", "parse_assignments", "with_text_overrides"} & (
            names | imported
        ), module  # nor any text of a --set: typed values travel as themselves
        if module == "api.py":  # not one flag of a command line
            strings = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]
            assert not [s for s in strings if s.startswith("--")], module
