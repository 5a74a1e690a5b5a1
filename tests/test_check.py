"""``keras-rl check``: the statistics, the decision, the error-rate estimates and the command's refusals."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from keras_rl.check.rules import MUTANTS, RULES
from keras_rl.check.statistics import decide, detectable_shift, false_alarm_rate, power, seed_statistic


def rows(metrics, scores=None):
    scores = scores if scores is not None else metrics
    return [{"episode": i + 1, "score": s, "metric": m} for i, (m, s) in enumerate(zip(metrics, scores))]


def above(threshold):
    return lambda m: m is not None and np.isfinite(m) and m > threshold


def test_statistics_of_a_seed_by_hand():
    run = rows([-900, -600, -350, -290, -250])  # crosses > -300 at episode 4
    assert seed_statistic("episodes_to_threshold", run, 10, above(-300)) == 4
    assert seed_statistic("success", run, 10, above(-300)) == 1.0
    assert seed_statistic("success", run, 3, above(-300)) == 0.0  # cut to 3 episodes: not yet
    assert seed_statistic("episodes_to_threshold", run, 3, above(-300)) == 4  # censored at 3 + 1
    # the mean score; a run stopped at the threshold counts its last metric for the episodes it did not play
    scored = rows([-900, -600, -350, -290, -250], scores=[-1000, -500, -300, -200, -100])
    assert seed_statistic("auc", scored, 7, above(-300)) == pytest.approx((-1000 - 500 - 300 - 200 - 100 - 250 * 2) / 7)
    assert seed_statistic("auc", scored, 2, above(-300)) == pytest.approx(-750)
    assert seed_statistic("final_metric", run, 7, above(-300)) == -250
    assert seed_statistic("final_metric", run, 2, above(-300)) == -600
    # judged at the end (post 001): only the last metric counts, and only for a complete run
    end = rows([5.0, 1.0, 3.0])
    assert seed_statistic("success", end, 3, lambda m: m <= 2, success_at_end=True) == 0.0
    assert seed_statistic("success", end[:2], 2, lambda m: m <= 2, success_at_end=True) == 1.0
    with pytest.raises(ValueError, match="unknown statistic"):
        seed_statistic("median", run, 5, above(-300))


def test_decide_flags_a_shift_in_either_direction_and_not_a_resample():
    rng = np.random.default_rng(0)
    base = rng.normal(130, 20, 30)
    assert not decide(base, rng.normal(130, 20, 10), "episodes_to_threshold", 0.01).changed
    assert decide(base, rng.normal(200, 20, 10), "episodes_to_threshold", 0.01).changed  # slower
    assert decide(base, rng.normal(60, 20, 10), "episodes_to_threshold", 0.01).changed  # faster: a change too
    fisher = decide(np.ones(30), np.zeros(10), "success", 0.01)
    assert fisher.changed and fisher.test.startswith("Fisher")
    assert not decide(np.ones(30), np.ones(10), "success", 0.01).changed
    assert decide(base, [np.nan] * 10, "auc", 0.01).changed  # runs that blew up changed
    assert decide(np.ones(30), [1.0] * 9 + [np.nan], "success", 0.01).changed  # for every statistic
    assert not decide([5.0] * 30, [5.0] * 10, "auc", 0.01).changed  # nothing to tell apart


@pytest.mark.slow
def test_the_false_alarm_rate_of_a_resampled_sample_is_about_alpha():
    base = np.random.default_rng(1).normal(size=30)
    rate = false_alarm_rate(base, 10, "auc", 0.05, repeats=2000)
    assert 0.02 < rate < 0.08, rate  # an exact test at alpha 0.05 on exchangeable draws
    assert false_alarm_rate(base, 10, "auc", 0.01, repeats=2000) < rate


def test_power_grows_with_the_shift_and_the_detectable_shift_is_found():
    base = np.random.default_rng(2).normal(130, 25, 30).round()
    small, large = (
        power(base, base + 5, 10, "episodes_to_threshold", 0.01, repeats=300),
        power(base, base + 60, 10, "episodes_to_threshold", 0.01, repeats=300),
    )
    assert small < 0.3 and large > 0.95
    shift = detectable_shift(base, 10, 0.01, budget=1000, repeats=200)
    assert shift is not None and 5 < shift < 60
    assert power(base, base + shift, 10, "episodes_to_threshold", 0.01, repeats=300) >= 0.7


def test_every_rule_is_well_formed_and_every_post_has_five_mutants_some_gross():
    from keras_rl.registry import get_experiment

    for (name, _tier), rule in RULES.items():
        experiment = get_experiment(name)
        assert rule.statistic in rule.candidates and rule.alpha in (0.01, 0.005)
        assert not set(rule.seed_list()) & set(range(30)), "fresh seeds must not be the baseline's"
        experiment.config_cls.for_variant("faithful", episodes=rule.episodes)  # a valid budget
    for name, mutants in MUTANTS.items():
        assert len(mutants) >= 5 and any(m.gross for m in mutants) and any(not m.gross for m in mutants)
        base = get_experiment(name).config_cls.for_variant("faithful")
        for m in mutants:  # every mutant is a valid config that differs from the faithful one
            changed = base.with_text_overrides([f"{k}={v}" for k, v in m.overrides.items()])
            assert changed != base, m.name


def _cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "keras_rl", "check", *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


@pytest.mark.slow
def test_check_refuses_bad_input_with_exit_2_and_touches_nothing(tmp_path):
    proc = _cli("pendulum", "--tier", "medium", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "unknown tier 'medium'" in proc.stderr
    proc = _cli("breakout", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "breakout" in proc.stderr
    proc = _cli("pendulum", "--against", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "no baseline at" in proc.stderr
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    baseline = tmp_path / "against" / "pendulum" / "baseline" / "seed_0"
    _fake_baseline_seed(baseline)
    proc = _cli("pendulum", "--against", str(tmp_path / "against"), "--out", str(foreign))
    assert proc.returncode == 2 and "not a check's output" in proc.stderr
    assert (foreign / "notes.txt").read_text() == "keep me"
    proc = _cli("pendulum", "--against", str(tmp_path / "against"), "--seeds", "0-3", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "baseline's own" in proc.stderr
    proc = _cli("pendulum", "--against", str(tmp_path / "against"), "--set", "seed=4", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "seed" in proc.stderr
    assert not (tmp_path / "o").exists()


def _fake_baseline_seed(seed_dir, seed=0):
    """A finished faithful pendulum run folder of three episodes (written with the project's own writers)."""
    from keras_rl.registry import get_experiment
    from keras_rl.runs.files import RunRecorder
    from keras_rl.runs.loop import SeedRun

    exp = get_experiment("pendulum")
    config = exp.config_cls.for_variant("faithful", seed=seed)
    recorder = RunRecorder(seed_dir, ("critic_loss", "actor_loss"))
    recorder.write_config(config.to_dict())
    run = SeedRun(exp, config, recorder, exp.make_metric(config), "test")
    from keras_rl.agents.skeleton import EpisodeStats

    for episode, score in enumerate([-1200.0, -800.0, -250.0], 1):
        run.record_episode(episode, score, 200, EpisodeStats(0, {"critic_loss": None, "actor_loss": None}))
    run.summary("completed").write(seed_dir)


def test_each_calibrated_rule_is_the_one_the_pre_registered_criterion_picks():
    """``reproductions/check_calibrate.py --write`` measured every candidate; the rule in
    ``rules.py`` must be the one its criterion picks, with false alarms at most 1%."""
    from keras_rl.check.command import CALIBRATION

    measured = json.loads(CALIBRATION.read_text())
    assert measured, "no rule calibrated yet"
    for name, entry in measured.items():
        for tier, result in entry["tiers"].items():
            if "not_calibrated" in result:
                continue
            rule = RULES[(name, tier)]
            assert result["chosen"] == {"statistic": rule.statistic, "alpha": rule.alpha}, (
                name,
                tier,
                result["chosen"],
            )
            mine = next(c for c in result["candidates"] if (c["statistic"], c["alpha"]) == (rule.statistic, rule.alpha))
            assert mine["false_alarm_rate"] <= 0.01 and (mine["seeds"], mine["episodes"]) == (rule.seeds, rule.episodes)


@pytest.mark.slow
def test_the_smoke_tier_finds_every_post_consistent_with_its_committed_baseline(tmp_path):
    """``keras-rl check --tier smoke`` on this code: fresh seeds of all three posts against
    the committed baselines. The rule's measured false-alarm rate (results/checks/calibration.md)
    is at most 1% per post, so this fails on an unchanged learner about once in a hundred
    code bases, and on a grossly broken one (the smoke tier's measured power) nearly always.
    It replaces the k-of-n threshold tests of posts 000, 001 and 003 (Keras)."""
    out = tmp_path / "check"
    proc = subprocess.run(
        [sys.executable, "-m", "keras_rl", "check", "--tier", "smoke", "--no-progress", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    assert proc.returncode == 0, (proc.stdout, proc.stderr[-3000:])  # before the report: a crash shows its stderr
    report = json.loads((out / "check.json").read_text())
    assert [e["experiment"] for e in report["experiments"]] == ["pendulum", "cartpole", "mountaincar"]
    for e in report["experiments"]:
        assert e["verdict"] == "consistent" and len(e["baseline"]) == 30 and len(e["new"]) == e["rule"]["seeds"]
        assert not set(e["new"]) & set(e["baseline"])  # fresh seeds
        assert (out / e["experiment"] / "check.png").is_file()
    assert (out / "check.md").read_text().count("consistent") == 3


def test_results_readme_states_the_calibrated_error_rates():
    import importlib.util
    from pathlib import Path

    from keras_rl.check.command import CALIBRATION

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("check_calibrate", root / "reproductions" / "check_calibrate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    readme = (root / "results" / "README.md").read_text()
    stated = readme.split(module.RULES_BEGIN, 1)[1].split(module.RULES_END, 1)[0].strip()
    assert stated == module.rules_table(json.loads(CALIBRATION.read_text())), (
        "results/README.md is stale: run python reproductions/check_calibrate.py ... --write"
    )


def test_check_names_an_unknown_experiment_before_tensorflow_loads():
    """#23.10: `check cartpool` imported TensorFlow before saying the name was unknown."""
    import subprocess
    import sys

    code = (
        "import sys; from keras_rl.cli import main; rc = main(['check', 'cartpool']); "
        "print(rc, 'tensorflow' in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["2", "False"], proc.stderr
    assert "unknown experiment 'cartpool'; check knows pendulum, cartpole, mountaincar" in proc.stderr


def test_a_baseline_of_another_post_is_named_as_such():
    """#23.9: --against a folder holding another post's baseline listed unknown config fields."""
    from pathlib import Path

    from keras_rl.check.command import baseline_values
    from keras_rl.check.rules import rule_for
    from keras_rl.errors import RunFolderError
    from keras_rl.registry import get_experiment

    cartpole = Path(__file__).resolve().parent.parent / "results" / "checks" / "cartpole" / "baseline"
    with pytest.raises(RunFolderError, match="is a baseline of cartpole, not of pendulum"):
        baseline_values(get_experiment("pendulum"), rule_for("pendulum", "smoke"), cartpole)


@pytest.mark.parametrize("failure", ["no summary", "disk full"])
def test_check_that_cannot_decide_exits_3_not_changed_or_usage(failure, tmp_path, monkeypatch, capsys):
    """Exit 3 means "could not decide": a fresh seed that crashed or left nothing, or an OSError.
    Exit 1 is kept for "changed" and 2 for the user's input (issue #21, item 6)."""
    import keras_rl.runs.jobs as jobs
    from keras_rl.cli import EXIT_NO_VERDICT, main

    def fake_run_jobs(todo, backend, progress=True, after_job=None):
        if failure == "disk full":
            raise OSError(28, "No space left on device")
        return jobs.JobsOutcome()  # the seeds never wrote a thing

    monkeypatch.setattr(jobs, "run_jobs", fake_run_jobs)
    code = main(["check", "pendulum", "--workers", "1", "--no-progress", "--out", str(tmp_path / "check")])
    err = capsys.readouterr().err
    assert code == EXIT_NO_VERDICT == 3, err
    assert "no verdict" in err and ("left no readable summary" in err or "No space left" in err)
