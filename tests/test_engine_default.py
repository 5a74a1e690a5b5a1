"""``--engine auto``, the default (issue 54, item 11): the compiled engine where it is certified,
and every recorded run replaying on the engine that made it.

The dry runs here are planned in this process (``keras_rl.cli.main``), so nothing trains and
TensorFlow is not loaded; the runs they find on disk are committed seeds written out as
folders (``SeedRun.extract``)."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import pytest

from keras_rl.cli import main
from keras_rl.runs.lifecycle import recorded_engine
from keras_rl.runs.run_set import RunSet

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
GYMNASIUM_RUN = RESULTS / "cartpole/faithful/seed_3"
"""A committed seed of post 003 made on the Gymnasium loop (packed)."""
COMPILED_RUN = RESULTS / "engines/cartpole/compiled/seed_3"
"""The same seed made on the compiled engine (packed)."""


def dry_run(capsys, *argv: str) -> tuple[int, str]:
    """``reproduce ... --dry-run`` in this process: its exit code and the engine line it printed
    (or its error)."""
    code = main(["reproduce", *argv, "--dry-run"])
    out, err = capsys.readouterr()
    engine = [line for line in out.splitlines() if line.startswith("engine: ")]
    return code, engine[0] if engine else err


def extracted(run: Path, dest: Path) -> Path:
    return RunSet.seed_at(run).extract(dest)


@pytest.mark.parametrize("experiment", ["pendulum", "cartpole", "mountaincar"])
def test_a_new_keras_study_runs_compiled_where_it_is_certified(experiment, capsys, tmp_path):
    code, line = dry_run(capsys, experiment, "--seeds", "0-1", "--out", str(tmp_path / "o"))
    assert code == 0 and line.startswith(f"engine: compiled (certified for {experiment} in keras"), line


@pytest.mark.parametrize(
    "argv, why",
    [
        (["pendulum", "--framework", "torch"], "not certified for pendulum in torch"),
        (["mountaincar", "--seed-batch", "10"], "--seed-batch 10 batches seeds on the Gymnasium loop"),
        (["mountaincar", "--set", "popping_buffer=false"], "cannot run this config: it runs mountaincar"),
        (["mountaincar", "--variant", "fixed"], "cannot run this config"),
    ],
)
def test_auto_falls_back_to_the_gymnasium_loop_and_says_why(argv, why, capsys, tmp_path):
    code, line = dry_run(capsys, *argv, "--seeds", "0", "--out", str(tmp_path / "o"))
    assert code == 0 and line.startswith("engine: gymnasium (") and why in line, line


def test_an_engine_asked_for_is_the_engine_used(capsys, tmp_path):
    code, line = dry_run(capsys, "pendulum", "--engine", "gymnasium", "--out", str(tmp_path / "o"))
    assert (code, line) == (0, "engine: gymnasium (--engine gymnasium)")


@pytest.mark.parametrize("run, engine", [(GYMNASIUM_RUN, "gymnasium"), (COMPILED_RUN, "compiled")])
def test_config_reruns_a_recorded_run_on_the_engine_that_made_it(run, engine, capsys, tmp_path):
    code, line = dry_run(capsys, "cartpole", "--config", str(run / "config.json"), "--out", str(tmp_path / "o"))
    assert (code, line) == (0, f"engine: {engine} (the engine that made --config's run)")


def test_a_set_stays_on_the_engine_it_started_on(capsys, tmp_path):
    """New seeds added to a set made on the Gymnasium loop run there too, as the seeds it keeps;
    overwriting the only seed that held the set's engine frees the choice."""
    out = tmp_path / "set"
    extracted(GYMNASIUM_RUN, out / "seed_3")
    code, line = dry_run(capsys, "cartpole", "--seeds", "4-5", "--out", str(out))
    assert code == 0 and line.startswith("engine: gymnasium (the engine of the runs already in"), line
    code, line = dry_run(capsys, "cartpole", "--seeds", "3", "--overwrite", "--out", str(out))
    assert code == 0 and line.startswith("engine: compiled (certified"), line


def test_a_set_of_two_engines_is_refused_naming_both(capsys, tmp_path):
    out = tmp_path / "mixed"
    extracted(GYMNASIUM_RUN, out / "seed_3")
    extracted(COMPILED_RUN, tmp_path / "c" / "seed_3")
    (tmp_path / "c" / "seed_3").rename(out / "seed_4")
    code, err = dry_run(capsys, "cartpole", "--seeds", "5", "--out", str(out))
    assert code == 2
    assert "holds runs of more than one engine" in err and "compiled engine: seed_4" in err
    assert "gymnasium engine: seed_3" in err and "--engine" in err
    code, line = dry_run(capsys, "cartpole", "--seeds", "5", "--engine", "compiled", "--out", str(out))
    assert code == 0 and line == "engine: compiled (--engine compiled)"


def test_a_killed_run_resumes_on_the_engine_its_checkpoint_names(capsys, tmp_path):
    """A seed killed before it wrote a summary holds only its checkpoint: that names the engine."""
    from keras_rl.runs.checkpoint import VERSION, write_checkpoint

    seed_dir = tmp_path / "k" / "seed_0"
    seed_dir.mkdir(parents=True)
    write_checkpoint(seed_dir, {"version": VERSION, "batch": [0], "vector_step": 7, "engine": "gymnasium"})
    assert recorded_engine(seed_dir) == "gymnasium"
    code, line = dry_run(capsys, "pendulum", "--seeds", "0", "--resume", "--out", str(tmp_path / "k"))
    assert code == 0 and line.startswith("engine: gymnasium (the engine of the runs already in"), line


def test_every_committed_set_names_the_engine_its_manifest_entry_records():
    """What ``--config`` and the set rule read (``recorded_engine``) is what the manifest, and
    through it the audit's reruns, record for every committed set."""
    entries = json.loads((RESULTS / "MANIFEST.json").read_text())
    entries = entries["sets"] if isinstance(entries, dict) else entries
    assert len(entries) > 50
    for entry in entries:
        first = RESULTS / entry["set"] / f"seed_{entry['seeds'][0]}"
        assert recorded_engine(first) == entry["engine"], entry["set"]


def test_the_api_and_the_command_share_one_default():
    from keras_rl import api
    from keras_rl.commands.flags import FLAGS
    from keras_rl.dispatch.options import AUTO, RunOptions

    assert inspect.signature(api.reproduce).parameters["engine"].default == AUTO
    assert FLAGS["--engine"]["default"] == AUTO == RunOptions().engine


def test_the_maintainers_commands_that_make_runs_name_their_engine():
    """The calibration's run commands (``calibrate/runs.engine_args``) and the findings table's
    commands name the engine their sets were made on, so that ``auto`` changes none of them."""
    from importlib import import_module

    from keras_rl.check.rules import CALIBRATED_TIERS, RULES

    runs = import_module("maintainers.calibrate.runs")
    for post in ("pendulum", "cartpole", "mountaincar"):
        for batch in (1, 10):
            args = runs.engine_args(post, batch)
            assert args[args.index("--engine") + 1] == RULES[(post, CALIBRATED_TIERS[0])].engine
    findings = import_module("maintainers.tables.findings")
    assert "--engine gymnasium" in findings.row_command("pendulum", "faithful", "keras", False, "0-29")
