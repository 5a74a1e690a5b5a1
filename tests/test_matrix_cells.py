"""The version matrix's cells ask pip for what they say: the torch extra only where the cell keeps
the pinned CPU wheel, the nightlies by their package names, and the machine's cap on torch lifted
only for a cell that needs another PyTorch, keeping the rest of pip's configuration."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _cells():
    spec = importlib.util.spec_from_file_location("matrix_cells", ROOT / "matrix" / "cells.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


cells = _cells()


def test_the_reference_keeps_the_torch_extra_and_pip_as_configured():
    (command,), env = cells.install_commands("reference", cells.CELLS["reference"], "py")
    assert command[:6] == ["py", "-m", "pip", "install", "--quiet", "-e"]
    assert command[6] == ".[test,torch]"
    assert sorted(command[7:]) == ["gymnasium==1.4.0", "keras==3.15.1", "numpy==2.4.6", "tensorflow==2.21.0"]
    assert env is None


def test_a_pytorch_cell_drops_the_extra_and_asks_for_its_release(monkeypatch):
    monkeypatch.setattr(cells, "lift_torch_cap", lambda python: {"lifted": python})
    (command,), env = cells.install_commands("torch2.14.1", cells.CELLS["torch2.14.1"], "py")
    assert command[6] == ".[test]" and "torch==2.14.1" in command[7:]
    assert env == {"lifted": "py"}
    (newest,), env = cells.install_commands("newest", cells.CELLS["newest"], "py")
    assert newest[6:] == [".[test]", "torch"] and env == {"lifted": "py"}


def test_a_release_past_the_projects_ranges_goes_over_its_install():
    """TensorFlow 2.22 and the nightlies lie outside setup.cfg's ranges: the project installs
    first with the factors that fit, then the release goes over it as a user's upgrade would; the
    nightlies replace the packages the project brought, which go first."""
    (project, over), env = cells.install_commands("tf2.22.0rc0", cells.CELLS["tf2.22.0rc0"], "py")
    assert project[6:] == [".[test,torch]", "gymnasium==1.4.0"]
    assert over[3:] == ["install", "--quiet", "tensorflow==2.22.0rc0"] and env is None
    (project, uninstall, over), env = cells.install_commands("nightly", cells.CELLS["nightly"], "py")
    assert project[6:] == [".[test,torch]", "gymnasium==1.4.0"]
    assert uninstall[3:] == ["uninstall", "--quiet", "--yes", "tensorflow", "keras"]
    assert over[5:] == ["tf-nightly==2.23.0.dev20261026", "keras-nightly==3.16.0.dev2026102704"]
    assert env is None


def test_every_cell_names_every_factor():
    for name, spec in cells.CELLS.items():
        assert set(spec) == set(cells.FACTORS), name


def test_lifting_the_cap_keeps_every_setting_but_the_constraint(monkeypatch):
    listed = (
        "global.constraint='/etc/xdg/pip/constraints.txt'\n"
        "global.extra-index-url='file:///a/simple file:///b/simple'\n"
        "install.no-cache-dir='1'\n"
        ":env:.find-links='/opt/wheels'\n"
    )

    class Done:
        stdout = listed

    monkeypatch.setattr(cells.subprocess, "run", lambda *a, **k: Done())
    monkeypatch.delenv("PIP_EXTRA_INDEX_URL", raising=False)
    monkeypatch.delenv("PIP_NO_CACHE_DIR", raising=False)
    env = cells.lift_torch_cap("py")
    assert env["PIP_CONFIG_FILE"] == os.devnull
    assert env["PIP_EXTRA_INDEX_URL"] == "file:///a/simple file:///b/simple"
    assert env["PIP_NO_CACHE_DIR"] == "1"
    assert "PIP_CONSTRAINT" not in env or env["PIP_CONSTRAINT"] == os.environ.get("PIP_CONSTRAINT")


def test_the_table_reads_a_twin_check_and_names_what_changed():
    """A cell checked with the twins shows the same bits where every twin kept them, the paired
    test's p elsewhere, and the versions and replaced packages the check named; a failed install
    gives pip's reason."""
    from maintainers.tables import compat

    environment = {
        "versions": {"tensorflow": {"was": "2.21.0", "now": "2.22.0-rc0"}},
        "replaced": {"keras": "keras-nightly"},
    }
    same = {"p": 1.0, "alpha": 0.01, "same_bits": True, "twins": 4, "identical": 4, "environment": environment}
    moved = {"p": 0.002, "alpha": 0.01, "same_bits": False, "twins": 80, "identical": 0, "environment": environment}
    cell = {
        "check": {
            "sensitive": {"exit_code": 1, "posts": {"pendulum": moved, "cartpole": same}},
            "torch": {"exit_code": 0, "posts": {"cartpole": {"p": 0.5, "alpha": 0.01}}},
        }
    }
    assert compat.check_text(cell, "cartpole") == "same bits (4/4 twins)"
    assert compat.check_text(cell, "pendulum") == "**changed** (p=0.002, 80 twins)"
    assert compat.check_text(cell, "mountaincar") == "**no verdict** (exit 1)"
    assert compat.torch_check_text(cell) == "consistent (p=0.5)"
    assert compat.changes_text(cell) == "tensorflow 2.21.0 -> 2.22.0-rc0; `keras` -> `keras-nightly`"
    smoke = {"check": {"smoke": {"exit_code": 0, "posts": {"cartpole": {"p": 0.79}}}, "rerun_at_full_tier": []}}
    assert compat.check_text(smoke, "cartpole") == "smoke: consistent (p=0.79)"
    assert compat.torch_check_text(smoke) == "not run" and compat.changes_text(smoke) == "not recorded"
    failed = {"error": "Looking in indexes: ...\nERROR: No matching distribution found for numpy==2.5.*\n"}
    assert compat.install_failure(failed) == "**failed**: No matching distribution found for numpy==2.5.*"


def test_a_cell_stopped_before_its_last_step_shows_what_it_ran(tmp_path, monkeypatch):
    """A cell stopped midway (no cell.json) is read from the steps it finished; the rest show as
    not run yet, and its cost says so far."""
    import json

    from maintainers.tables import compat

    folder = tmp_path / "tf9.9"
    folder.mkdir()
    (folder / "install.json").write_text(json.dumps({"spec": {"tensorflow": "9.9"}, "exit_code": 0, "seconds": 60}))
    tests = {"exit_code": 0, "tests": 3, "failures": 0, "errors": 0, "skipped": 0, "passed": 3, "step_seconds": 120}
    (folder / "tests.json").write_text(json.dumps(tests))
    monkeypatch.setattr(compat, "COMPAT", tmp_path)
    ((name, install, cell),) = compat.load_cells()
    assert cell["partial"] and cell["seconds"] == 180
    row = compat.table().splitlines()[-1]
    assert row.startswith("| tf9.9 | 9.9 |") and "| 3 passed |" in row and row.endswith("| 3 (so far) |")
    assert row.count("not run yet") == 11  # env parity, 3 replays, first numbers, 3 checks, PyTorch, changes, speed
    assert compat.short_table().splitlines()[-1] == "| TensorFlow | tf9.9: tests all passed; not run yet; not run yet |"


def test_a_cell_run_with_only_runs_those_steps_and_writes_no_cell_json_until_every_step_is_done(tmp_path, monkeypatch):
    """``compat_cell.py --only versions --only check`` (a cell's verdict first, issue 70) runs those
    two steps and leaves the others for a later run, which runs just them and writes ``cell.json``."""
    import json
    import sys

    monkeypatch.syspath_prepend(str(ROOT / "matrix"))  # as the script runs: its cells.py beside it
    spec = importlib.util.spec_from_file_location("compat_cell", ROOT / "matrix" / "compat_cell.py")
    cell = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cell)
    ran = []
    for step in cell.STEPS:
        monkeypatch.setattr(cell, f"step_{step}", lambda *args, step=step: ran.append(step) or {"step": step})
    monkeypatch.setattr(cell, "_commit", lambda: "0123abcd")
    python, out = tmp_path / "python", tmp_path / "cell"
    python.write_text("")
    argv = ["compat_cell.py", "--cell", "x", "--spec", "{}", "--reference-python", str(python), "--out", str(out)]
    monkeypatch.setattr(sys, "argv", [*argv, "--only", "check", "--only", "versions"])
    cell.main()
    assert ran == [s for s in cell.STEPS if s in ("versions", "check")] and len(cell.STEPS) > 2
    assert not (out / "cell.json").exists()
    ran.clear()
    monkeypatch.setattr(sys, "argv", argv)
    cell.main()
    assert ran == [s for s in cell.STEPS if s not in ("versions", "check")]  # the two are not run again
    made = json.loads((out / "cell.json").read_text())
    assert all(made[s]["step"] == s and made[s]["commit"] == "0123abcd" for s in cell.STEPS)
