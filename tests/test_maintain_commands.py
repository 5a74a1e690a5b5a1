"""The maintainers' commands (``python -m maintainers calibrate``, ``tables``, ``manifest``), apart
from the package users install: run from a checkout, with bad input refused; ``keras-rl --help``
lists only users' commands."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from maintainers.cli import main

ROOT = Path(__file__).resolve().parents[1]
READS_THE_MANIFEST = pytest.mark.xdist_group("manifest")
"""Tests that read every committed set (``manifest()``, about 25 s) share one process, whose cache reads
them once (``maintainers.manifest._MANIFESTS``)."""


def test_tables_runs_tabulates_folders_against_the_first(capsys):
    assert main(["tables", "runs", "results/pendulum/faithful", "results/pendulum/fixed"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("| runs | seeds | success | Fisher p |")
    assert lines[2].startswith("| `results/pendulum/faithful` | 0-29 | 30/30 | - |")
    assert lines[3].startswith("| `results/pendulum/fixed` | 0-29 | 30/30 |")


def test_tables_print_without_writing(capsys, monkeypatch):
    import keras_rl.runs.files as files

    monkeypatch.setattr(files, "atomic_write_text", lambda *a, **k: pytest.fail("wrote without --write"))
    assert main(["tables", "compat"]) == 0
    assert "| cell |" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["tables", "ablations", "nosuchpost"], "unknown experiment(s) nosuchpost"),
        (["calibrate", "rules", "nosuchpost"], "unknown post nosuchpost"),
        (["calibrate", "bisect-levels", "--draws", "5"], "--draws must be at least 100, got 5"),
        (["manifest", "--regenerate", "pendulum/faithful"], "--regenerate needs --out"),
        (["manifest", "--regenerate", "pendulum/faithful", "--out", "results/x"], "--out must not be inside results/"),
        (["tables", "runs", "/nonexistent"], "/nonexistent holds no run set"),
        (
            ["manifest", "--regenerate", "no/such/set", "--out", "/tmp/keras-rl-no-such-rerun"],
            "no committed set matches",
        ),
        (["audit", "--per-set", "0", "--out", "/tmp/keras-rl-audit"], "--per-set must be at least 1, got 0"),
        (["audit"], "audit needs --out"),
        (["audit", "--out", "results/audit"], "--out must not be inside results/"),
        (["audit", "--sets", "no/such/set", "--out", "/tmp/keras-rl-audit"], "no committed set matches"),
        (["audit", "--again", "--out", "/tmp/keras-rl-audit"], "--again reruns the sets the committed report holds"),
    ],
)
@READS_THE_MANIFEST
def test_bad_input_exits_2_naming_it(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_outside_a_checkout_the_maintainers_commands_say_so(capsys, monkeypatch, tmp_path):
    import maintainers.checkout as checkout

    monkeypatch.setattr(checkout, "RESULTS", tmp_path / "no-results")
    assert main(["tables", "findings"]) == 2
    assert "no results/ in this checkout" in capsys.readouterr().err


def test_a_subcommand_is_required(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["calibrate"])
    assert exit_.value.code == 2 and "WHAT" in capsys.readouterr().err


def test_keras_rl_lists_users_commands_only_and_never_imports_the_maintainers_tools():
    import subprocess
    import sys

    from keras_rl.cli import build_parser

    commands = set(build_parser()._subparsers._group_actions[0].choices)  # type: ignore[union-attr]
    assert commands == {"reproduce", "evaluate", "compare", "sweep", "aggregate", "pack", "check", "bisect", "list"}
    imported = [p for p in (ROOT / "keras_rl").rglob("*.py") if "maintainers" in _imports(p)]
    assert imported == []
    shown = subprocess.run(
        [sys.executable, "-m", "maintainers", "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert shown.returncode == 0 and all(w in shown.stdout for w in ("calibrate", "tables", "manifest"))


def test_every_maintainers_command_prints_its_help():
    """Each command's and subcommand's ``--help`` formats (argparse reads a bare "%" in a help
    string as a format: "90% interval" once broke ``tables --help``)."""
    import argparse

    from maintainers.cli import build_parser

    def helps(parser: argparse.ArgumentParser, name: str):
        yield name, parser
        for action in parser._subparsers._group_actions if parser._subparsers else ():  # type: ignore[union-attr]
            if isinstance(action, argparse._SubParsersAction):
                for sub, child in action.choices.items():
                    yield from helps(child, f"{name} {sub}")

    shown = {name: parser.format_help() for name, parser in helps(build_parser(), "maintainers")}
    assert "maintainers tables forest" in shown and all("usage:" in text for text in shown.values())
    assert all("%%" not in text for text in shown.values()) and "90% interval" in shown["maintainers tables forest"]
    listed = build_parser()._subparsers._group_actions[0].choices["tables"].format_help()  # type: ignore[union-attr]
    assert "90% interval" in listed and "%%" not in listed


def _imports(path: Path) -> set[str]:
    import ast

    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module.split(".")[0])
    return found


def test_an_audit_draws_the_same_seeds_from_the_same_draw_seed_and_a_batch_whole():
    from maintainers.audit import draw

    entries = [
        {"set": "a", "batches": [[0], [1], [2], [3]]},
        {"set": "b", "batches": [[0, 1, 2], [3, 4, 5]]},
        {"set": "c", "batches": [[7]]},
    ]
    first = draw(entries, 2, 52)
    assert first == draw(entries, 2, 52)
    assert len(first["a"]) == 2 and all(b in entries[0]["batches"] for b in first["a"])
    assert first["b"] == [[0, 1, 2], [3, 4, 5]] and first["c"] == [[7]]  # K past a set's batches: all of them
    assert any(draw(entries, 1, seed)["a"] != draw(entries, 1, 52)["a"] for seed in range(5))
    # a set made at three commits: its first draw kept, and one batch of each commit it missed
    versions = [{**entries[0], "batch_commits": ["x", "x", "y", "z"]}]
    by_version = draw(versions, 1, 52)["a"]
    assert draw(entries, 1, 52)["a"][0] in by_version
    assert len(by_version) == 3 and {versions[0]["batch_commits"][b[0]] for b in by_version} == {"x", "y", "z"}


def test_a_written_audit_runs_at_a_committed_tree_and_keeps_no_rerun_made_on_changes(tmp_path, monkeypatch):
    """--write refuses a tree whose tracked files differ from HEAD (its report's own files aside, which
    it rewrites as it goes), and reruns a committed result made at "HEAD + changes" or transcribed
    from an older report without its JSON."""
    import maintainers.audit as audit

    monkeypatch.setattr(audit, "uncommitted", lambda: ["keras_rl/api.py"])
    code = main(["audit", "--sets", "checks/pendulum/mutants/tau_x10", "--write", "--out", str(tmp_path / "a")])
    assert code == 2 and not (tmp_path / "a").exists()
    made = {
        "a": {"at": "HEAD 0123abcd"},
        "b": {"at": "HEAD 0123abcd + changes"},
        "c": {"at": "HEAD 0123abcd", "transcribed": "from results/AUDIT.md at e6136158"},
    }
    assert audit.at_committed_tree(made) == {"a": made["a"]}


@pytest.mark.slow
@READS_THE_MANIFEST
def test_an_audit_reruns_its_drawn_seeds_to_the_committed_bits_and_resumes_from_its_log(tmp_path, capsys):
    """Two committed compiled-engine sets (about 2 s a seed), one drawn seed each, two at once."""
    sets = ["checks/pendulum/mutants/tau_x10", "checks/pendulum/mutants/gamma_0.9"]
    argv = ["audit", "--sets", *sets, "--workers", "2", "--out", str(tmp_path / "audit")]
    assert main(argv) == 0
    report = (tmp_path / "audit" / "audit.md").read_text()
    assert "2 of 2 sets audited: 2 seed(s) the same bits" in report and "**0 mismatch(es)**" in report
    assert "| `checks/pendulum/mutants/tau_x10` |" in report
    assert re.search(r"\| HEAD [0-9a-f]{8}( \+ changes)? \| same bits \|", report)  # the commit it ran at
    assert "random seed 52" in report and "--draw-seed 52" in report
    capsys.readouterr()
    assert main(argv) == 0  # resumed: each set's result is read back from audit.json, nothing reruns
    assert "tau_x10: seeds" not in capsys.readouterr().out


@pytest.mark.slow
@READS_THE_MANIFEST
def test_a_written_audit_extends_the_committed_report_and_reruns_only_the_sets_it_lacks(tmp_path, capsys, monkeypatch):
    """--write keeps the committed report's results for this draw (here one set's, marked so that
    a rerun would show) and reruns only the set it lacks; the report covers every committed set."""
    import json

    import maintainers.audit as audit
    from maintainers.manifest import manifest

    old, new = "checks/pendulum/mutants/tau_x10", "checks/pendulum/mutants/gamma_0.9"
    batches = audit.draw(manifest(), 1, 52)[old]
    result = {
        "set": old,
        "seeds": [batches[0][0]],
        "batches": batches,
        "at": "HEAD 0123abcd",
        "by_seed": {str(batches[0][0]): {"verdict": "same bits", "why": None, "divergence": None}},
        "mismatches": 0,
    }
    record, report = tmp_path / "AUDIT.json", tmp_path / "AUDIT.md"
    record.write_text(json.dumps({"draw_seed": 52, "per_set": 1, "results": [result]}))
    monkeypatch.setattr(audit, "uncommitted", lambda: [])  # this test is not about the tree it runs in
    monkeypatch.setattr(audit, "RECORD", record)
    monkeypatch.setattr(audit, "REPORT", report)
    argv = ["audit", "--sets", old, new, "--write", "--out", str(tmp_path / "audit")]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "gamma_0.9: seeds" in printed and "tau_x10: seeds" not in printed
    text = report.read_text()
    assert f"2 of {len(manifest())} sets audited" in text and "| HEAD 0123abcd | same bits |" in text
    assert [r["set"] for r in json.loads(record.read_text())["results"]] == [new, old]  # the manifest's order
    # another draw keeps nothing: the set reruns (the rerun itself is checked above, with gamma_0.9's;
    # here, which sets are sent to it)
    reran = []

    def recorded(entry, batches, *args):
        reran.append(entry["set"])
        return {**result, "seeds": [b[0] for b in batches], "batches": batches}

    monkeypatch.setattr(audit, "audit_set", recorded)
    other_draw = ["audit", "--sets", old, "--draw-seed", "7", "--write", "--out", str(tmp_path / "audit-7")]
    assert main(other_draw) == 0
    assert reran == [old] and "tau_x10: seeds" in capsys.readouterr().out


@READS_THE_MANIFEST
def test_the_committed_audit_report_is_its_records_rendering_over_committed_sets():
    """results/AUDIT.md is ``markdown`` of results/AUDIT.json (what ``audit --write`` extends), and
    every set it audited is a committed set, drawn as its draw seed draws it."""
    import json

    from maintainers.audit import RECORD, REPORT, draw, markdown
    from maintainers.manifest import manifest

    record, text = json.loads(RECORD.read_text()), REPORT.read_text()
    command = re.search(r"Generated by `([^`]*)`", text)
    total = re.search(r"of (\d+) sets audited", text)
    assert command and total
    assert text == markdown(record["results"], command[1], record["per_set"], record["draw_seed"], int(total[1]))
    drawn = draw(manifest(), record["per_set"], record["draw_seed"])
    assert all(r["batches"] == drawn[r["set"]] for r in record["results"])
    assert not [r["set"] for r in record["results"] if r["at"].endswith("+ changes")]  # every rerun at a commit
