"""Twin seeds (issue 70): the sensitive tier reruns seeds its baseline holds, says "the same bits"
where they reproduce it, and otherwise tests the paired differences. The rule is exercised on real
committed twins (an engine swap, a mutant) and on a real unchanged rerun; the report names what
changed around the code (versions, a replaced package, the CPU)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from committed import RESULTS, copy_seeds

import keras_rl.check.command as command
from keras_rl.check.rules import RULES, rule_for
from keras_rl.check.statistics import decide_paired, paired_changed_many, paired_differences
from keras_rl.errors import ConfigError
from keras_rl.registry import get_experiment
from keras_rl.runs.run_set import RunSet

HOLM_FIRST = 0.01 / 3


def _twins(post: str, folder: Path, seeds: range) -> tuple[list[float], list[float], command.TwinReading]:
    """The baseline's and ``folder``'s statistic for ``seeds``, and what their bits say."""
    rule, experiment = rule_for(post, "sensitive"), get_experiment(post)
    base, other = RunSet(RESULTS / "checks" / post / rule.baseline), RunSet(folder)
    b_rows = {s: base.run(s).rows() for s in seeds}
    o_rows = {s: other.run(s).rows() for s in seeds}
    b = [command._statistic(experiment, rule, b_rows[s]) for s in seeds]
    o = [command._statistic(experiment, rule, o_rows[s]) for s in seeds]
    return b, o, command.read_twins(b_rows, o_rows, list(seeds))


def test_a_real_change_of_arithmetic_parts_the_bits_and_the_paired_test_reads_no_change():
    """The engine swap keeps the algorithm and changes every kernel: post 000's Gymnasium-loop seeds
    0-79 part from the compiled baseline's bits, and the paired test on the rule's 80 twins does not
    call it a change at Holm's first level."""
    b, o, reading = _twins("pendulum", RESULTS / "engines" / "pendulum" / "gymnasium", range(80))
    assert not reading.same_bits and reading.identical < reading.compared == 80
    assert "the paired test decides" in reading.text()
    decision = decide_paired(b, o, "episodes_to_threshold", HOLM_FIRST)
    assert not decision.changed and decision.p > 0.05, decision


def test_a_real_mutant_on_twin_seeds_is_flagged():
    """``broadcast_target_off`` (quirk P000-BROADCAST off; median x1.45 on seeds 0-29) run on the
    baseline's seeds: every twin parts, and 30 twins flag it at Holm's first level."""
    b, o, reading = _twins("pendulum", RESULTS / "checks" / "pendulum" / "mutants" / "broadcast_target_off", range(30))
    assert reading.identical == 0
    decision = decide_paired(b, o, "episodes_to_threshold", HOLM_FIRST)
    assert decision.changed and decision.p < 1e-4, decision


def test_the_paired_test_reads_ratios_and_drops_twins_that_did_not_move():
    base = np.array([100.0, 120, 130, 140, 150, 160, 170, 180, 190, 200])
    assert np.allclose(paired_differences(base, base * 1.1, "episodes_to_threshold"), math.log(1.1))
    assert decide_paired(base, base, "episodes_to_threshold", 0.01).p == 1.0  # nothing moved
    slower = decide_paired(base, base * 1.1, "episodes_to_threshold", 0.01)
    assert slower.changed and slower.p == pytest.approx(2 / 2**10)  # every twin one way: the exact floor
    # a twin that blew up is a change in itself; success reads the discordant twins' signs
    assert decide_paired(base, np.r_[base[:-1], np.nan], "episodes_to_threshold", 0.01).changed
    ones, zeros = np.ones(12), np.zeros(12)
    assert decide_paired(ones, zeros, "success", 0.01).changed
    # the vectorised form agrees with the one-at-a-time one
    rng = np.random.default_rng(0)
    d = np.round(rng.normal(0.05, 0.2, (50, 30)), 2)
    d[0] = 0.0
    pairs = [(np.full(30, 100.0), np.round(100.0 * np.exp(row))) for row in d]  # whole episodes, with ties
    one = [decide_paired(b, n, "episodes_to_threshold", 0.05).changed for b, n in pairs]
    many = paired_changed_many(np.stack([paired_differences(b, n, "episodes_to_threshold") for b, n in pairs]), 0.05)
    assert many.tolist() == one and 5 < sum(one) < 45


def test_bits_are_compared_exactly_but_for_wall_time():
    rows = [{"episode": 1, "score": -1.5, "metric": float("nan"), "loss": None, "wall_seconds": 1.0}]
    again = [dict(rows[0], wall_seconds=2.0)]
    assert command.first_difference(rows, again) is None  # NaN equals NaN, wall time aside
    assert command.first_difference(rows, [dict(rows[0], score=-1.5000000000000002)]) == 1
    assert command.first_difference(rows, rows + again) == 2  # a longer run parts where the other ended
    reading = command.read_twins({0: rows, 1: rows}, {0: again, 1: rows + again}, [0, 1])
    assert reading.parted == {1: 2} and not reading.same_bits
    assert command.read_twins({0: rows}, {0: again}, [0]).text() == "the same bits as the baseline for 1 of 1 seeds"
    # a rerun that stopped where its baseline seed first met the threshold is compared as far as it
    # played; one that ended anywhere else (a non-finite loss, another budget), played past its
    # baseline seed's end, or parted before it stopped, parts
    ended = [dict(rows[0], episode=k, score=-1.0) for k in (2, 3)]
    assert command.first_difference(rows + ended, rows, crossed_at=1) is None
    assert command.first_difference(rows + ended, rows) == 2
    assert command.first_difference(rows + ended, rows + ended[:1], crossed_at=1) == 3  # ended after it
    assert command.first_difference(rows + ended, rows, crossed_at=2) == 2  # ended before it: no stop
    assert command.first_difference(rows + ended, [], crossed_at=1) == 1
    assert command.first_difference(rows, rows + again, crossed_at=1) == 2
    assert command.first_difference(rows + ended, [ended[0]], crossed_at=1) == 1


def test_a_cartpole_twin_stopped_at_its_threshold_reads_the_same_bits_and_one_cut_short_parts():
    """Baseline seed 31 of post 003 meets 475 at episode 382 (a rerun stopped there gave those 382
    rows bit for bit); its first 382 rows read "the same bits", its first 381 (a run that ended
    on a non-finite loss) part at 382, and the plot's baseline is cut where a stopping run ends."""
    from keras_rl.check.command import BASELINES

    experiment = get_experiment("cartpole")
    full = {31: RunSet(BASELINES / "cartpole" / "baseline").run(31).rows()}
    assert command.first_crossing(experiment, full[31]) == 382 and len(full[31]) == 600
    stopped = command.read_twins(full, {31: full[31][:382]}, [31], experiment, stops=True)
    assert stopped.same_bits and stopped.text().endswith("(each to its threshold, or to its last episode)")
    assert not command.read_twins(full, {31: full[31][:382]}, [31], experiment, stops=False).same_bits
    cut = command.read_twins(full, {31: full[31][:381]}, [31], experiment, stops=True)
    assert cut.parted == {31: 382}
    assert len(command.as_played(experiment, full, True)[31]) == 382
    assert command.as_played(experiment, full, False) is full


def test_a_check_stops_a_solo_seed_at_its_threshold_where_that_settles_the_statistic():
    """Post 003's sensitive twins played 23% of their wall time after the threshold, which settles
    their episodes to it; a rerun of baseline seed 31 stopped there gave its first 382 rows bit for
    bit. Post 001's final metric needs every episode, and a seed batch (PyTorch's post 003) keeps
    its seeds to the end."""
    from keras_rl.check.statistics import settles_at_threshold

    assert settles_at_threshold("episodes_to_threshold") and settles_at_threshold("success")
    assert not settles_at_threshold("success", success_at_end=True) and not settles_at_threshold("final_metric")
    assert command.seeds_stop_at_threshold(rule_for("cartpole", "sensitive"))
    assert not command.seeds_stop_at_threshold(rule_for("mountaincar", "sensitive"))
    batched = replace(rule_for("cartpole", "sensitive"), seed_batch=10)  # a batch keeps its seeds whole
    assert not command.seeds_stop_at_threshold(batched)
    plan = command.describe_plan(rule_for("cartpole", "sensitive"), list(range(40)), 200, None)
    assert "episodes_to_threshold over 600 episodes, each seed stopping at its threshold if it gets there" in plan
    kept = command.describe_plan(rule_for("cartpole", "sensitive"), list(range(40)), 200, None, stopping=False)
    assert "stopping" not in kept  # --set stop_at_threshold=false: the plan says what runs


def test_a_baseline_without_the_twins_falls_back_to_fresh_seeds_and_says_so():
    rule = rule_for("pendulum", "sensitive")
    held = {s: 100.0 for s in range(200)}
    assert command.twin_seeds("pendulum", rule, rule.seed_list(), held, False) == (rule, rule.seed_list(), None)
    mine = {s: 100.0 for s in range(5)}  # a user's 5-seed baseline
    unpaired, fresh, why = command.twin_seeds("pendulum", rule, rule.seed_list(), mine, False)
    assert not unpaired.twins and fresh == list(range(4000, 4080))
    assert why is not None and "holds seeds 0-4 (5), not the twins 0-79" in why
    with pytest.raises(ConfigError, match="give one kind or the other"):
        command.twin_seeds("pendulum", rule, [3, 4, 5, 6], mine, True)
    with pytest.raises(ConfigError, match="it needs at least 8"):
        command.check_twin_count("pendulum", "episodes_to_threshold", 7, 0.01)
    command.check_twin_count("pendulum", "episodes_to_threshold", 8, 0.01)


def test_error_rates_are_claimed_only_for_the_committed_baseline(tmp_path):
    """Issue 72 item 6: ``check --against mybase`` (5 seeds) reported the committed baseline's power
    and false-alarm rate. For another baseline the result carries no rates, and its note gives the
    smallest p the test allows."""
    rule = rule_for("pendulum", "smoke")
    committed = command.BASELINES / "pendulum" / "baseline"
    assert command.committed_baseline(committed, rule)
    mine = tmp_path / "pendulum" / "baseline"
    mine.mkdir(parents=True)
    (mine / "runs.parquet").write_bytes(b"another set")
    result = command.CheckResult(
        "pendulum",
        rule,
        {s: 120.0 for s in range(5)},
        {s: 120.0 for s in range(1000, 1010)},
        command.Decision(0.5, False, "Mann-Whitney U (two-sided)", 0.0),
        [],
        command.error_rates(rule),
    )
    assert command.measured_for(committed, result) == {}
    fields = command.measured_for(mine, result)
    assert fields["error_rates"] is None
    assert (
        "not the committed one" in fields["baseline_note"] and "smallest p its test allows" in fields["baseline_note"]
    )
    report = tmp_path / "report"
    report.mkdir()
    command.write_report(report, [replace(result, **fields)], "smoke", command="keras-rl check pendulum --against mine")
    text = (report / "check.md").read_text()
    assert "not calibrated" in text and "The power column is the rule's" not in text
    assert "its test's size on this baseline" in text


def test_a_dry_run_against_another_baseline_quotes_no_committed_rate(tmp_path, capsys):
    """The same for ``--dry-run``, which quoted the committed baseline's rates for any (round four's pass)."""
    from keras_rl.cli import main

    committed = command.BASELINES / "pendulum" / "baseline"
    mine = tmp_path / "mine" / "pendulum" / "baseline"
    mine.mkdir(parents=True)
    (mine / "runs.parquet").write_bytes((committed / "runs.parquet").read_bytes())
    argv = ["check", "pendulum", "--tier", "smoke", "--dry-run", "--out", str(tmp_path / "out")]
    assert main([*argv, "--against", str(tmp_path / "mine")]) == 0  # byte for byte the committed one
    assert "measured false-alarm rate" in capsys.readouterr().out
    subset = tmp_path / "subset"
    copy_seeds(RESULTS / "checks" / "pendulum" / "baseline", subset / "pendulum" / "baseline", lambda s: s < 20)
    assert main([*argv, "--against", str(subset)]) == 0
    out = capsys.readouterr().out
    assert "measured false-alarm rate" not in out and "power" not in out
    assert "error rates not measured for this baseline" in out


def test_the_report_names_each_version_that_differs_a_replaced_package_and_the_cpus(monkeypatch):
    """TensorFlow 2.22.0rc0 swapped Keras for keras-nightly, and the check said only "consistent"."""
    baseline = {
        "versions": {"tensorflow": "2.21.0", "keras": "3.15.1", "numpy": "2.4.0", "python": "3.11.7"},
        "provenance": {"cpu_model": "AMD EPYC", "cpu_isa": ["avx2", "avx512f"]},
    }
    new = {
        "versions": {"tensorflow": "2.22.0rc0", "keras": "3.16.0.dev2026102704", "numpy": "2.4.0", "python": "3.11.7"},
        "provenance": {"cpu_model": "Intel Xeon", "cpu_isa": ["avx2"]},
    }
    monkeypatch.setattr(command, "providers", lambda versions: {"keras": "keras-nightly"})
    env = command.environment_changes(baseline, new)
    assert env["versions"] == {
        "tensorflow": {"was": "2.21.0", "now": "2.22.0rc0"},
        "keras": {"was": "3.15.1", "now": "3.16.0.dev2026102704"},
    }
    result = command.CheckResult(
        "pendulum", rule_for("pendulum", "smoke"), {}, {}, command.Decision(1, False, "t", 0), [], None, environment=env
    )
    (line,) = [line for line in command.environment_lines([result]) if line]
    assert "`tensorflow 2.21.0 -> 2.22.0rc0`" in line and "`keras 3.15.1 -> 3.16.0.dev2026102704`" in line
    assert "`keras` is provided by `keras-nightly`" in line
    assert "Intel Xeon (AVX2) against the baseline's AMD EPYC (AVX-512): another CPU" in line
    same = command.environment_changes(baseline, baseline)
    assert same["versions"] == {} and same["same_cpu"] and same["arithmetic"] is None
    fast = {
        **baseline,
        "provenance": {**baseline["provenance"], "environment": {"XLA_FLAGS": "--xla_cpu_enable_fast_math=true"}},
    }
    moved = command.environment_changes(baseline, fast)
    assert moved["arithmetic"] == {"baseline": {}, "new": {"XLA_FLAGS": "--xla_cpu_enable_fast_math=true"}}
    result = replace(result, environment=moved)
    (line,) = [line for line in command.environment_lines([result]) if line]
    assert "The arithmetic's environment differs: `{'XLA_FLAGS': '--xla_cpu_enable_fast_math=true'}`" in line


def test_a_run_records_the_environment_that_changes_its_arithmetic_only_where_set(monkeypatch):
    from keras_rl.runs.provenance import provenance

    for name in ("XLA_FLAGS", "TF_XLA_FLAGS", "TF_ENABLE_ONEDNN_OPTS"):
        monkeypatch.delenv(name, raising=False)
    assert "environment" not in provenance()  # the committed runs' summaries: nothing new in them
    monkeypatch.setenv("TF_ENABLE_ONEDNN_OPTS", "0")
    assert provenance()["environment"] == {"TF_ENABLE_ONEDNN_OPTS": "0"}


def test_providers_name_the_distribution_whose_version_the_import_reports(monkeypatch):
    """TensorFlow 2.22.0rc0 installs keras-nightly beside keras: both hold the ``keras`` import's
    files, and the import is keras-nightly's (its version). ``tf.__version__`` spells an rc
    ``2.22.0-rc0``."""
    import importlib.metadata

    monkeypatch.setattr(
        importlib.metadata,
        "packages_distributions",
        lambda: {"keras": ["keras", "keras-nightly"], "tensorflow": ["tensorflow"], "numpy": ["numpy"]},
    )
    installed = {
        "keras": "3.15.1",
        "keras-nightly": "3.16.0.dev2026102704",
        "tensorflow": "2.22.0rc0",
        "numpy": "2.4.6",
    }
    monkeypatch.setattr(importlib.metadata, "version", installed.__getitem__)
    now = {"keras": "3.16.0.dev2026102704", "tensorflow": "2.22.0-rc0", "numpy": "2.4.6"}
    assert command.providers(now) == {"keras": "keras-nightly"}
    assert command.providers({**now, "keras": "3.15.1"}) == {}


@pytest.mark.slow
def test_an_unchanged_install_says_the_same_bits_and_a_change_runs_every_twin(tmp_path, monkeypatch, capsys):
    """A real check: a baseline of 8 compiled seeds of 2 episodes made here (so on this host's bits),
    and a twin rule over it. Unchanged, its first 2 twins give the baseline's bits and the check stops
    there, "the same bits"; with ``--set noise_sigma=0.3`` they part and all 8 twins run."""
    from keras_rl.cli import main

    against = tmp_path / "against"
    made = main(
        [
            "reproduce", "pendulum", "--engine", "compiled", "--seeds", "0-7", "--episodes", "2", "--workers", "1",
            "--no-progress", "--min-success-rate", "0", "--out", str(against / "pendulum" / "baseline"),
        ]
    )  # fmt: skip
    assert made == 0
    rule = replace(RULES[("pendulum", "sensitive")], seeds=8, episodes=2, bits_seeds=2)
    monkeypatch.setitem(RULES, ("pendulum", "sensitive"), rule)
    args = ["check", "pendulum", "--tier", "sensitive", "--workers", "1", "--no-progress", "--against", str(against)]
    assert main([*args, "--out", str(tmp_path / "same")]) == 0
    said = capsys.readouterr().out
    assert "twins: the same bits as the baseline for 2 of 2 seeds" in said
    assert "versions that differ from the baseline's: none" in said
    report = json.loads((tmp_path / "same" / "check.json").read_text())
    (entry,) = report["experiments"]
    assert entry["pairing"] == "twins" and entry["twins"]["same_bits"] and sorted(entry["new"]) == ["0", "1"]
    report_md = (tmp_path / "same" / "check.md").read_text()
    assert "the same bits as the baseline for 2 of 2 seeds" in report_md
    # issue 72 item 7: an installed check points to what ships, never a checkout's files
    assert "python -m maintainers" not in report_md and "results/checks" not in report_md
    # the same bits need no measured rate: no note that the baseline is not the committed one
    assert entry["baseline_note"] is None

    assert main([*args, "--set", "noise_sigma=0.3", "--out", str(tmp_path / "moved")]) == 0  # 2 episodes: all 3s
    report = json.loads((tmp_path / "moved" / "check.json").read_text())
    (entry,) = report["experiments"]
    assert not entry["twins"]["same_bits"] and sorted(map(int, entry["new"])) == list(range(8))
    assert entry["decision"]["test"] == "Wilcoxon signed-rank on twins (two-sided)"
    assert "not the committed one" in entry["baseline_note"]


def test_calibration_md_states_the_twin_rates_twins_json_holds():
    """``python -m maintainers calibrate twins --write`` renders calibration.md's block from
    keras_rl/check/twins.json; a block edited by hand, or a json recomputed without it, fails here.
    The one size the check does not take from its plan (post 003 keeps 40 twins) is stated there."""
    from maintainers.calibrate import twins

    data = json.loads(command.TWIN_RATES.read_text())
    text = (RESULTS / "checks" / "calibration.md").read_text()
    stated = text.split(twins.BEGIN, 1)[1].split(twins.END, 1)[0].strip()
    assert stated == twins.render(data).strip(), "stale: python -m maintainers calibrate twins --write"
    for post, entry in data["posts"].items():
        rule = RULES[(post, "sensitive")]
        assert entry["rule"]["seeds"] == rule.seeds and entry["rule"]["statistic"] == rule.statistic, post
        picked = entry.get("statistic_choice")
        if picked and picked["n"] != rule.seeds:
            assert f"**The check keeps {rule.seeds} twins**" in stated
