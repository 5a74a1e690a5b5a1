"""``keras-rl check --framework torch`` (issue 70, item 3): the PyTorch rule of post 003, its
baseline, its rates measured on committed real runs, and its refusals before anything trains."""

from __future__ import annotations

import importlib.util
import json

from keras_rl.check import command
from keras_rl.check.rules import TORCH_RULES, rule_for
from keras_rl.cli import main


def test_a_post_without_a_pytorch_rule_and_an_install_without_pytorch_are_refused_by_name(
    tmp_path, capsys, monkeypatch
):
    argv = ["check", "--framework", "torch", "--dry-run", "--out", str(tmp_path / "out")]
    assert main([*argv[:1], "pendulum", *argv[1:]]) == 2
    err = capsys.readouterr().err
    assert "no rule for pendulum at the smoke tier; it checks cartpole --tier smoke" in err
    assert main([*argv[:1], "cartpole", *argv[1:], "--tier", "sensitive"]) == 2
    assert "no rule for cartpole at the sensitive tier" in capsys.readouterr().err
    assert main([*argv[:1], "cartpole", *argv[1:], "--framework", "jax"]) == 2
    assert "unknown framework 'jax'" in capsys.readouterr().err
    assert main([*argv[:1], "cartpole", *argv[1:], "--sequential"]) == 2
    assert "--framework torch has no sequential design" in capsys.readouterr().err
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a))
    assert main([*argv[:1], "cartpole", *argv[1:]]) == 2  # a Keras-only install, before any training
    assert "pip install 'keras-rl-repro[torch]'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_pytorch_plan_names_its_engine_its_baseline_and_its_real_run_rates(tmp_path, capsys):
    assert main(["check", "cartpole", "--framework", "torch", "--dry-run", "--out", str(tmp_path / "o")]) == 0
    plan = capsys.readouterr().out
    assert "fresh seeds 1000-1009 (10) on the vectorised-compiled engine against a baseline of 200" in plan
    assert "against real changes of the algorithm: pytorch/tutorials #3080's values" in plan
    assert "(torch.json)" in plan and "calibration.json" not in plan
    rule = rule_for("cartpole", "smoke", "torch")
    assert rule.framework == "torch" and command.error_rates(rule) is not None
    assert command.error_rates(rule_for("cartpole", "smoke")) != command.error_rates(rule)  # Keras' own
    # the baseline is compared with the PyTorch faithful config (the run from the wheel said "framework:
    # 'torch' -> 'keras'", comparing it with Keras')
    from keras_rl.registry import get_experiment

    assert command.config_changes(get_experiment("cartpole"), command.BASELINES / "cartpole" / rule.baseline) == []


def test_a_pytorch_report_names_where_its_power_was_measured(tmp_path):
    rule = rule_for("cartpole", "smoke", "torch")
    result = command.CheckResult(
        "cartpole",
        rule,
        {s: 120.0 for s in range(200)},
        {s: 118.0 for s in range(1000, 1010)},
        command.Decision(0.4, False, "Mann-Whitney U (two-sided)", 0.0),
        [],
        command.error_rates(rule),
    )
    command.write_report(tmp_path, [result], "smoke", command="keras-rl check cartpole --framework torch")
    text = (tmp_path / "check.md").read_text()
    assert "measured against real changes of the algorithm (the least shown) (torch.json)" in text
    assert "calibration.json)." not in text and "keras_rl/check/torch.json" in text


def test_the_pytorch_rates_are_what_committed_runs_give(tmp_path):
    """torch.json and calibration.md's block regenerate from the committed runs, as the plan said."""
    from maintainers.calibrate import torch as calibrate

    data = calibrate.compute()
    assert data == json.loads(command.TORCH_RATES.read_text())
    assert calibrate.render(data) in (calibrate.CHECKS / "calibration.md").read_text()
    assert f"{calibrate.DOCS_BEGIN}\n{calibrate.summary(data)}\n{calibrate.DOCS_END}" in calibrate.DOCS.read_text()
    for (post, tier), rule in TORCH_RULES.items():
        entry = data[post][tier]
        assert entry["rule"] == command.rule_fields(rule) and entry["baseline_seeds"] == 200
        assert all(r["true_shift"] > 1.1 for r in entry["real_power"].values())  # the fixes move it 2-3x
        assert entry["false_alarm_rate"] == max(r["resampled"] for r in entry["false_alarms"].values())
