"""Keras against PyTorch at the planned seeds (issue 35 item 1, ``maintainers/certified.py``):
arms made of several run sets, read only on seeds 0 to N-1 and only once both arms hold them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from keras_rl.errors import RunFolderError
from maintainers import certified
from maintainers.certified import Certification, arm, certifications, reading


def _seed(root: Path, folder: str, seed: int, reached: int | None, status: str = "completed") -> None:
    d = root / folder / f"seed_{seed}"
    d.mkdir(parents=True)
    summary = {
        "seed": seed,
        "status": status,
        "success": reached is not None,
        "reached_at_episode": reached,
        "budget_episodes": 100,
    }
    (d / "summary.json").write_text(json.dumps(summary))


@pytest.fixture
def arms(tmp_path, monkeypatch):
    monkeypatch.setitem(certified.KERAS_ARMS, "toy", ("k-first", "k-more"))
    monkeypatch.setitem(certified.TORCH_ARMS, ("toy", False), ("t",))
    return tmp_path


def test_an_arm_reads_its_sets_in_order_and_skips_interrupted_seeds(arms):
    _seed(arms, "k-first", 0, 10)
    _seed(arms, "k-more", 0, 10)  # the same run again: the first set's is read
    _seed(arms, "k-more", 1, None)
    _seed(arms, "k-more", 2, 12, status="interrupted")
    _seed(arms, "k-more", 4, None, status="non_finite_loss")  # what the config does: a seed of the arm
    held = arm(("k-first", "k-more", "not-committed-yet"), arms)
    assert sorted(held) == [0, 1, 4]
    assert held[1]["success"] is False


def test_a_seed_held_twice_with_different_outcomes_is_refused(arms):
    _seed(arms, "k-first", 3, 10)
    _seed(arms, "k-more", 3, 11)
    with pytest.raises(RunFolderError, match="seed 3 is in k-first and k-more with different outcomes"):
        arm(("k-first", "k-more"), arms)


def test_no_reading_until_both_arms_hold_every_planned_seed_and_none_past_them(arms):
    c = Certification("toy", False, planned=4)
    for s in range(4):
        _seed(arms, "k-first", s, 10 + s)
    for s in range(3):
        _seed(arms, "t", s, 10 + s)
    pending = reading(c, arms)
    assert pending["pending"] and pending["held"] == [4, 3] and "judged" not in pending
    _seed(arms, "t", 3, None)
    read = reading(c, arms)
    assert not read["pending"] and read["successes"] == [4, 3]
    _seed(arms, "t", 4, None)  # a seed past the plan changes nothing
    _seed(arms, "k-first", 5, None)
    again = reading(c, arms)
    assert again["successes"] == read["successes"] and again["arms"] == read["arms"]
    assert [e.reading for e in again["judged"]] == [e.reading for e in read["judged"]]


def test_the_certifications_follow_the_committed_plan_never_under_100_seeds():
    plan = json.loads(certified.PLAN.read_text())
    got = certifications()
    assert [(c.post, c.matched_init, c.planned) for c in got] == [
        (p["post"], p["init"] == "matched", p["seeds_per_arm"]) for p in plan
    ]
    assert all(c.planned >= 100 for c in got)
    for c in got:  # each arm's first set is the committed 30-seed arm compare reads
        assert (certified.RESULTS / c.keras[0]).is_dir() and (certified.RESULTS / c.torch[0]).is_dir()
