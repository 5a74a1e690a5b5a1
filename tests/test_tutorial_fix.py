"""``reproductions/tutorial_fix.py``: the tutorial's community fix against the tutorial as
published, read from run folders; its numbers checked against the folders by hand."""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from committed import copy_seeds

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "results" / "engines" / "cartpole" / "compiled"
FIX = ROOT / "results" / "cartpole" / "tutorial-fix" / "issue-3080"
SCRIPT_PATH = ROOT / "reproductions" / "tutorial_fix.py"
_spec = importlib.util.spec_from_file_location("tutorial_fix_script", SCRIPT_PATH)
assert _spec is not None and _spec.loader is not None
SCRIPT = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(SCRIPT)


def arm(tmp_path: Path, name: str, seeds: range, source: Path = PUBLISHED) -> Path:
    return copy_seeds(source, tmp_path / name, lambda seed: seed in seeds)


def run_script(*args: str) -> subprocess.CompletedProcess:
    """The script on its command line, in a process of its own, as a maintainer runs it."""
    return subprocess.run(
        [sys.executable, str(SCRIPT_PATH), *args], capture_output=True, text=True, timeout=120, cwd=ROOT
    )


def run(*args: str) -> subprocess.CompletedProcess:
    """The script's ``main`` on these arguments in this process, from the checkout's root, with what
    it prints and its exit status as ``run_script`` gives them (without a Python start-up each)."""
    out, err, code = io.StringIO(), io.StringIO(), 0
    with contextlib.chdir(ROOT), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            SCRIPT.main(list(args))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return subprocess.CompletedProcess([str(SCRIPT_PATH), *args], code, out.getvalue(), err.getvalue())


def test_the_report_counts_what_the_folders_hold(tmp_path):
    a, b = arm(tmp_path, "a", range(0, 10)), arm(tmp_path, "b", range(10, 20))
    out = tmp_path / "report.md"
    proc = run_script(str(a), str(b), "--labels", "published,issue-3080", "--write", str(out))
    assert proc.returncode == 0, proc.stderr
    text = out.read_text()
    for folder, seeds in ((a, range(0, 10)), (b, range(10, 20))):
        summaries = [json.loads((folder / f"seed_{s}" / "summary.json").read_text()) for s in seeds]
        wins = sum(s["success"] for s in summaries)
        means = []
        for s in seeds:
            with open(folder / f"seed_{s}" / "episodes.csv", newline="") as fh:
                steps = [int(r["steps"]) for r in csv.DictReader(fh)][:50]
            means.append(np.mean(steps))
        row = next(line for line in text.splitlines() if f"`{folder}`" in line)
        assert f"| {wins}/10 (" in row and f"| {np.median(means):.1f} (" in row
    assert "issue-3080 minus published" in text and "success rate difference: **" in text
    assert "tutorial_fix.py" in text  # the command that made it


def report_rows(path: Path) -> list[list[str]]:
    """The report's two arm rows, from the seeds column on."""
    lines = path.read_text().splitlines()
    return [line.split(" | ")[2:] for line in lines if line.startswith(("| published", "| fix"))]


def test_an_arm_in_several_folders_reads_as_one(tmp_path):
    """An arm that grew in steps (folders comma-joined) reads as that arm in one folder: a seed held
    twice is read once, and the report's numbers are those of the one-folder arm."""
    whole, fix = arm(tmp_path, "whole", range(0, 12)), arm(tmp_path, "fix", range(0, 12), FIX)
    part1, part2 = arm(tmp_path, "part1", range(0, 7)), arm(tmp_path, "part2", range(5, 12))  # 5, 6 twice
    one, split = tmp_path / "one.md", tmp_path / "split.md"
    assert run(str(whole), str(fix), "--write", str(one)).returncode == 0
    proc = run(f"{part1},{part2}", str(fix), "--write", str(split))
    assert proc.returncode == 0, proc.stderr
    assert report_rows(one) == report_rows(split) and len(report_rows(one)) == 2
    assert f"`{part1} + {part2}`" in split.read_text()
    assert one.read_text().split("judged on")[1] == split.read_text().split("judged on")[1]


def test_a_seed_held_twice_with_different_outcomes_is_refused(tmp_path):
    part1, part2 = arm(tmp_path, "part1", range(0, 3)), arm(tmp_path, "part2", range(2, 5))
    summary = part2 / "seed_2" / "summary.json"
    record = json.loads(summary.read_text())
    record["success"], record["reached_at_episode"] = (False, None) if record["success"] else (True, 321)
    summary.write_text(json.dumps(record))
    proc = run(f"{part1},{part2}", str(part1))
    assert proc.returncode == 2 and "seed 2 is in" in proc.stderr and "different outcomes" in proc.stderr


def test_seeds_reads_those_seeds_only_and_each_arm_must_hold_them(tmp_path):
    a, b = arm(tmp_path, "a", range(0, 14)), arm(tmp_path, "b", range(6, 20), FIX)
    picked, exact = tmp_path / "picked.md", tmp_path / "exact.md"
    proc = run(str(a), str(b), "--seeds", "0-9", "--write", str(picked))
    assert proc.returncode == 2 and f"{b} lacks finished seed(s) 0-5 of the 10 asked for (0-9)" in proc.stderr
    assert not picked.exists()  # nothing written
    assert run(str(a), str(b), "--seeds", "6-13", "--write", str(picked)).returncode == 0
    a2, b2 = arm(tmp_path, "a2", range(6, 14)), arm(tmp_path, "b2", range(6, 14), FIX)
    assert run(str(a2), str(b2), "--write", str(exact)).returncode == 0
    assert report_rows(picked) == report_rows(exact) and report_rows(picked)[0][0] == "6-13 (8)"
    assert "--seeds 6-13" in picked.read_text()


def test_a_first_look_gives_the_earlier_reading_from_the_same_folders(tmp_path):
    a, b = arm(tmp_path, "a", range(0, 20)), arm(tmp_path, "b", range(0, 20), FIX)
    both, early = tmp_path / "both.md", tmp_path / "early.md"
    assert run(str(a), str(b), "--seeds", "0-19", "--first-look", "0-9", "--write", str(both)).returncode == 0
    assert run(str(a), str(b), "--seeds", "0-9", "--write", str(early)).returncode == 0
    second = both.read_text().split("This is a second look")
    assert len(second) == 2 and "on seeds 0-9 of the same arms" in second[1]
    first_reading = second[1].split("stays as it was:")[1].strip()
    assert first_reading == early.read_text().split("the runs (2026-11-23):")[1].strip()
    assert "10 seeds each" in first_reading and "20 seeds each" in second[0]
    proc = run(str(a), str(b), "--seeds", "0-9", "--first-look", "0-19")
    assert proc.returncode == 2 and "--first-look 0-19 is not a smaller part of --seeds 0-9" in proc.stderr


def test_an_empty_arm_or_a_missing_folder_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    proc = run(str(PUBLISHED), str(tmp_path / "empty"))
    assert proc.returncode == 2 and "holds no finished seed" in proc.stderr
    proc = run(str(PUBLISHED), str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "is not a folder" in proc.stderr


@pytest.mark.parametrize("labels", ["one", "a,b,c", ",b"])
def test_labels_are_two_names(labels):
    proc = run(str(PUBLISHED), str(PUBLISHED), "--labels", labels)
    assert proc.returncode == 2 and "--labels" in proc.stderr


def test_each_committed_report_is_what_its_command_makes_of_the_committed_folders(tmp_path):
    """The reports beside ``results/cartpole/tutorial-fix/plan.md`` (the findings quote them):
    each one's recorded command, rerun into a scratch file, gives the committed text, with the
    deviations that its committed path discloses (``maintainers/plans.py``)."""
    import re
    import shlex

    from maintainers import plans

    reports = sorted((ROOT / "results" / "cartpole" / "tutorial-fix").glob("report*.md"))
    assert len(reports) >= 2
    for report in reports:
        text = report.read_text()
        command = re.search(r"Generated by `python reproductions/tutorial_fix\.py ([^`]*)`", text)
        assert command, f"{report.name} names no command"
        args = shlex.split(command.group(1))
        assert args[args.index("--write") + 1] == str(report.relative_to(ROOT))
        args[args.index("--write") + 1] = str(tmp_path / report.name)
        proc = run(*args)
        assert proc.returncode == 0, proc.stderr
        made = plans.disclosed((tmp_path / report.name).read_text(), report.relative_to(ROOT).as_posix())
        assert made.replace(str(tmp_path / report.name), "") == text.replace(str(report.relative_to(ROOT)), ""), (
            f"{report.relative_to(ROOT)} is stale: rerun its command"
        )


def test_each_proposals_folders_were_made_by_the_command_the_findings_print():
    """``maintainers/tutorial_fix.py`` is the one home of each proposal's folders and commands:
    every committed seed of each arm records that command (its own seed range aside), on the
    variant and framework the arm claims. An arm not yet committed is one its queue still makes
    (the vectorised engine's, ``maintainers/queues/tutorial-fix-vectorised.tsv``), with the same
    command."""
    import re

    from keras_rl.runs.run_set import RunSet
    from maintainers.tutorial_fix import FRAMEWORK_OF, FRAMEWORKS, PLANNED_SEEDS, TUTORIAL_FIXES

    queued = {
        folder: "keras-rl " + args + f" --resume --out {folder}"
        for folder, args in (
            line.split("\t")
            for line in (ROOT / "maintainers" / "queues" / "tutorial-fix-vectorised.tsv").read_text().splitlines()
            if line and not line.startswith("#")
        )
    }
    for fix in TUTORIAL_FIXES:
        for fw in FRAMEWORKS:
            runs = RunSet(ROOT / "results" / fix.folder(fw))
            summaries, configs = runs.summary_records(), runs.configs()
            if not summaries and fw == "vectorised":  # still to run: its queue runs the command named here
                assert queued[f"results/{fix.folder(fw)}"] == fix.command(fw, "0-99"), fix.folder(fw)
                continue
            assert len(summaries) >= PLANNED_SEEDS[fw], (runs, len(summaries))
            for s, config in zip(summaries, configs, strict=True):
                made = re.sub(r"--seeds \S+", "--seeds {seeds}", s["command"])
                assert made == fix.command(fw, "{seeds}"), (fix.folder(fw), s["seed"], s["command"])
                assert config["seed"] == s["seed"], (fix.folder(fw), s["seed"])
                assert config["variant"] == fix.variant and config["framework"] == FRAMEWORK_OF[fw], (
                    fix.folder(fw),
                    s["seed"],
                )
