"""Bad input, across the commands: each is refused with a message that names the problem, exit 2,
before anything is trained or written (many were found from a fresh clone, as a new user
would meet them; the item numbers are that report's)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from committed import committed_seed

from keras_rl.cli import main, parse_seeds
from keras_rl.errors import ConfigError

ROOT = Path(__file__).resolve().parent.parent
PENDULUM_SEED = committed_seed("pendulum/faithful/seed_0")


def _exit_2(argv, capsys, message: str) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err, err
    assert "Traceback" not in err
    return err


# -- 1. a seed range too large is refused from its ends, before any list is built -----------------
@pytest.mark.parametrize("text", ["0-4294967295", "0-100000000", "0-5000,6000-12000"])
def test_a_huge_seed_range_is_refused_before_it_is_built(text):
    with pytest.raises(ConfigError, match="names more than 10000 seeds"):
        parse_seeds(text)


def test_the_huge_range_of_the_report_exits_2_through_the_cli(capsys, tmp_path):
    _exit_2(
        ["reproduce", "pendulum", "--seeds", "0-4294967295", "--dry-run", "--out", str(tmp_path / "o")],
        capsys,
        "names more than 10000 seeds",
    )


# -- 15. seed lists: empty items, seeds named twice and non-ASCII digits --------------------------
@pytest.mark.parametrize(
    "text,message",
    [
        ("1,,2", "has an empty item"),
        ("1,", "has an empty item"),
        ("1,1", "names seed 1 twice"),
        ("0-3,2", "names seed 2 twice"),
        ("\u0661", "not written in ASCII digits"),
    ],
)
def test_seed_lists_that_were_silently_accepted_are_refused(text, message):
    with pytest.raises(ConfigError, match=message):
        parse_seeds(text)


# -- 2. NaN and infinity are not config values --------------------------------------------------
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "NaN"])
def test_non_finite_set_values_are_refused(value, capsys, tmp_path):
    _exit_2(
        ["reproduce", "pendulum", "--set", f"threshold={value}", "--dry-run", "--out", str(tmp_path / "o")],
        capsys,
        "threshold must be finite",
    )


def test_a_recorded_config_with_a_null_number_is_refused_and_leaves_no_folder(capsys, tmp_path):
    values = json.loads((PENDULUM_SEED / "config.json").read_text())
    values["threshold"] = None  # what json.dump wrote for NaN before the fix
    config = tmp_path / "config.json"
    config.write_text(json.dumps(values))
    out = tmp_path / "out"
    _exit_2(["reproduce", "pendulum", "--config", str(config), "--out", str(out)], capsys, "threshold must be a number")
    assert not out.exists()


# -- 5 and 6. --config: not UTF-8, an unknown variant, a missing field -------------------------------
def test_a_config_that_is_not_utf8_is_not_json(capsys, tmp_path):
    config = tmp_path / "config.json"
    config.write_bytes(b"\xff\xfe{\x00")
    _exit_2(["reproduce", "pendulum", "--config", str(config), "--dry-run"], capsys, "is not JSON")


def test_a_config_of_an_unknown_variant_is_refused(capsys, tmp_path):
    values = json.loads((PENDULUM_SEED / "config.json").read_text())
    values["variant"] = "nosuch"
    config = tmp_path / "config.json"
    config.write_text(json.dumps(values))
    _exit_2(["reproduce", "pendulum", "--config", str(config), "--dry-run"], capsys, "unknown variant 'nosuch'")


def test_a_config_missing_a_field_names_it(capsys, tmp_path):
    values = json.loads((PENDULUM_SEED / "config.json").read_text())
    del values["tau"]
    config = tmp_path / "config.json"
    config.write_text(json.dumps(values))
    _exit_2(["reproduce", "pendulum", "--config", str(config), "--dry-run"], capsys, "lacks field(s) tau")


# -- 3 and 7. an output folder that cannot be written is bad input, found before any training -----
@pytest.mark.parametrize(
    "argv",
    [
        ["compare", "pendulum", "--seeds", "0", "--out", "/proc/no-such-dir/compare"],
        ["check", "pendulum", "--out", "/proc/no-such-dir/check"],
        ["bisect", "HEAD", "HEAD", "pendulum", "--out", "/proc/no-such-dir/bisect"],
    ],
)
def test_an_unwritable_out_exits_2_before_any_training(argv, capsys, replace_backend):
    def no_training(*args, **kwargs):
        raise AssertionError("trained before checking --out")

    replace_backend(no_training)
    _exit_2(argv, capsys, "is not a writable folder")


# -- 8. a baseline too small for the rule's alpha ------------------------------------------------
def test_a_baseline_too_small_to_flag_anything_is_refused_naming_the_minimum():
    from keras_rl.check.command import check_baseline_size
    from keras_rl.check.statistics import smallest_p

    assert smallest_p("episodes_to_threshold", 1, 10) > 0.01
    with pytest.raises(ConfigError, match=r"cannot flag anything .* it needs at least (\d+) seeds") as info:
        check_baseline_size("pendulum", "episodes_to_threshold", 1, 10, 0.01)
    minimum = int(str(info.value).rsplit("at least ", 1)[1].split()[0])
    assert (
        smallest_p("episodes_to_threshold", minimum, 10) < 0.01 <= smallest_p("episodes_to_threshold", minimum - 1, 10)
    )
    check_baseline_size("pendulum", "episodes_to_threshold", 100, 10, 0.01)  # the committed size passes
    with pytest.raises(ConfigError, match="cannot flag anything"):
        check_baseline_size("cartpole", "success", 2, 3, 0.01)


def test_check_against_a_one_seed_baseline_exits_2(capsys, tmp_path, replace_backend):
    replace_backend(lambda *a, **k: pytest.fail("trained against a useless baseline"))
    baseline = tmp_path / "against" / "pendulum" / "baseline"
    baseline.mkdir(parents=True)
    shutil.copytree(committed_seed("checks/pendulum/baseline/seed_0"), baseline / "seed_0")
    _exit_2(
        ["check", "pendulum", "--against", str(tmp_path / "against"), "--out", str(tmp_path / "check")],
        capsys,
        "a baseline of 1 seed(s) cannot flag anything",
    )


# -- 17. a changed default is checked, not refused ------------------------------------------------
def test_a_changed_default_is_reported_beside_the_verdict_not_refused(tmp_path):
    """A baseline recorded actor_lr 0.002 where the code's default is now 0.001: the same as a
    default changed after the baseline was made. It loads (it was refused: "not a faithful
    run") and the change is named."""
    from keras_rl.check import command
    from keras_rl.check.rules import rule_for
    from keras_rl.registry import get_experiment

    committed = ROOT / "results" / "checks" / "pendulum" / "baseline"
    experiment = get_experiment("pendulum")
    assert command.config_changes(experiment, committed) == []
    baseline = tmp_path / "baseline"
    for s in range(3):
        seed = baseline / f"seed_{s}"
        seed.mkdir(parents=True)
        for name in ("summary.json", "episodes.csv"):
            shutil.copy(committed_seed(f"checks/pendulum/baseline/seed_{s}") / name, seed / name)
        values = json.loads((committed_seed(f"checks/pendulum/baseline/seed_{s}") / "config.json").read_text())
        (seed / "config.json").write_text(json.dumps({**values, "actor_lr": 0.002}))
    values, _ = command.baseline_values(experiment, rule_for("pendulum", "smoke"), baseline)
    assert sorted(values) == [0, 1, 2]
    assert command.config_changes(experiment, baseline) == ["actor_lr: 0.002 -> 0.001"]


# -- 10. a field given by --set and by the grid ----------------------------------------------------
def test_a_field_given_both_by_set_and_grid_is_refused(capsys, tmp_path):
    _exit_2(
        ["sweep", "pendulum", "--grid", "tau=0.001,0.01", "--set", "tau=0.005", "--out", str(tmp_path / "s")],
        capsys,
        "tau given both by --set and by the --grid",
    )


# -- 11. a folder of another post ----------------------------------------------------------------
def test_resuming_into_another_posts_folder_names_the_post(capsys, tmp_path):
    seed = tmp_path / "runs" / "seed_0"
    seed.mkdir(parents=True)
    for name in ("config.json", "summary.json"):
        shutil.copy(PENDULUM_SEED / name, seed / name)
    _exit_2(
        ["reproduce", "cartpole", "--resume", "--dry-run", "--out", str(tmp_path / "runs")],
        capsys,
        "holds runs of pendulum (faithful, keras), seeds 0; this is cartpole",
    )


# -- 12 and 13. evaluate: a run that stopped at a NaN loss; a folder another command holds ---------
def _run_without_weights(tmp_path: Path, status: str) -> Path:
    run = tmp_path / "runs" / "seed_0"
    run.mkdir(parents=True)
    shutil.copy(PENDULUM_SEED / "config.json", run / "config.json")
    summary = json.loads((PENDULUM_SEED / "summary.json").read_text())
    summary.update(status=status, success=False, message="non-finite loss at update 1")
    (run / "summary.json").write_text(json.dumps(summary))
    return run


@pytest.mark.slow
def test_evaluate_says_a_run_stopped_at_a_nan_loss_before_saving_weights(capsys, tmp_path):
    run = _run_without_weights(tmp_path, "non_finite_loss")
    _exit_2(["evaluate", str(run), "--episodes", "1"], capsys, "stopped at a NaN loss")


def test_evaluate_is_refused_while_another_command_writes_the_folder(capsys, tmp_path):
    from keras_rl.runs.files import run_folder_locks

    run = _run_without_weights(tmp_path, "running")
    with run_folder_locks([run]):
        _exit_2(["evaluate", str(run), "--episodes", "1"], capsys, "is being written by another keras-rl command")


# -- 15. options that were silently accepted --------------------------------------------------------
def test_eval_episodes_without_eval_every_is_refused(capsys, tmp_path):
    _exit_2(
        ["reproduce", "pendulum", "--eval-episodes", "3", "--dry-run", "--out", str(tmp_path / "o")],
        capsys,
        "give --eval-every N too",
    )


def test_out_inside_a_seed_folder_is_refused(capsys, tmp_path):
    seed = tmp_path / "runs" / "seed_0"
    seed.mkdir(parents=True)
    shutil.copy(PENDULUM_SEED / "config.json", seed / "config.json")
    _exit_2(["reproduce", "pendulum", "--dry-run", "--out", str(seed / "more")], capsys, "is inside the run folder")


@pytest.mark.parametrize("ray_installed", [True, False])
def test_a_bad_ray_address_from_the_environment_is_named_as_such(capsys, tmp_path, monkeypatch, ray_installed):
    """Named before Ray is looked for: a matrix cell installs the project without Ray."""
    import importlib.util

    if not ray_installed:
        find_spec = importlib.util.find_spec
        monkeypatch.setattr(
            importlib.util, "find_spec", lambda name, *a: None if name == "ray" else find_spec(name, *a)
        )
    monkeypatch.setenv("RAY_ADDRESS", "garbage")
    err = _exit_2(
        ["reproduce", "pendulum", "--dry-run", "--out", str(tmp_path / "o")], capsys, "$RAY_ADDRESS 'garbage'"
    )
    assert "--address" not in err.split("is not HOST:PORT")[0]


# -- 9. a sweep point whose loss turns NaN is a result, named, not a failed command ------------------
def test_a_sweep_names_each_nan_stop_and_does_not_fail_on_it(capsys, tmp_path, replace_backend):
    template = committed_seed("mountaincar/faithful/seed_0")

    def fake_run_jobs(todo, backend, progress=True, after_job=None):
        for job in todo:
            job.out_dir.mkdir(parents=True, exist_ok=True)
            (job.out_dir / "config.json").write_text(json.dumps(job.config.to_dict()))
            summary = json.loads((template / "summary.json").read_text())
            if job.config.learning_phase_training:
                summary.update(status="non_finite_loss", success=False, message="loss is nan at update 1")
            summary["seed"] = job.config.seed
            (job.out_dir / "summary.json").write_text(json.dumps(summary))
            shutil.copy(template / "episodes.csv", job.out_dir / "episodes.csv")

    replace_backend(fake_run_jobs)
    code = main(
        ["sweep", "mountaincar", "--grid", "learning_phase_training=false,true", "--seeds", "0", "--no-progress"]
        + ["--out", str(tmp_path / "sweep")]
    )
    err = capsys.readouterr().err
    assert code == 0, err
    assert "learning_phase_training=true seed 0 stopped (non_finite_loss): loss is nan at update 1" in err


# -- 14, 15, 21: what a command prints (21, a GIF drawn without a word of error: tests/test_evaluate.py) ----
@pytest.mark.slow
def test_a_run_names_its_files_and_a_resume_says_where(tmp_path):
    from clitools import run_cli

    out = tmp_path / "runs"
    base = ["reproduce", "pendulum", "--seeds", "0-1", "--no-progress", "--min-success-rate", "0", "--out", str(out)]
    first = run_cli(*base, "--episodes", "2")
    assert first.returncode == 0, first.stderr
    assert f"all seeds: {out / 'summary.md'} and {out / 'curves.png'}" in first.stdout
    assert not list(out.glob(".*.lock"))  # the lock files went with the command
    more = run_cli(*base, "--episodes", "3", "--resume")
    assert more.returncode == 0, more.stderr
    assert f"seed 0: resumed in {out / 'seed_0'} after episode 2" in more.stderr


@pytest.mark.slow
def test_compare_says_which_framework_runs_its_seeds_alone_under_seed_batch(tmp_path, capsys):
    code = main(
        ["compare", "cartpole", "--seeds", "0-29", "--seed-batch", "2", "--reuse-only", "--no-progress"]
        + ["--out", str(tmp_path / "c")]
    )
    assert code == 0
    err = capsys.readouterr().err
    assert "warning: --seed-batch 2: cartpole in keras, torch has no seed-batched version" in err
    assert "(keras: a compiled solo run costs" in err  # why: its stacked learner was retired (issue 34)


@pytest.mark.parametrize(
    "command", [["reproduce", "pendulum", "--episodes", "2"], ["reproduce", "pendulum", "--dry-run"]]
)
def test_a_count_too_large_for_any_array_is_refused_naming_the_field_and_leaves_nothing(command, capsys, tmp_path):
    """``--set buffer_size=99999999999999999999999`` was a ValueError traceback (exit 1) and an
    empty output folder; the dry run accepted it."""
    out = tmp_path / "o"
    assert main([*command, "--set", "buffer_size=99999999999999999999999", "--out", str(out)]) == 2
    assert "buffer_size must be at most 2,147,483,647" in capsys.readouterr().err
    assert not out.exists()


def test_a_name_too_long_for_the_file_system_or_a_symlink_loop_is_named_before_anything_runs(capsys, tmp_path):
    """A 300-character --out, or a 500-layer override that names the default folder, was
    ``[Errno 36] File name too long`` (exit 1); a symlink loop was ``[Errno 17] File exists``."""
    assert main(["reproduce", "pendulum", "--dry-run", "--out", str(tmp_path / ("x" * 300))]) == 2
    assert "is 300 bytes, more than the 255 a file system takes; pass --out" in capsys.readouterr().err
    wide = ",".join(["64"] * 500)
    monkey_out = tmp_path / "cwd"
    monkey_out.mkdir()
    import os

    here = os.getcwd()
    os.chdir(monkey_out)
    try:
        assert main(["reproduce", "pendulum", "--dry-run", "--set", f"actor_hidden_units={wide}"]) == 2
    finally:
        os.chdir(here)
    assert "pass --out with a shorter name" in capsys.readouterr().err
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    assert main(["reproduce", "pendulum", "--dry-run", "--out", str(tmp_path / "a")]) == 2
    assert "is a symlink loop" in capsys.readouterr().err
