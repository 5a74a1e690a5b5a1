"""The sensitive tier's sizing (``reproductions/sensitive_plan.py``) and its held-out report
(``reproductions/sensitive_held_out.py``), on committed runs whose answer is known."""

from __future__ import annotations

import importlib.util
import re
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "reproductions" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_plans_power_is_alpha_without_a_shift_and_grows_with_the_shift(monkeypatch):
    plan = load("sensitive_plan")
    monkeypatch.setattr(plan, "REPS", 300)
    episodes, budget, _ = plan.source()
    rng = np.random.default_rng(0)
    assert plan.power(episodes, budget, 40, 200, 1.0, rng) < 0.03  # alpha 0.0033, 300 draws
    small, large = (plan.power(episodes, budget, 40, 200, s, rng) for s in (1.05, 1.30))
    assert small < 0.6 and large > 0.99


def test_the_held_out_report_flags_a_slow_mutant_and_not_the_baseline_itself(tmp_path, monkeypatch):
    report = load("sensitive_held_out")
    mutants = tmp_path / "held-out-compiled"
    # the baseline's own seeds 100-199 as a "mutant" that changes nothing, and the committed
    # Gymnasium-loop runs of critic_lr x0.3 (median 191 episodes against 126) as one that does
    first_hundred = {f"seed_{i}" for i in range(100)}
    shutil.copytree(report.BASELINE, mutants / "buffer_x0.5", ignore=lambda d, names: first_hundred & set(names))
    committed = ROOT / "results" / "checks" / "pendulum" / "held-out" / "critic_lr_x0.3"
    shutil.copytree(committed, mutants / "critic_lr_x0.3")
    monkeypatch.setattr(report, "MUTANTS", mutants)
    monkeypatch.setattr(report, "DRAWS", 400)
    rows = {line.split("|")[1].strip(): line for line in report.table().splitlines() if line.startswith("| ")}
    same, slow = rows["buffer_x0.5"].split("|"), rows["critic_lr_x0.3"].split("|")
    assert 0.9 < float(re.search(r"\(x([0-9.]+)\)", same[4]).group(1)) < 1.1
    assert float(same[5]) < 0.05 and same[6].strip().startswith("0/2 ")
    assert float(slow[5]) > 0.95 and "none: fewer than 40 seeds" in slow[6]  # 30 seeds: no disjoint check of 40
    assert "not run" in rows["batch_32"]
