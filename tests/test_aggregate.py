"""`keras-rl aggregate`: mixed configs refused, a damaged or corrupt seed named with exit 2, and
curves redrawn against env steps."""

from __future__ import annotations

import json
import shutil

import pytest

from keras_rl.cli import main


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


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.write_text("garbage\n"), "is not an episodes.csv (no header with 'score')"),
        (lambda p: p.write_text(""), "is not an episodes.csv"),
        (lambda p: p.write_text(p.read_text()[: p.read_text().rindex(",-") + 2]), "line 8"),  # cut after a minus sign
        (lambda p: p.write_bytes(b"\xff\xfe\x00garbage"), "is not text"),
        (
            lambda p: p.write_text("".join(p.read_text().splitlines(keepends=True)[:4])),
            "holds 3 episodes, but its summary.json counts 7",
        ),
    ],
    ids=["garbage", "empty", "cut-mid-number", "binary", "truncated-rows"],
)
def test_aggregate_names_a_damaged_episodes_csv_and_exits_2(short_run, tmp_path, damage, message, capsys):
    """#23.6 and #23.7: a damaged episodes.csv gave a raw traceback (exit 1); a truncated one
    was accepted silently. Now exit 2, naming the file, and nothing is written."""
    import shutil

    parent = tmp_path / "set"
    shutil.copytree(short_run.parent, parent)
    csv_path = parent / "seed_3" / "episodes.csv"
    damage(csv_path)
    before = {p.name: p.read_bytes() for p in parent.iterdir() if p.is_file()}
    assert main(["aggregate", str(parent)]) == 2
    err = capsys.readouterr().err
    assert str(csv_path) in err and message in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in parent.iterdir() if p.is_file()} == before


def test_aggregate_redraws_curves_against_env_steps(short_run, tmp_path, capsys):
    import shutil

    parent = tmp_path / "set"
    shutil.copytree(short_run.parent, parent)
    (parent / "seed_3" / "curve.png").unlink()
    assert main(["aggregate", str(parent), "--x-axis", "steps"]) == 0
    assert (parent / "seed_3" / "curve.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(SystemExit):
        main(["aggregate", str(parent), "--x-axis", "time"])


def test_a_post_judged_at_the_end_counts_only_its_successes_in_the_median_and_says_the_plans_reading(tmp_path):
    """Issue 54 item 14: post 001's summary.md gave a median of 10 episodes to threshold while
    counting a seed that met the threshold at episode 10 and failed at the end. The table's median
    counts the seeds that succeeded; the sentence below gives the plans' reading (each seed's first
    passing episode, the failed seed included), labelled."""
    from keras_rl.report.aggregate import write_aggregate
    from keras_rl.runs.summary import RunSummary

    def summary(seed, success, reached):
        return RunSummary(
            "mountaincar", "faithful", seed, "completed", success, "metric <= 2 after all 100 episodes", reached,
            100, 100, 99900, None, 0.0 if success else 9.0, 0.0, 1.0,
        )  # fmt: skip

    write_aggregate(tmp_path, [summary(0, False, 10), summary(1, True, 20), summary(2, True, 30)], 2.0, "t", "m")
    text = (tmp_path / "summary.md").read_text()
    assert "| 3 | 2/3 (67%) | 25 | " in text  # the two seeds that succeeded: 20 and 30
    assert "count the seeds that succeeded" in text and "By the plans' reading" in text
    assert "(each seed's first passing episode, 3 seeds)" in text and "median 20," in text
