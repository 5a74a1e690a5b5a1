"""Issue 54's input items on the library side (items 5-8, 10 and 17): what a notebook passes
to ``keras_rl/api.py`` arrives as the fields' own types or is refused by name before anything
is written, and the command line refuses the same values the same way. Nothing here trains:
``study.run`` is replaced where a call would reach it."""

from __future__ import annotations

import types

import numpy as np
import pytest

from keras_rl import api, study
from keras_rl.cli import main
from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.posts.cartpole import CartPoleDQNConfig
from keras_rl.posts.pendulum import PendulumDDPGConfig


@pytest.fixture
def planned(monkeypatch):
    """``api.reproduce`` up to its plan: the Study it would run, nothing trained; each seed's
    summary is ``planned["summaries"]`` (none by default)."""
    seen: dict = {"summaries": []}

    def fake_run(s, modes, after_job=None):
        seen["study"] = s
        return study.StudyResult(api.RunSet(s.out), seen["summaries"], False, [], [])

    monkeypatch.setattr(study, "run", fake_run)
    return seen


# -- item 5: seeds that are not whole numbers ------------------------------------------------


def test_compare_refuses_seeds_that_are_not_whole_numbers_before_reading_anything(tmp_path):
    """``api.compare(..., seeds=[0.5, 1.9])`` compared seeds 0 and 1."""
    with pytest.raises(ConfigError, match=r"seeds must be whole numbers, got 0\.5"):
        api.compare("pendulum", seeds=[0.5, 1.9], out=tmp_path / "c")
    assert not (tmp_path / "c").exists()


# -- item 6: NumPy's whole numbers, and overrides that are not fields --------------------------


def test_numpy_whole_numbers_are_whole_numbers_for_episodes_workers_and_fields(planned, tmp_path):
    """``seeds=np.int64(3)`` was taken; ``episodes=np.int64(4)``, ``workers=np.int64(1)`` and
    ``overrides={"buffer_size": np.int64(...)}`` were refused as not numbers."""
    api.reproduce(
        "pendulum",
        seeds=np.int64(3),
        episodes=np.int64(4),
        workers=np.int64(1),
        overrides={"buffer_size": np.int64(5000)},
        out=tmp_path / "o",
    )
    made = planned["study"]
    assert made.seeds == (3,) and made.options.workers == 1
    assert made.config == PendulumDDPGConfig(episodes=4, buffer_size=5000)
    assert type(made.config.episodes) is int and type(made.config.buffer_size) is int


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"nosuch": 1}, "unknown pendulum config field(s): nosuch"),  # was a TypeError from dataclasses
        (["tau=0.1"], "overrides must be a mapping of config field to value, got ['tau=0.1']"),  # a ValueError
        ({"seed": 4}, "overrides cannot set seed; pass seeds="),  # was silently replaced by each seed
        ({"variant": "fixed"}, "overrides cannot set variant; pass variant="),  # recorded 'fixed' on faithful values
    ],
)
def test_overrides_that_are_not_config_fields_are_config_errors_naming_them(overrides, message, planned, tmp_path):
    with pytest.raises(ConfigError) as caught:
        api.reproduce("pendulum", seeds=[0], overrides=overrides, out=tmp_path / "o")
    assert message in str(caught.value)
    assert "study" not in planned and not (tmp_path / "o").exists()


# -- item 7: a path that is not a run set ----------------------------------------------------


def test_load_says_what_a_file_or_one_seeds_folder_is_instead_of_a_set(tmp_path):
    """A file was "not a folder of runs (no such folder)"; one seed's folder "holds no run set"."""
    packed = tmp_path / "set" / "runs.parquet"
    packed.parent.mkdir()
    packed.write_bytes(b"")
    with pytest.raises(RunFolderError) as caught:
        api.load(packed)
    assert f"{packed} is a file, not a folder of runs; load the folder that holds it, {packed.parent}" in str(
        caught.value
    )
    seed = tmp_path / "set" / "seed_3"
    seed.mkdir()
    (seed / "config.json").write_text("{}")
    with pytest.raises(RunFolderError) as caught:
        api.load(seed)
    assert f"{seed} is one seed's run folder; load the set that holds it, {seed.parent}" in str(caught.value)


# -- item 8: one default success rate ----------------------------------------------------------


def test_reproduce_takes_its_default_success_rate_from_the_library_and_fails_when_every_seed_fails(planned, tmp_path):
    """``api.reproduce`` defaulted to 0.0 where the command takes 1.0, so every seed failing was exit 0;
    the default now lives once, in ``study.MIN_SUCCESS_RATE``."""
    import inspect

    assert inspect.signature(api.reproduce).parameters["min_success_rate"].default is study.MIN_SUCCESS_RATE
    planned["summaries"] = [types.SimpleNamespace(success=False), types.SimpleNamespace(success=True)]
    assert api.reproduce("pendulum", seeds=[0, 1], out=tmp_path / "o").exit_code == 1
    assert api.reproduce("pendulum", seeds=[0, 1], out=tmp_path / "p", min_success_rate=0.5).exit_code == 0


# -- item 10: typed values passed from Python --------------------------------------------------


def test_typed_overrides_arrive_as_their_fields_types(planned, tmp_path):
    """A list of widths stayed a list (so the config differed from the same one with a tuple),
    NumPy's floats and booleans were refused, and a whole number stayed one in a float field."""
    api.reproduce(
        "pendulum",
        seeds=[0],
        overrides={
            "actor_hidden_units": [32, np.int64(32)],
            "critic_hidden_units": np.array([16, 8]),
            "tau": np.float64(0.005),
            "gamma": 1,
            "broadcast_target": np.bool_(False),
        },
        out=tmp_path / "o",
    )
    config = planned["study"].config
    assert config == PendulumDDPGConfig(
        actor_hidden_units=(32, 32), critic_hidden_units=(16, 8), tau=0.005, gamma=1.0, broadcast_target=False
    )
    assert config.differs_from(PendulumDDPGConfig.from_dict(config.to_dict())) == []  # as config.json reads back
    for name, kind in [("actor_hidden_units", tuple), ("tau", float), ("gamma", float), ("broadcast_target", bool)]:
        assert type(getattr(config, name)) is kind, name
    assert {type(w) for w in config.actor_hidden_units + config.critic_hidden_units} == {int}


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"actor_hidden_units": "32,32"}, "actor_hidden_units must be one or more positive layer widths, got '32,32'"),
        ({"tau": "0.005"}, "tau must be a number, got '0.005'"),  # no round trip through text
        ({"episodes": 2.0}, "episodes must be a whole number, got 2.0"),
        ({"broadcast_target": 0}, "broadcast_target must be true or false, got 0"),
        ({"tau": 10**400}, "tau must be finite"),  # was an OverflowError
    ],
)
def test_a_typed_value_of_the_wrong_kind_is_refused_naming_the_field(overrides, message, planned, tmp_path):
    with pytest.raises(ConfigError) as caught:
        api.reproduce("pendulum", seeds=[0], overrides=overrides, out=tmp_path / "o")
    assert message in str(caught.value)
    assert "study" not in planned


# -- item 17: whole numbers out of range, refused once, where the config is validated ------------


def test_a_config_object_is_checked_on_the_way_in(planned, tmp_path):
    """``api.reproduce(PendulumDDPGConfig(buffer_size=10**23))`` went on to train. Since issue 72
    item 8 a config built directly is checked at construction, before it reaches ``reproduce``."""
    for fields, message in [
        ({"buffer_size": 10**23}, "buffer_size must be at most 2,147,483,647"),
        ({"tau": -1.0}, "tau must be in (0, 1]"),
        ({"actor_hidden_units": (10**23,)}, "actor_hidden_units must be at most 2,147,483,647"),
    ]:
        with pytest.raises(ConfigError) as caught:
            PendulumDDPGConfig(**fields)
        assert message in str(caught.value)
    with pytest.raises(ConfigError, match="buffer_size must be at most 2,147,483,647"):
        api.reproduce("pendulum", seeds=[0], overrides={"buffer_size": 99999999999999999999999}, out=tmp_path / "o")
    assert "study" not in planned and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "command",
    [
        ["reproduce", "pendulum", "--dry-run"],
        ["reproduce", "cartpole", "--dry-run"],
        ["check", "pendulum", "--dry-run"],
    ],
)
def test_a_layer_width_too_large_for_any_array_is_refused_by_the_dry_run(command, capsys, tmp_path):
    """``--set actor_hidden_units=99999999999999999999999`` passed the dry run, then training
    stopped with a Keras traceback (exit 1) and left an empty output folder."""
    field = "q_hidden_units" if "cartpole" in command else "actor_hidden_units"
    out = tmp_path / "o"
    assert main([*command, "--set", f"{field}=99999999999999999999999,4", "--out", str(out)]) == 2
    assert f"{field} must be at most 2,147,483,647" in capsys.readouterr().err
    assert not out.exists()


def test_a_seed_above_2_31_is_a_seed_not_a_count(capsys, tmp_path):
    """Seeds are whole numbers in [0, 2**32) (``--seeds``, ``api``, NumPy's limit); the 32-bit count
    limit of the other whole-number fields refused ``--seeds 3000000000`` once training began,
    after the dry run had accepted it."""
    assert PendulumDDPGConfig().replace(seed=2**32 - 1).seed == 2**32 - 1
    assert CartPoleDQNConfig.from_dict({"seed": 3_000_000_000}).seed == 3_000_000_000
    with pytest.raises(ConfigError, match=r"seed must be in \[0, 2\*\*32\), got 4294967296"):
        PendulumDDPGConfig().replace(seed=2**32)
    assert main(["reproduce", "pendulum", "--seeds", "3000000000", "--dry-run", "--out", str(tmp_path / "o")]) == 0
