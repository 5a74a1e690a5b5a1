"""``keras-rl compare`` and its statistics helpers."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from keras_rl.cli import main
from keras_rl.report.stats import fisher_exact, iqm, iqm_ci, mann_whitney, median_difference_ci, success_difference_ci
from keras_rl.runs.files import read_episodes


def test_mann_whitney_against_a_hand_computed_u():
    # a = [1, 2, 3] all below b = [4, 5]: U_a = 0; exact two-sided p = 2 * 1 / C(5, 2) = 0.2
    u, p = mann_whitney([1, 2, 3], [4, 5])
    assert u == 0 and p == pytest.approx(0.2)
    u, _ = mann_whitney([4, 5], [1, 2, 3])
    assert u == 6  # len(a) * len(b) - 0


def test_success_difference_ci_against_newcombes_published_example():
    # Newcombe (1998), Statistics in Medicine 17:873, table II example (a): 56/70 against
    # 48/80, method 10 (hybrid score): 0.0524 to 0.3339.
    d = success_difference_ci(56, 70, 48, 80)
    assert d.estimate == pytest.approx(0.2)
    assert (d.low, d.high) == (pytest.approx(0.0524, abs=5e-5), pytest.approx(0.3339, abs=5e-5))
    same = success_difference_ci(10, 10, 10, 10)  # 10/10 twice: no difference, yet an honest width
    assert same.estimate == 0 and same.low < -0.2 and same.high > 0.2
    assert success_difference_ci(0, 10, 10, 10).high < -0.5
    with pytest.raises(ValueError, match="successes"):
        success_difference_ci(3, 0, 1, 2)


def test_fisher_exact_against_a_hand_computed_p():
    # 10/10 vs 5/10: P(table) = C(10,10) C(10,5) / C(20,15) = 252 / 15504; the only other table
    # as unlikely is its mirror (5/10 vs 10/10), so the two-sided p is twice that
    assert fisher_exact(10, 10, 5, 10) == pytest.approx(2 * 252 / 15504)
    assert fisher_exact(3, 10, 3, 10) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="successes must lie in"):
        fisher_exact(11, 10, 0, 10)


def test_iqm_is_the_mean_of_the_middle_half():
    assert iqm([1, 2, 3, 4, 5, 6, 7, 8]) == pytest.approx(4.5)  # mean of 3, 4, 5, 6
    assert iqm([0, 0, 1, 100]) == pytest.approx(0.5)  # mean of 0, 1: robust to the 100


def test_bootstrap_intervals_with_a_fixed_rng_are_scipys_percentile_intervals():
    x = np.array([3.0, 7, 1, 9, 4, 4, 8, 2, 6, 5])
    ci = iqm_ci(x, np.random.default_rng(42), n_resamples=2000)
    ref = stats.bootstrap(
        (x,), iqm, n_resamples=2000, method="percentile", vectorized=False, random_state=np.random.default_rng(42)
    ).confidence_interval
    assert (ci.low, ci.high) == (ref.low, ref.high)
    assert ci.low <= ci.estimate <= ci.high and x.min() <= ci.low and ci.high <= x.max()
    assert iqm_ci(x, np.random.default_rng(42), n_resamples=2000) == ci  # same RNG, same interval


def test_median_difference_interval_of_separated_samples_excludes_zero():
    a, b = [10, 11, 12, 13, 14], [20, 21, 22, 23, 24]
    ci = median_difference_ci(a, b, np.random.default_rng(0), n_resamples=2000)
    assert ci.estimate == -10 and ci.high < 0 and ci.low >= -14  # every resample's difference lies in [-14, -6]
    same = median_difference_ci([5, 5, 5], [5, 5, 5])
    assert (same.estimate, same.low, same.high) == (0, 0, 0)


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    pytest.importorskip("torch", reason="compare needs the torch extra")
    root = tmp_path_factory.mktemp("cmp")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "keras_rl",
            "compare",
            "cartpole",
            "--seeds",
            "0-1",
            "--episodes",
            "20",
            "--runs",
            str(root / "runs"),
            "--out",
            str(root / "out"),
            "--workers",
            "1",  # in this process: tests/test_ray.py covers Ray, and a Ray instance here competed
            "--no-progress",  # with the other xdist worker for the two cores
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return root


def test_compare_writes_a_well_formed_report_whose_numbers_the_csvs_reproduce(compared):
    out = compared / "out" / "cartpole"
    report = (out / "report.md").read_text()
    for png in ("curves.png", "episodes_to_threshold.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "**Verdict.**" in report and "Mann-Whitney" in report
    assert "Fisher exact test (two-sided) p = 1." in report  # 0/2 vs 0/2
    result = json.loads((out / "result.json").read_text())  # the same numbers, for machines
    assert result["experiment"] == "cartpole" and result["fisher_p"] == 1.0 and result["matched_init"] is False
    assert result["verdict"] in report
    assert "Inconclusive at 2 seeds each" in report and "success 0/2 (Keras) vs 0/2 (PyTorch)" in report
    assert "margin -0.15 to 0.15, set before the runs" in report  # a TOST verdict, not "no detectable difference"
    for fw, folder in (("keras", "faithful"), ("torch", "faithful-torch")):
        finals, walls, ms = [], [], []
        for seed in (0, 1):
            run = compared / "runs" / "cartpole" / folder / f"seed_{seed}"
            rows = read_episodes(run / "episodes.csv")
            summary = json.loads((run / "summary.json").read_text())
            assert len(rows) == 20 and summary["framework"] == fw
            finals.append(rows[-1]["metric"])
            walls.append(summary["wall_seconds"])
            ms.append(summary["wall_seconds"] / summary["total_steps"] * 1e3)
        line = next(row for row in report.splitlines() if row.startswith(f"| {fw} |"))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[1] == "0/2"  # 20 episodes cannot reach a 100-episode mean of 475
        assert float(cells[4].split(" ")[0]) == pytest.approx(iqm(finals), abs=1e-3)
        assert float(cells[5]) == pytest.approx(np.median(walls), abs=0.05)
        assert float(cells[6]) == pytest.approx(np.median(ms), abs=5e-4)
        assert result["frameworks"][fw]["final_iqm"]["estimate"] == pytest.approx(iqm(finals))


def test_compare_reuses_matching_runs_and_refuses_mismatched_ones(compared, capsys, tmp_path):
    import shutil

    runs, out = tmp_path / "runs", tmp_path / "out2"
    shutil.copytree(compared / "runs", runs)  # it edits runs: the module's fixture stays as made
    args = [
        "compare",
        "cartpole",
        "--seeds",
        "0-1",
        "--episodes",
        "20",
        "--runs",
        str(runs),
        "--out",
        str(out),
        "--no-progress",
        "--reuse-only",
    ]
    assert main(args) == 0  # everything reusable: nothing runs
    assert (out / "cartpole" / "report.md").is_file()
    # a different config: refuse to mix, name the field
    assert main([*args[:4], "--episodes", "25", *args[6:]]) == 2
    assert "different config (episodes=20 here, 25 wanted)" in capsys.readouterr().err
    # mismatched seed sets
    assert main([*args[:3], "0-2", *args[4:]]) == 2
    err = capsys.readouterr().err
    assert "mismatched seed sets" in err and "keras lacks seeds [2]" in err
    # another code version
    summary_path = runs / "cartpole" / "faithful-torch" / "seed_1" / "summary.json"
    summary = json.loads(summary_path.read_text())
    summary["provenance"]["code_tree"] = "0" * 40  # made from other package files
    summary_path.write_text(json.dumps(summary))
    training = [a for a in args if a != "--reuse-only"]
    assert main(training) == 2  # a command that would train beside it refuses to mix
    assert re.search(
        r"made by code version 0{40}\S*, this is \S+; refusing to mix code versions", capsys.readouterr().err
    )
    # a report of the runs there trains nothing: it reports them, naming each code version
    assert main(args) == 0
    assert "torch 000000000000, " in (out / "cartpole" / "report.md").read_text()
    del summary["provenance"]  # a run from before commits were recorded
    summary_path.write_text(json.dumps(summary))
    assert main(training) == 2
    assert "(no commit recorded), this is" in capsys.readouterr().err


def test_compare_resumes_an_interrupted_seed_from_its_checkpoint_and_restarts_one_without(compared, tmp_path):
    """An interrupted run of the same config and code version goes on from its checkpoint, as
    ``reproduce --resume`` would (it was restarted from scratch before); without a checkpoint it
    starts again; finished ones are reused."""
    import shutil

    from keras_rl.dispatch.compare_runs import gather
    from keras_rl.registry import get_experiment
    from keras_rl.runs.checkpoint import VERSION, write_checkpoint

    runs = tmp_path / "runs"
    shutil.copytree(compared / "runs", runs)
    for seed, checkpointed in ((0, True), (1, False)):
        seed_dir = runs / "cartpole" / "faithful-torch" / f"seed_{seed}"
        summary = json.loads((seed_dir / "summary.json").read_text())
        (seed_dir / "summary.json").write_text(json.dumps({**summary, "status": "interrupted", "finished": False}))
        for old in seed_dir.glob("checkpoint*.pkl"):  # a finished solo run keeps its last one
            old.unlink()
        if checkpointed:
            write_checkpoint(seed_dir, {"version": VERSION, "batch": [seed], "vector_step": 5})
    jobs = gather(get_experiment("cartpole"), "faithful", [0, 1], runs, False, False, {"episodes": 20})
    assert [(j.config.framework, j.config.seed, j.start) for j in jobs] == [
        ("torch", 0, "resume"),
        ("torch", 1, "overwrite"),
    ]
    rerun = gather(get_experiment("cartpole"), "faithful", [0], runs, True, False, {"episodes": 20})
    assert {j.start for j in rerun} == {"overwrite"}  # --rerun replaces, checkpoint or not


def test_a_sweep_resumes_an_interrupted_seed_from_its_checkpoint(compared, tmp_path):
    """The same for ``sweep`` (it restarted interrupted seeds from scratch as well)."""
    import shutil

    from keras_rl.dispatch.sweep import GridPoint, sweep_jobs
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.runs.checkpoint import VERSION, write_checkpoint

    point = tmp_path / "sweep" / "episodes=20"
    for seed in (0, 1):
        shutil.copytree(compared / "runs" / "cartpole" / "faithful" / f"seed_{seed}", point / f"seed_{seed}")
    seed_dir = point / "seed_1"
    summary = json.loads((seed_dir / "summary.json").read_text())
    (seed_dir / "summary.json").write_text(json.dumps({**summary, "status": "interrupted", "finished": False}))
    write_checkpoint(seed_dir, {"version": VERSION, "batch": [1], "vector_step": 5})
    base = CartPoleDQNConfig.for_variant("faithful")
    every, todo, _ = sweep_jobs(base, [GridPoint("episodes=20", {"episodes": 20})], [0, 1], tmp_path / "sweep")
    assert len(every) == 2 and [(j.config.seed, j.start) for j in todo] == [(1, "resume")]
    # seed 0 finished inside a batch with seed 1 that was stopped after: it rejoins the batch
    for seed in (0, 1):
        write_checkpoint(point / f"seed_{seed}", {"version": VERSION, "batch": [0, 1], "vector_step": 5})
    _, todo, _ = sweep_jobs(base, [GridPoint("episodes=20", {"episodes": 20})], [0, 1], tmp_path / "sweep")
    assert [(j.config.seed, j.start) for j in todo] == [(0, "resume"), (1, "resume")]


@pytest.mark.parametrize("experiment", ["cartpole", "pendulum", "mountaincar"])
def test_compare_without_torch_is_a_clear_error(monkeypatch, capsys, tmp_path, experiment):
    monkeypatch.setitem(sys.modules, "torch", None)
    assert main(["compare", experiment, "--runs", str(tmp_path)]) == 2
    assert "the torch framework needs PyTorch" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing ran, nothing written


@pytest.mark.slow
def test_compare_pendulum_with_matched_init_keeps_its_runs_and_report_apart(tmp_path):
    pytest.importorskip("torch", reason="compare needs the torch extra")
    args = [
        "compare",
        "pendulum",
        "--seeds",
        "0-1",
        "--episodes",
        "6",
        "--runs",
        str(tmp_path / "runs"),
        "--out",
        str(tmp_path / "out"),
        "--no-progress",
    ]
    assert main([*args, "--matched-init"]) == 0
    report = (tmp_path / "out" / "pendulum" / "matched-init" / "report.md").read_text()
    assert "Initialisation: matched init" in report and "| torch | 0/2 |" in report
    torch_run = tmp_path / "runs" / "pendulum" / "faithful-torch-matched-init" / "seed_1"
    assert json.loads((torch_run / "config.json").read_text())["matched_init"] is True
    keras_rows = read_episodes(tmp_path / "runs" / "pendulum" / "faithful" / "seed_1" / "episodes.csv")
    torch_rows = read_episodes(torch_run / "episodes.csv")
    # same seed, same env and noise draws, same initial weights: the warm-up episodes (no
    # updates before 1000 transitions) are the same in both frameworks to float32 rounding
    for k, t in zip(keras_rows[:5], torch_rows[:5]):
        assert t["score"] == pytest.approx(k["score"], rel=1e-4)
    # the default-init comparison reuses the Keras runs and makes its own torch folder
    assert main(["compare", "pendulum", *args[2:], "--reuse-only"]) == 2
    assert main(args) == 0
    assert (tmp_path / "runs" / "pendulum" / "faithful-torch" / "seed_0" / "actor.pt").is_file()
    assert "Initialisation: default init" in (tmp_path / "out" / "pendulum" / "report.md").read_text()


def test_a_sweep_point_that_left_no_run_has_no_row_and_an_empty_baseline_is_named():
    """A sweep whose grid point's jobs all failed crashed its report on "0 of 0" seeds; the
    point now has no row (``sweep`` names it and exits 1), and an empty baseline is an error."""
    from keras_rl.errors import RunFolderError
    from keras_rl.report.sweep import analyse_sweep
    from keras_rl.runs.summary import RunSummary

    def run(seed, reached):
        return RunSummary(
            "mountaincar", "faithful", seed, "completed", reached is not None, "c", reached, 100, 100,
            1000, None, 0.1, 0.1, 1.0,
        )  # fmt: skip

    base = [run(0, 10), run(1, 12), run(2, None)]
    result = analyse_sweep({"base": base, "learning_phase_training=true": [], "tau=0.1": [run(0, 30)]}, "base")
    assert [row["point"] for row in result["points"]] == ["base", "tau=0.1"]
    with pytest.raises(RunFolderError, match="baseline grid point 'base' has no run"):
        analyse_sweep({"base": [], "tau=0.1": base}, "base")


def test_compare_says_what_it_reused_and_where_and_prints_no_markdown(capsys, tmp_path):
    """Round three: compare said nothing of what it reused or trained, nor where its runs are, and
    printed the report's ``**`` on the terminal."""
    root = Path(__file__).resolve().parents[1] / "results"
    argv = ["compare", "pendulum", "--seeds", "0-2", "--reuse-only", "--runs", str(root), "--out", str(tmp_path)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert f"keras: {root / 'pendulum' / 'faithful'}: 3 of 3 seeds reused, none to train" in captured.err
    assert f"torch: {root / 'pendulum' / 'faithful-torch'}: 3 of 3 seeds reused" in captured.err
    assert "**" not in captured.out and f"report: {tmp_path / 'pendulum' / 'report.md'}" in captured.out
