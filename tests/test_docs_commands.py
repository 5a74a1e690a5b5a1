"""Every `keras-rl ...` command in the README's CLI block runs as shown on a fresh clone
(#23.11: the first examples exited 2 because their default folders are committed).
`reproduce` commands run with `--dry-run`, which makes every check a real run makes
(folders, options, seeds) and trains nothing; the others are parsed by the real parser."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from keras_rl.cli import build_parser, main

ROOT = Path(__file__).resolve().parent.parent


def readme_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## The CLI\s+```\n(.*?)```", text, re.S).group(1)
    commands = []
    for line in block.splitlines():
        for part in line.split(" && "):
            part = part.split("  #")[0].strip()
            if part.startswith("keras-rl "):
                commands.append(shlex.split(part)[1:])
    return commands


def test_the_readme_shows_commands():
    assert len(readme_commands()) >= 15


@pytest.mark.parametrize("argv", readme_commands(), ids=lambda argv: " ".join(argv)[:60])
def test_each_readme_command_runs_on_a_fresh_clone(argv, monkeypatch, capsys):
    if (ROOT / "runs").exists() or (ROOT / "tb").exists():
        pytest.skip("runs/ or tb/ exists in this checkout; the README's commands are for a fresh clone")
    monkeypatch.chdir(ROOT)  # where a reader runs them: the committed results/ is there
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    if argv[:1] == ["--version"]:
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 0
    elif argv[0] == "reproduce":
        assert main([*argv, "--dry-run"]) == 0, capsys.readouterr().err
        assert not any(Path(a).exists() for a in argv if a.startswith("runs/"))  # a dry run writes nothing
    elif argv[0] == "list":
        assert main(argv) == 0
    else:
        build_parser().parse_args(argv)  # every flag exists and takes what it is given
