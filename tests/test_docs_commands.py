"""The docs: every `keras-rl ...` command shown in README.md and docs/*.md runs as shown on
a fresh clone, the pages build with `mkdocs build --strict`, and the README stays short.

`reproduce` commands run with `--dry-run`, which makes every check a real run makes
(folders, options, seeds) and trains nothing; the others are parsed by the real parser."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from keras_rl.cli import build_parser, main
from keras_rl.runs.run_set import RunSet

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def shown_commands() -> list[tuple[str, list[str]]]:
    """(page, argv) for each `keras-rl ...` line of a fenced block in the README or the docs."""
    commands = []
    for page in PAGES:
        # a `keras-rl reproduce ...` written inline in the text is an example a reader runs too
        for inline in re.findall(r"(?<!`)`(keras-rl reproduce [^`]+)`", page.read_text()):
            # not a syntax line, nor the record of how a committed set was made (no --out, or one
            # under results/: its folder holds that set)
            inline = " ".join(inline.split())  # a span may wrap over lines
            record = "--out" not in inline or "--out results/" in inline
            if not record and not any(mark in inline for mark in ("<", "...", "…")):
                commands.append((page.name, shlex.split(inline)[1:]))
        for block in re.findall(r"```[a-z]*\n(.*?)```", page.read_text(), re.S):
            for line in block.splitlines():
                for part in line.split(" && "):
                    part = part.split("  #")[0].strip()
                    if part.startswith("keras-rl "):
                        commands.append((page.name, shlex.split(part)[1:]))
    return commands


def test_the_docs_show_commands_and_the_readme_is_short():
    pages = {page for page, _ in shown_commands()}
    assert {"README.md", "cli.md"} <= pages and len(shown_commands()) >= 20
    assert len((ROOT / "README.md").read_text().splitlines()) <= 150


@pytest.mark.parametrize("page,argv", shown_commands(), ids=lambda x: " ".join(x)[:60] if isinstance(x, list) else x)
def test_each_shown_command_runs_on_a_fresh_clone(page, argv, monkeypatch, capsys):
    # only a command whose own output folder a run made here already holds is passed over (after `make
    # reproduce`, which writes runs/make-reproduce, every other command still runs)
    made = [a for a in argv if a.startswith(("runs/", "tb/")) and (ROOT / a).exists()]
    if made:
        pytest.skip(f"{', '.join(made)} exists in this checkout (a run made here); the command is for a fresh clone")
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


def test_the_docs_build_strictly(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    built = {p.relative_to(tmp_path / "site").as_posix() for p in (tmp_path / "site").rglob("index.html")}
    for page in (ROOT / "docs").glob("*.md"):
        assert (page.stem == "index" and "index.html" in built) or f"{page.stem}/index.html" in built, page.name


def test_contributing_lists_every_test_module_once():
    """docs/contributing.md's "Where the tests are" names each tests/test_*.py in one row."""
    text = (ROOT / "docs" / "contributing.md").read_text().split("## Where the tests are", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"`(test_\w+\.py)`", text)
    modules = sorted(p.name for p in (ROOT / "tests").glob("test_*.py"))
    assert sorted(listed) == modules, (set(modules) - set(listed), set(listed) - set(modules))


def test_users_pages_speak_of_the_project_not_of_its_issue_tracker():
    """A user's page cites no internal issue number ("issue #20", "before #18"); upstream
    issues and pull requests are named with their repository (pytorch/tutorials #3080)."""
    pages = [ROOT / "README.md", ROOT / "results" / "README.md", ROOT / "reproductions" / "FIDELITY.md"]
    pages += sorted((ROOT / "docs").glob("*.md"))
    found = []
    for page in pages:
        text = re.sub(r"<!--.*?-->", "", page.read_text(), flags=re.S)  # as a reader sees it
        for match in re.finditer(r"#\d+\b", text):
            before = text[max(0, match.start() - 40) : match.start()]
            if "tutorials" in before or "PR" in before[-6:]:
                continue
            found.append(f"{page.relative_to(ROOT)}: ...{before[-30:]}{match.group()}")
    assert found == [], found


def test_the_readmes_commands_chain():
    """What ``reproduce --out`` writes is what ``compare --runs`` and ``evaluate`` then read: the
    README's compare reuses its reproduce folder (run_folder's layout) instead of retraining."""
    from keras_rl.runs.files import run_folder

    readme = [argv for page, argv in shown_commands() if page == "README.md"]
    made = {Path(a[a.index("--out") + 1]) for a in readme if a[0] == "reproduce" and "--out" in a}
    compares = [a for a in readme if a[0] == "compare"]
    assert compares
    for argv in compares:
        runs = Path(argv[argv.index("--runs") + 1])
        assert run_folder(runs, argv[1], "faithful", "keras") in made, (argv, made)
    for argv in (a for a in readme if a[0] == "evaluate"):
        assert Path(argv[1]).parent in made, argv


def test_no_message_advises_overwriting_committed_results(capsys):
    """A command aimed at a committed results/ folder is told to use its own --out, not
    --overwrite, which would replace committed results."""
    committed = ROOT / "results" / "pendulum" / "faithful"
    assert 0 in RunSet(committed).seeds
    assert main(["reproduce", "pendulum", "--seeds", "0", "--dry-run", "--out", str(committed)]) == 2
    err = capsys.readouterr().err
    assert "--overwrite" not in err and "pass --out for a folder of your own" in err


@pytest.mark.slow
def test_the_python_apis_example_runs_as_the_docs_show_it(monkeypatch, capsys):
    """docs/api.md's example, executed as it stands, from the repository (the committed runs):
    a typed config trained, the committed set read, the frameworks compared."""
    text = (ROOT / "docs" / "api.md").read_text()
    (example,) = re.findall(r"```python\n(.*?)```", text, re.S)
    monkeypatch.chdir(ROOT)
    exec(compile(example, "docs/api.md", "exec"), {})
    out = capsys.readouterr().out
    assert "trained seeds [0, 1]: [2, 2] episodes, exit 0" in out
    assert "30/30 seeds reached EMA > -300; median episode 128" in out  # the README's median
    assert "The frameworks differ" in out  # post 000's committed verdict (default init)


def test_no_page_states_a_test_count_that_goes_stale():
    """The README's matrix table said "938 passed" while the fast tier had grown to 2,581, and
    contributing.md quoted 1,540 and 1,712: pages say whether tests passed, and pytest prints
    each run's count."""
    for page in (ROOT / "README.md", ROOT / "docs" / "contributing.md"):
        counts = re.findall(r"\b\d[\d,]* (?:passed|tests)\b", page.read_text())
        assert counts == [], (page.name, counts)
