"""Run folders: every file a run writes, provenance and strict JSON in its summary, no silent
overwrite, one writer per folder, nothing lost on a full disk, and episodes.csv written the same
row by row or whole."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import signal
import subprocess
import time

import pytest
from clitools import CLI, run_cli, strict_json

from keras_rl.cli import main
from keras_rl.errors import RunFolderError
from keras_rl.posts.pendulum import PendulumDDPGConfig
from keras_rl.runs.files import read_episodes


def test_a_folder_holding_a_run_is_refused_then_replaced_whole_with_overwrite(tiny, tmp_path):
    out = tmp_path / "c"
    shutil.copytree(tiny[0], out)
    seed_dir = out / "seed_1"
    (seed_dir / "evaluation.json").write_text("{}")  # what an earlier evaluate left
    before = {p.name: p.read_bytes() for p in seed_dir.iterdir()}
    proc = run_cli("reproduce", "cartpole", "--seeds", "1", "--episodes", "3", "--no-progress", "--out", str(out))
    assert proc.returncode == 2
    assert f"{seed_dir} (a completed run, 2 episodes)" in proc.stderr and "--overwrite" in proc.stderr
    assert {p.name: p.read_bytes() for p in seed_dir.iterdir()} == before  # nothing touched
    proc = run_cli(
        "reproduce", "cartpole", "--seeds", "1", "--episodes", "3", "--no-progress", "--out", str(out), "--overwrite"
    )
    assert proc.returncode == 1, proc.stderr
    assert not (seed_dir / "evaluation.json").exists()  # cleared whole: no stale file survives
    assert len(read_episodes(seed_dir / "episodes.csv")) == 3


@pytest.mark.slow
def test_set_never_writes_into_the_variants_own_folder(tmp_path):
    proc = run_cli(
        "reproduce",
        "cartpole",
        "--seeds",
        "0",
        "--episodes",
        "1",
        "--no-progress",
        "--set",
        "tau=0.01",
        "--set",
        "gamma=0.9",
        cwd=tmp_path,
    )
    assert proc.returncode == 1, proc.stderr
    assert not (tmp_path / "results" / "cartpole" / "faithful").exists()
    folder = tmp_path / "results" / "cartpole" / "faithful-set-gamma=0.9,tau=0.01" / "seed_0"
    assert json.loads((folder / "config.json").read_text())["tau"] == 0.01


@contextlib.contextmanager
def tiny_disk(folder, size: str):
    """A tmpfs of ``size`` mounted at ``folder`` for the block (skips where it cannot mount)."""
    folder.mkdir()
    if subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], capture_output=True
    ).returncode:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], capture_output=True)


@pytest.mark.slow
def test_disk_full_is_an_error_naming_the_file_and_nothing_claims_success(tmp_path):
    with tiny_disk(tmp_path / "tiny", "40k") as mount:
        proc = run_cli(
            "reproduce",
            "pendulum",
            "--seeds",
            "0",
            "--episodes",
            "3",
            "--no-progress",
            "--set",
            "train_start=200",
            "--out",
            str(mount / "run"),
        )
        assert proc.returncode != 0
        summary_path = mount / "run" / "seed_0" / "summary.json"
        if summary_path.is_file():
            summary = json.loads(summary_path.read_text())
            assert summary["status"] != "completed" and not summary["success"]
        assert "No space left on device" in proc.stderr or "could not write" in proc.stderr, proc.stderr


@pytest.mark.slow
def test_disk_full_under_ray_is_one_line_per_seed_naming_the_file(tmp_path):
    """#23.8: with --workers 2 a full disk printed a Ray stack trace with colour codes."""
    with tiny_disk(tmp_path / "tiny", "200k") as mount:
        proc = run_cli(
            "reproduce",
            "pendulum",
            "--seeds",
            "0-1",
            "--episodes",
            "20",
            "--workers",
            "2",
            "--no-progress",
            "--out",
            str(mount / "r"),
        )
        assert proc.returncode == 1
        assert "Traceback" not in proc.stderr and "\x1b[" not in proc.stderr, proc.stderr
        for seed in (0, 1):
            assert re.search(
                rf"error: seed {seed}\b.*could not write {mount / 'r' / f'seed_{seed}'}/\S+: No space left", proc.stderr
            ), proc.stderr


def test_summary_records_provenance_and_is_valid_json_with_usual_permissions(tiny):
    seed_dir = tiny[0] / "seed_1"
    summary = strict_json(seed_dir / "summary.json")
    prov = summary["provenance"]
    assert prov["cpu_model"] and prov["started_at"].endswith("+00:00")
    assert "cwd" not in prov  # the maker's local path tells a reader nothing
    assert (len(prov["commit"]) == 40 and isinstance(prov["dirty"], bool)) or prov["commit"] is None
    mask = os.umask(0)
    os.umask(mask)
    for name in ("summary.json", "config.json", "episodes.csv"):
        assert (seed_dir / name).stat().st_mode & 0o777 == 0o666 & ~mask, name


@pytest.mark.slow
def test_lower_is_better_metrics_keep_their_best_and_json_has_no_infinity(tmp_path):
    proc = run_cli(
        "reproduce",
        "mountaincar",
        "--seeds",
        "0",
        "--episodes",
        "12",
        "--no-progress",
        "--set",
        "converge_window=3",
        "--out",
        str(tmp_path),
    )
    assert proc.returncode in (0, 1), proc.stderr
    summary = strict_json(tmp_path / "seed_0" / "summary.json")  # the spread is inf for 2 episodes
    spreads = [r["metric"] for r in read_episodes(tmp_path / "seed_0" / "episodes.csv") if math.isfinite(r["metric"])]
    assert summary["best_metric"] == min(spreads)


def test_episodes_csv_is_the_same_text_whether_written_row_by_row_or_whole(tmp_path):
    """``RunRecorder.add_episode`` formats each row once and keeps the text; the file is
    still what formatting every row afresh gives, after the rows are replaced too (resume)."""
    from keras_rl.runs.files import RunRecorder, episode_columns, episodes_csv_text

    names = ("loss",)
    rows = [
        {
            "episode": i,
            "steps": 20 + i,
            "total_steps": 21 * i,
            "score": 0.1 * i,
            "metric": float("inf") if i < 2 else i,
            "loss": None if i < 2 else 1 / 3 * i,
            "wall_seconds": 0.5 * i,
        }
        for i in range(1, 8)
    ]
    recorder = RunRecorder(tmp_path, names)
    for row in rows[:4]:
        recorder.add_episode(row)
    assert (tmp_path / "episodes.csv").read_text() == episodes_csv_text(rows[:4], episode_columns(names))
    recorder.rows = [dict(r) for r in rows[:2]]  # a resume cuts the rows back to its checkpoint's
    for row in rows[2:]:
        recorder.add_episode(row)
    assert (tmp_path / "episodes.csv").read_text() == episodes_csv_text(rows, episode_columns(names))


def test_run_folder_has_every_file(short_run):
    for name in ("config.json", "episodes.csv", "summary.json", "curve.png", "actor.weights.h5", "critic.weights.h5"):
        assert (short_run / name).is_file(), name
    summary = json.loads((short_run / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["success"] is False
    assert summary["reached_at_episode"] is None and summary["episodes_run"] == 7
    assert summary["versions"]["keras_backend"] == "tensorflow"
    rows = read_episodes(short_run / "episodes.csv")
    assert [r["episode"] for r in rows] == list(range(1, 8))
    assert all(r["steps"] == 200 for r in rows) and rows[-1]["total_steps"] == 1400
    assert rows[0]["critic_loss"] is None and rows[-1]["critic_loss"] is not None  # training from step 600


@pytest.mark.slow
def test_compare_and_sweep_never_remove_a_seed_folder_they_did_not_make(tmp_path, capsys):
    """Issue #23.1: a seed folder without summary.json (someone's notes in it) is refused
    with its name, not deleted; --rerun is the way to replace it."""
    from keras_rl.runs.provenance import code_version
    from keras_rl.runs.reuse import check_reusable

    seed_dir = tmp_path / "seed_0"
    seed_dir.mkdir()
    (seed_dir / "NOTES.txt").write_text("mine")
    with pytest.raises(RunFolderError, match="NOTES.txt.*no summary.json.*left as it is"):
        check_reusable(seed_dir, PendulumDDPGConfig(seed=0), code_version())
    assert (seed_dir / "NOTES.txt").read_text() == "mine"
    assert check_reusable(tmp_path / "seed_1", PendulumDDPGConfig(seed=1), code_version()) == "missing"
    (tmp_path / "seed_2").mkdir()  # an empty folder holds nothing to lose
    assert check_reusable(tmp_path / "seed_2", PendulumDDPGConfig(seed=2), code_version()) == "missing"
    pytest.importorskip("torch", reason="compare needs the torch extra")
    argv = ["compare", "pendulum", "--seeds", "0", "--episodes", "2", "--runs", str(tmp_path / "runs"), "--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "R1")]) == 0
    made = tmp_path / "runs" / "pendulum" / "faithful" / "seed_0"
    (made / "summary.json").unlink()
    (made / "NOTES.txt").write_text("mine")
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "R2")]) == 2  # the reproducer exited 0 and lost NOTES.txt
    err = capsys.readouterr().err
    assert f"{made} holds files (NOTES.txt" in err and "no summary.json" in err
    assert (made / "NOTES.txt").read_text() == "mine"


@pytest.mark.slow
def test_a_second_command_writing_the_same_run_folder_is_refused(tmp_path):
    """#23.5: two commands with one --out were not kept apart (the second's --overwrite
    cleared the first's folder under it). The second now exits 2 naming the folder, and the
    first finishes as if alone. The first is held (SIGSTOP) from its first episode on disk until
    the second has been refused, so it is still running when they meet however slow the machine."""
    out = tmp_path / "out"
    argv = [
        *CLI,
        "reproduce",
        "pendulum",
        "--seeds",
        "4",
        "--episodes",
        "5",
        "--no-progress",
        "--set",
        "stop_at_threshold=false",
        "--min-success-rate",
        "0",
        "--out",
        str(out),
    ]
    first = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    csv_path = out / "seed_4" / "episodes.csv"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and first.poll() is None and not csv_path.is_file():
        time.sleep(0.05)
    first.send_signal(signal.SIGSTOP)
    try:
        assert first.poll() is None, "the first command ended before the second could meet it"
        second = run_cli(*argv[3:], "--overwrite")
        assert first.poll() is None, "the first command ended before the second met it"
    finally:
        first.send_signal(signal.SIGCONT)
    assert second.returncode == 2, second.stderr
    assert f"{out / 'seed_4'} is being written by another keras-rl command (pid {first.pid})" in second.stderr
    _, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert len(read_episodes(csv_path)) == 5
    again = run_cli(*argv[3:], "--episodes", "2", "--overwrite")
    assert again.returncode == 0, again.stderr  # the lock went with the first command


def test_the_lock_files_go_when_the_block_ends(tmp_path):
    from keras_rl.runs.files import run_folder_locks

    runs = [tmp_path / "out" / f"seed_{s}" for s in range(3)]
    with run_folder_locks(runs):
        assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [f".seed_{s}.lock" for s in range(3)]
    assert list((tmp_path / "out").iterdir()) == []


def test_episodes_are_appended_not_rewritten_and_a_cut_run_is_written_anew(tmp_path):
    """Each episode adds its line to ``episodes.csv`` in place (bytes written grow with the run,
    not with its square); rows a resume replaced are written whole, atomically."""
    import os

    from keras_rl.runs.files import RunRecorder, read_episodes

    def row(n: int) -> dict:
        return {"episode": n, "steps": 200, "total_steps": 200 * n, "score": -1.5 * n, "metric": -1.0, "loss": None}

    recorder = RunRecorder(tmp_path, ("loss",))
    path = tmp_path / "episodes.csv"
    recorder.add_episode(row(1))
    first = os.stat(path).st_ino
    head = path.read_bytes()
    recorder.add_episode(row(2))
    recorder.add_episode(row(3))
    assert os.stat(path).st_ino == first and path.read_bytes().startswith(head)  # the same file, grown
    assert [r["episode"] for r in read_episodes(path)] == [1, 2, 3]
    recorder.rows = recorder.rows[:1]  # as a resume from an earlier checkpoint cuts them
    recorder.add_episode(row(2))
    assert os.stat(path).st_ino != first and [r["episode"] for r in read_episodes(path)] == [1, 2]
