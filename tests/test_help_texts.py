"""What each command's ``--help`` offers (issue 54, item 15): the variants are the config classes'
own, so a variant added to a post appears without anyone editing a help text, and ``--seed-batch``
offers batching only where a seed-batched learner exists, naming the ones retired as retired."""

from __future__ import annotations

import argparse

import pytest

from keras_rl.cli import build_parser
from keras_rl.learners.table import RETIRED, STACKED
from keras_rl.posts.cartpole import CartPoleDQNConfig
from keras_rl.registry import EXPERIMENTS


def _parser(command: str, monkeypatch) -> argparse.ArgumentParser:
    monkeypatch.setenv("COLUMNS", "1000")  # one line per option: argparse breaks no name at its hyphen
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]


def _help(command: str, monkeypatch) -> str:
    """``keras-rl COMMAND --help`` as a user reads it."""
    return _parser(command, monkeypatch).format_help()


def _option_line(text: str, flag: str) -> str:
    return next(line for line in text.splitlines() if line.strip().startswith(flag + " "))


@pytest.mark.parametrize("command", ["reproduce", "compare", "sweep"])
def test_variant_help_lists_every_variant_of_every_post(command, monkeypatch):
    """``reproduce --help`` once left out cartpole's ``pr-3384``: the list was written by hand."""
    line = _option_line(_help(command, monkeypatch), "--variant")
    for name, experiment in EXPERIMENTS.items():
        for variant in experiment.config_cls.VARIANTS:
            assert variant in line, f"{command} --variant omits {name}'s {variant}: {line}"


def test_a_variant_added_to_a_post_appears_in_the_help_unedited(monkeypatch):
    monkeypatch.setattr(CartPoleDQNConfig, "VARIANTS", {**CartPoleDQNConfig.VARIANTS, "pr-9999": {}})
    assert "pr-9999" in _option_line(_help("reproduce", monkeypatch), "--variant")


@pytest.mark.parametrize("command", ["reproduce", "compare", "sweep"])
def test_seed_batch_help_offers_what_batches_and_names_what_is_retired(command, monkeypatch):
    """The README calls post 000's and post 003's seed-batched Keras learners retired (the
    ``--seed-batch auto`` rows of its speed table); the help offered ``auto`` for every post."""
    parser = _parser(command, monkeypatch)
    line = _option_line(parser.format_help(), "--seed-batch")
    offered, _, retired = line.partition("Retired")
    assert retired, f"{command} --seed-batch does not say what is retired: {line}"
    for experiment, framework in STACKED:
        assert f"{experiment} ({framework})" in offered
    for experiment, framework in RETIRED:
        assert f"{experiment} ({framework})" not in offered and f"{experiment} ({framework})" in retired
    # what to do instead, in the command's own flags: only reproduce takes --engine
    takes_engine = any("--engine" in action.option_strings for action in parser._actions)
    assert ("--engine compiled" in retired) == takes_engine == (command == "reproduce"), line
    assert takes_engine or "alone" in retired
