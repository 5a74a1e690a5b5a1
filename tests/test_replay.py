"""Where a rerun parts from a committed run (maintainers/replay.py), on hand-made rows."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from committed import committed_seed

from maintainers.replay import first_divergence, plan_replay, seed_rows

RESULTS = Path(__file__).resolve().parent.parent / "results"


def rows(*scores: str) -> list[dict[str, str]]:
    return [{"episode": str(i + 1), "score": s, "metric": s} for i, s in enumerate(scores)]


def test_identical_runs_have_no_divergence():
    d = first_divergence(rows("1", "2", "3"), rows("1", "2", "3"))
    assert d.identical and d.compared == 3 and d.as_dict() == {"compared": 3, "first_episode": None, "columns": []}


def test_the_first_differing_episode_and_its_columns_are_named():
    got = rows("1", "2", "3.5", "9")
    got[2]["metric"] = "3"  # only the score differs in episode 3
    d = first_divergence(rows("1", "2", "3", "4"), got)
    assert (d.first_episode, d.columns, d.compared) == (3, ("score",), 3)


def test_a_rerun_that_stopped_early_differs_at_its_first_missing_episode():
    d = first_divergence(rows("1", "2", "3"), rows("1"))
    assert (d.first_episode, d.columns, d.compared) == (2, (), 1)


def test_the_timing_column_is_not_compared(tmp_path):
    path = tmp_path / "episodes.csv"
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=["episode", "score", "wall_seconds"])
        writer.writeheader()
        writer.writerow({"episode": 1, "score": "-1.5", "wall_seconds": "0.25"})
    assert seed_rows(path) == [{"episode": "1", "score": "-1.5"}]


def test_a_whole_run_replays_with_its_own_budget_and_a_cut_one_with_its_length():
    folder = RESULTS / "pendulum" / "faithful" / "seed_0"
    config = json.loads((committed_seed("pendulum/faithful/seed_0") / "config.json").read_text())
    whole = plan_replay(folder, "pendulum")  # read from the packed set
    assert whole.expected == seed_rows(committed_seed("pendulum/faithful/seed_0") / "episodes.csv")
    assert whole.budget == config["episodes"]
    first = plan_replay(folder, "pendulum", 7)
    assert first.budget == 7 and len(first.expected) == 7
    command = first.command(Path("OUT"), "--framework", "torch", python="py")
    assert command[:5] == ["py", "-m", "keras_rl", "reproduce", "pendulum"]
    assert command[command.index("--episodes") + 1] == "7" and command[-2:] == ["--framework", "torch"]
    assert command[command.index("--engine") + 1] == "gymnasium" == first.engine  # as recorded, not auto's pick
    compiled = plan_replay(RESULTS / "engines" / "pendulum" / "compiled" / "seed_0", "pendulum", 3)
    assert compiled.command(Path("OUT"))[compiled.command(Path("OUT")).index("--engine") + 1] == "compiled"


def test_a_machine_listed_as_not_bit_exact_or_another_isa_is_named(tmp_path, monkeypatch):
    import json

    from keras_rl.runs import provenance
    from maintainers.replay import why_not_bit_exact

    monkeypatch.setattr(provenance, "cpu_model", lambda: "AMD EPYC")
    monkeypatch.setattr(provenance, "cpu_isa", lambda: ["avx2", "fma"])
    listed = tmp_path / "PLATFORMS.json"
    listed.write_text(json.dumps({"not_bit_exact": []}))
    assert why_not_bit_exact({"cpu_model": "AMD EPYC"}, listed) is None
    assert "made on 'Intel Xeon'" in why_not_bit_exact({"cpu_model": "Intel Xeon"}, listed)
    assert "avx512f" in why_not_bit_exact({"cpu_model": "AMD EPYC", "cpu_isa": ["avx2", "avx512f"]}, listed)
    listed.write_text(
        json.dumps({"not_bit_exact": [{"cpu_model": "AMD EPYC", "cpu_isa": ["avx2", "fma"], "measured": "x"}]})
    )
    assert "measured not to" in why_not_bit_exact({"cpu_model": "AMD EPYC"}, listed)


def test_a_cpu_of_another_model_measured_to_give_a_frameworks_bits_replays_that_framework_exactly(
    tmp_path, monkeypatch
):
    """``bit_exact``: a CPU of another model name, measured to give the committed bits of one
    framework's runs (TensorFlow's follow the instruction set), is exact for that framework only,
    for runs made on the model it names, and only with the instruction set it was measured with."""
    import json

    from keras_rl.runs import provenance
    from maintainers.replay import why_not_bit_exact

    isa = ["avx2", "fma", "avx512f"]
    monkeypatch.setattr(provenance, "cpu_model", lambda: "Intel Xeon")
    monkeypatch.setattr(provenance, "cpu_isa", lambda: isa)
    listed = tmp_path / "PLATFORMS.json"
    entry = {"cpu_model": "Intel Xeon", "cpu_isa": isa, "same_as": "AMD EPYC", "frameworks": ["keras"], "measured": "x"}
    listed.write_text(json.dumps({"not_bit_exact": [], "bit_exact": [entry]}))
    assert why_not_bit_exact({"cpu_model": "AMD EPYC"}, listed) is None
    assert why_not_bit_exact({"cpu_model": "AMD EPYC", "cpu_isa": isa}, listed, framework="keras") is None
    assert "made on 'AMD EPYC'" in why_not_bit_exact({"cpu_model": "AMD EPYC"}, listed, framework="torch")
    assert "made on 'Other'" in why_not_bit_exact({"cpu_model": "Other"}, listed)
    assert "this one has" in why_not_bit_exact({"cpu_model": "AMD EPYC", "cpu_isa": ["avx2", "fma"]}, listed)
    monkeypatch.setattr(provenance, "cpu_isa", lambda: ["avx2", "fma"])  # the same model name, no AVX-512
    assert "made on 'AMD EPYC'" in why_not_bit_exact({"cpu_model": "AMD EPYC"}, listed)
