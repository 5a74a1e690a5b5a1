"""Runs a user can trust (issue #13): no silent overwrite, SIGTERM like Ctrl-C, checks before
TensorFlow loads, provenance, valid JSON, TensorBoard, and what the user is told."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from keras_rl.cli import build_parser, main
from keras_rl.runs.files import read_episodes

CLI = [sys.executable, "-m", "keras_rl"]


def run_cli(*args, **kwargs):
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=600, **kwargs)


def strict_json(path: Path):
    """JSON as the standard has it: NaN and Infinity are refused."""

    def refuse(name):
        raise ValueError(f"{path} holds {name}, which is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A 2-episode cartpole run (seconds), made once."""
    out = tmp_path_factory.mktemp("tiny") / "c"
    proc = run_cli("reproduce", "cartpole", "--seeds", "1", "--episodes", "2", "--no-progress", "--out", str(out))
    assert proc.returncode == 1, proc.stderr
    return out, proc


# -- data safety ---------------------------------------------------------------------------------
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


@pytest.mark.parametrize(
    "field, flag",
    [
        ("variant=fixed", "--variant"),
        ("seed=7", "--seeds"),
        ("framework=torch", "--framework"),
        ("matched_init=true", "--matched-init"),
    ],
)
def test_set_of_a_run_field_is_refused_and_points_to_the_flag(field, flag, capsys, tmp_path):
    assert main(["reproduce", "pendulum", "--set", field, "--out", str(tmp_path)]) == 2
    assert f"use {flag}" in capsys.readouterr().err


def _default_signals():
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.slow
def test_sigterm_is_handled_like_ctrl_c(tmp_path, workers):
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [
            *CLI,
            "reproduce",
            "pendulum",
            "--seeds",
            "0-2",
            "--workers",
            str(workers),
            "--no-progress",
            "--set",
            "stop_at_threshold=false",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_signals,
    )
    csv = out / "seed_0" / "episodes.csv"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if csv.is_file() and len(csv.read_text().splitlines()) >= 4:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)  # to the command only, as `timeout` or `docker stop` send it
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    assert "seed 0: interrupted, no verdict" in stdout and "FAIL" not in stdout  # #23.9: it said FAIL
    summary = strict_json(out / "seed_0" / "summary.json")
    assert summary["status"] == "interrupted" and "SIG" in summary["message"]
    assert summary["episodes_run"] == len(read_episodes(csv)) >= 3
    assert (out / "seed_0" / "checkpoint.pkl").is_file()  # so --resume can continue it
    assert not (out / "seed_2").exists()  # the queued seed never started


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


# -- checks before anything heavy loads ----------------------------------------------------------------
BEFORE_TF = [
    (["reproduce", "pendulum", "--seeds", "4294967296"], "below 2**32"),
    (["reproduce", "pendulum", "--seeds", "0-100000"], "more than 10000 seeds"),
    (["reproduce", "pendulum", "--set", "actor_hidden_units=0"], "positive layer widths"),
    (["reproduce", "pendulum", "--set", "batch_size=1500"], "larger than train_start"),
    (["reproduce", "pendulum", "--set", "buffer_size=500"], "would never train"),
    (["reproduce", "cartpole", "--set", "buffer_size=100"], "would never train"),
    (["reproduce", "mountaincar", "--set", "batch_size=200"], "train_down_to + 1"),
    (["reproduce", "pendulum", "--out", "/proc/version"], "is a file, not a folder"),
    (["reproduce", "pendulum", "--out", "/proc/no-such-dir/out"], "not a writable folder"),
    (["reproduce", "pendulum", "--set", "hidden_units=32"], "was renamed; use actor_hidden_units"),
    (["evaluate", "results/x", "--seed", "-1"], "--seed must be in [0, 2**32)"),
    (["evaluate", "results/x", "--gif", "/tmp"], "is a folder; name a file"),
    (["evaluate", "results/x", "--gif", "/proc/no-such-dir/a.gif"], "not a writable folder"),
    (["compare", "pendulum", "--workers", "0"], "--workers must be at least 1"),
]


@pytest.mark.parametrize("argv, message", BEFORE_TF, ids=[" ".join(a[:3]) + " " + m for a, m in BEFORE_TF])
def test_bad_input_exits_2_before_tensorflow_is_imported(argv, message):
    code = (
        "import sys; from keras_rl.cli import main; rc = main(sys.argv[1:]); "
        "sys.exit(rc + 10 if 'tensorflow' in sys.modules else rc)"
    )
    proc = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)  # 12: right error, but TensorFlow was loaded
    assert message in proc.stderr


def test_empty_out_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "pendulum", "--out", ""])
    assert exc.value.code == 2 and "--out: is empty" in capsys.readouterr().err


def test_aggregate_refuses_mixed_configs_and_names_a_corrupt_seed(tiny, tmp_path, capsys):
    parent = tmp_path / "agg"
    shutil.copytree(tiny[0] / "seed_1", parent / "seed_1")
    shutil.copytree(tiny[0] / "seed_1", parent / "seed_2")
    config = json.loads((parent / "seed_2" / "config.json").read_text())
    (parent / "seed_2" / "config.json").write_text(json.dumps({**config, "seed": 2, "tau": 0.5}))
    assert main(["aggregate", str(parent)]) == 2
    assert "tau=0.5 there, 0.005 here" in capsys.readouterr().err
    (parent / "seed_2" / "config.json").write_text(json.dumps({**config, "seed": 2}))
    (parent / "seed_2" / "episodes.csv").unlink()  # a run killed before its first episode: coped with
    assert main(["aggregate", str(parent)]) == 0
    (parent / "seed_2" / "summary.json").write_text('{"status": ')
    assert main(["aggregate", str(parent)]) == 2
    assert "seed_2/summary.json is corrupt" in capsys.readouterr().err


def test_ctrl_c_during_evaluate_keeps_the_episodes_played(tiny):
    run_dir = tiny[0] / "seed_1"
    proc = subprocess.Popen(
        [*CLI, "evaluate", str(run_dir), "--episodes", "100000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_signals,
    )
    deadline = time.monotonic() + 120
    lines = []
    while time.monotonic() < deadline and len(lines) < 3:
        line = proc.stdout.readline()
        if line.startswith("episode:"):
            lines.append(line)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in stderr, stderr
    result = strict_json(run_dir / "evaluation.json")
    assert result["interrupted"] is True and len(result["scores"]) >= 3 and result["episodes"] == len(result["scores"])


# -- provenance and valid files -----------------------------------------------------------------------
def test_summary_records_provenance_and_is_valid_json_with_usual_permissions(tiny):
    seed_dir = tiny[0] / "seed_1"
    summary = strict_json(seed_dir / "summary.json")
    prov = summary["provenance"]
    assert prov["cpu_model"] and prov["cwd"] and prov["started_at"].endswith("+00:00")
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


@pytest.mark.slow
def test_torch_runs_record_the_torch_version(tmp_path):
    pytest.importorskip("torch")
    proc = run_cli(
        "reproduce",
        "cartpole",
        "--framework",
        "torch",
        "--seeds",
        "0",
        "--episodes",
        "1",
        "--no-progress",
        "--out",
        str(tmp_path),
    )
    assert proc.returncode == 1, proc.stderr
    import torch

    assert strict_json(tmp_path / "seed_0" / "summary.json")["versions"]["torch"] == torch.__version__


# -- what the user is told ------------------------------------------------------------------------------
def test_the_end_of_a_run_says_where_pass_or_fail_and_why_exit_1(tiny):
    out, proc = tiny
    # a solo run that played its whole budget keeps its final checkpoint, to be extended (--resume --episodes N)
    files = "checkpoint.pkl, config.json, curve.png, episodes.csv, q_network.weights.h5, summary.json"
    assert f"{out / 'seed_1'}/: {files}" in proc.stdout
    assert "FAIL (metric >= 475 within 2 episodes: not reached" in proc.stdout
    assert "constantly achieves 500 steps" in proc.stdout  # the post's own claim beside it
    assert "criterion not met: 0/1 seeds succeeded, need 100%" in proc.stderr


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("keras-rl ")


def test_every_option_has_help_text():
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = [
        f"{name} {action.option_strings or action.dest}"
        for name, sub in subparsers.choices.items()
        for action in sub._actions
        if action.dest != "help" and not action.help
    ]
    assert missing == []
    assert "faithful-intended" in subparsers.choices["reproduce"].format_help()


@pytest.mark.parametrize("seed_batch", [1, 2])
@pytest.mark.slow
def test_tensorboard_scalars_read_back(tmp_path, seed_batch):
    import tensorflow as tf

    proc = run_cli(
        "reproduce",
        "cartpole",
        "--seeds",
        "0-1",
        "--episodes",
        "3",
        "--no-progress",
        "--out",
        str(tmp_path / "runs"),
        "--tensorboard",
        str(tmp_path / "tb"),
        "--seed-batch",
        str(seed_batch),
    )
    assert proc.returncode == 1, proc.stderr
    runs = sorted(p.name for p in (tmp_path / "tb").iterdir())
    assert runs == ["cartpole-faithful-keras-seed0", "cartpole-faithful-keras-seed1"]
    scores = {}
    for event_file in (tmp_path / "tb" / runs[0]).glob("events.out.tfevents.*"):
        for event in tf.compat.v1.train.summary_iterator(str(event_file)):
            for value in event.summary.value:
                if value.tag == "score":
                    scores[event.step] = float(tf.make_ndarray(value.tensor))
    expected = {r["episode"]: r["score"] for r in read_episodes(tmp_path / "runs" / "seed_0" / "episodes.csv")}
    assert scores == expected


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
