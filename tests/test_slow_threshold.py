"""Full-training threshold test (slow): post 000's faithful DDPG reaches EMA > -300."""

import json
import subprocess
import sys

import pytest


@pytest.mark.slow
def test_faithful_pendulum_reaches_minus_300_in_2_of_3_seeds_within_300_episodes(tmp_path):
    """k=2 of n=3 seeds must pass EMA > -300 within 300 episodes.

    Derivation (results/pendulum/faithful/summary.md, 10 seeds, the post's 1000-episode
    budget): 10/10 seeds succeeded, episodes-to-threshold median 130, IQR 116-142,
    min 95, max 155; the post itself reports 153. A 300-episode budget is about twice
    the slowest seed seen, so a healthy learner passes with a wide margin even where
    floating-point details (another CPU, another oneDNN kernel) move a seed by tens of
    episodes; allowing one of three seeds to miss absorbs a rare outlier. The test still
    has teeth: a random or non-learning policy scores about -1200 per episode (the EMA
    at the start of every run), and a learner even twice as slow as measured fails the
    budget. Seeds 0-2 reached the threshold at episodes 95, 137 and 155 here.
    """
    out = tmp_path / "runs"
    proc = subprocess.run([sys.executable, "-m", "keras_rl", "reproduce", "pendulum", "--variant", "faithful",
                           "--seeds", "0-2", "--episodes", "300", "--workers", "2", "--no-progress",
                           "--min-success-rate", "0.66", "--out", str(out)],
                          capture_output=True, text=True, timeout=1800)
    summaries = [json.loads((out / f"seed_{s}" / "summary.json").read_text()) for s in range(3)]
    reached = [s["reached_at_episode"] for s in summaries]
    assert sum(r is not None and r <= 300 for r in reached) >= 2, (reached, proc.stderr[-2000:])
    assert proc.returncode == 0, proc.stderr[-2000:]
    for s in summaries:
        if s["success"]:
            assert s["final_metric"] > -300 and s["episodes_run"] == s["reached_at_episode"]
    assert (out / "summary.md").is_file() and (out / "curves.png").is_file()
