"""Full-training threshold tests (slow): each post reaches its threshold within a budget.

Post 003's Keras test ("1 of 4 seeds reaches 475 within 600 episodes") is gone: the smoke
tier of ``keras-rl check`` (tests/test_check.py) replaced it. Measured on the 30-seed
baseline, the old test cried wolf 3.7% of the time (each seed succeeds with p = 0.57, and
0.43^4 = 3.4%), the smoke rule 0.7%, and the smoke rule flags both gross mutants always and
all six 84% of the time (results/checks/calibration.md).

Post 000's Keras test ("2 of 3 seeds reach -300 within 300 episodes") is gone as well: it
never cried wolf on the baseline, but it flags the six mutants 34% of the time on average
against the smoke rule's 82% (both: 100% against the gross ones), at about the same cost.
Its helper stays for the PyTorch port below, which ``check`` does not cover.

Post 001's Keras test ("2 of 3 seeds meet the criterion after 100 episodes") is gone too: on
the 30-seed baseline the criterion holds for 25 seeds (10/10 on the seeds 0-9 it was chosen
on, 15/20 on seeds 10-29), so the old test failed an unchanged learner 7.5% of the time; the
smoke rule's false-alarm rate is 0.99%. Its power against post 001's mutants is not measured
yet (their runs are still to make), and neither was the old test's.
"""

import json
import subprocess
import sys

import pytest


def pendulum_2_of_3(tmp_path, framework: str) -> list[dict]:
    """Seeds 0-2 of post 000's faithful variant, 300 episodes; at least 2 must pass -300.
    Seeds 0 and 1 run first; seed 2 runs only where one of them missed, since then it decides
    (the same verdict as running all three, without the third seed's run where it cannot matter).

    Derivation for the Keras learner (results/pendulum/faithful, 10 seeds, budget 1000):
    10/10 succeeded, episodes-to-threshold median 130, range 95-155; 300 episodes is about
    twice the slowest seed, and one of three may miss."""
    out = tmp_path / "runs"

    def run(seeds: str) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "keras_rl", "reproduce", "pendulum", "--variant", "faithful"]
        command += ["--framework", framework, "--seeds", seeds, "--episodes", "300", "--workers", "1"]
        command += ["--no-progress", "--min-success-rate", "0", "--resume", "--out", str(out)]
        return subprocess.run(command, capture_output=True, text=True, timeout=1800)

    proc = run("0-1")
    summaries = [json.loads((out / f"seed_{s}" / "summary.json").read_text()) for s in range(2)]
    if not all(s["success"] for s in summaries):
        proc = run("2")
        summaries.append(json.loads((out / "seed_2" / "summary.json").read_text()))
    reached = [s["reached_at_episode"] for s in summaries]
    assert sum(r is not None and r <= 300 for r in reached) >= 2, (reached, proc.stderr[-2000:])
    assert proc.returncode == 0, proc.stderr[-2000:]
    for s in summaries:
        assert s["framework"] == framework
        if s["success"]:
            assert s["final_metric"] > -300 and s["episodes_run"] == s["reached_at_episode"]
    return summaries


@pytest.mark.slow
def test_torch_port_of_post_000_reaches_minus_300_in_2_of_3_seeds_within_300_episodes(tmp_path):
    """The PyTorch port (default torch init) under the rule the Keras learner had (``pendulum_2_of_3``).

    Derivation (results/pendulum/faithful-torch, 10 seeds, budget 1000): 10/10 succeeded,
    episodes-to-threshold median 132.5, IQR 124.5-159, range 112-219; seeds 0-2 reached it
    at 130, 126 and 219. 300 episodes is 1.4x the slowest seed seen; one of three may miss.
    Teeth: a port whose update is wrong (a sign, a missing soft update, the wrong Adam)
    stays near the random policy's -1200.
    """
    pytest.importorskip("torch", reason="needs the torch extra")
    pendulum_2_of_3(tmp_path, "torch")
