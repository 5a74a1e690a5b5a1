"""Post 003's PyTorch agent per environment step: the tutorial's code as written
(``TutorialDQNAgent(..., as_written=True)``) against the same code with its batch gathered by
index, its soft update in place and AdamW's multi-tensor step (the default; the module
docstring of ``keras_rl/torch/dqn_tutorial.py`` says what changed).

    python benchmarks/torch_tutorial_step.py                 # 5 rounds of 2,000 steps each
    python benchmarks/torch_tutorial_step.py --markdown      # the table for docs/performance.md

It ends with what the floor means for regenerating ``results/``: the env steps of the committed
PyTorch post 003 seeds (every set ``results/MANIFEST.json`` lists, and the least issue 35 asked
for: the seed plan's seeds per arm of the certified comparison at each init, 200, and the
planned 30 for each proposed fix), times the update alone.

Both agents start from the same seed and a memory filled to the tutorial's capacity (10,000
CartPole transitions from random actions: where a 600-episode seed spends nearly all of its
steps), then take the same steps on their own copy of the environment, a chunk each in turn.
They must end with the same weights, bit for bit, or the benchmark exits 1: a speed-up that
changed a number would not be one. Then the floor: the tutorial's update alone (forward,
backward, gradient clip, AdamW step and soft update) on one batch gathered once, which every
step of the tutorial's eager PyTorch code pays however its batch is made. One torch thread, as
the runs use. Only ratios within one run mean much on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


class Arm:
    """One agent on its own CartPole, stepped by the agent verbs as ``train/loop.py`` steps it."""

    def __init__(self, as_written: bool, transitions: int):
        import gymnasium as gym

        from benchmarks.checkpoint import filled_agent

        self.env = gym.make("CartPole-v1")
        self.agent = filled_agent(transitions, as_written, self.env)
        obs, _ = self.env.reset()
        self.action = self.agent.begin_episode(obs)

    def steps(self, n: int) -> float:
        start = time.perf_counter()
        for _ in range(n):
            obs, reward, terminated, truncated, _ = self.env.step(self.action)
            action = self.agent.step(reward, obs, terminated, truncated)
            if action is None:
                self.agent.end_episode()
                obs, _ = self.env.reset()
                action = self.agent.begin_episode(obs)
            self.action = action
        return time.perf_counter() - start

    def weights(self):
        return [p.detach().clone() for net in (self.agent.policy_net, self.agent.target_net) for p in net.parameters()]


def committed_steps() -> dict[str, tuple[int, int]]:
    """Seeds and env steps (``total_steps``) of the committed PyTorch post 003 runs: all of them,
    and the least issue 35 asked for (the seed plan's seeds per arm of the certified comparison at
    each init, ``maintainers.certified.certifications``, and the planned PyTorch seeds of each proposed
    fix, ``maintainers.tutorial_fix``)."""
    import json

    from keras_rl.runs.run_set import RunSet
    from maintainers.certified import arm, certifications
    from maintainers.checkout import ROOT
    from maintainers.tutorial_fix import PLANNED_SEEDS, TUTORIAL_FIXES

    sets = [s["set"] for s in json.loads((ROOT / "results" / "MANIFEST.json").read_text())]
    every = [
        r
        for name in sets
        for r in RunSet(ROOT / "results" / name).summary_records()
        if r.get("experiment") == "cartpole" and r.get("framework") == "torch"
    ]
    arms = [(c.torch, c.planned) for c in certifications() if c.post == "cartpole"]
    arms += [((fix.folder("torch"),), PLANNED_SEEDS["torch"]) for fix in TUTORIAL_FIXES]
    least = [arm(folders)[seed] for folders, seeds in arms for seed in range(seeds)]
    return {
        "every committed seed": (len(every), sum(int(r["total_steps"]) for r in every)),
        "the least issue 35 asked for": (len(least), sum(int(r["total_steps"]) for r in least)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=2000, help="steps per arm per round")
    parser.add_argument("--transitions", type=int, default=10_000, help="the memory's fill (the tutorial's capacity)")
    parser.add_argument("--markdown", action="store_true", help="print the result as a Markdown table")
    args = parser.parse_args()
    if args.rounds < 1 or args.steps < 1 or args.transitions < 128:
        parser.error("--rounds and --steps must be at least 1, --transitions at least 128 (one batch)")
    import torch

    from keras_rl.torch import single_threaded

    single_threaded()
    arms = {"as written": Arm(True, args.transitions), "gathered": Arm(False, args.transitions)}
    per_step: dict[str, list[float]] = {name: [] for name in arms}
    for _ in range(args.rounds):
        for name, arm in arms.items():
            per_step[name].append(arm.steps(args.steps) / args.steps * 1e3)
    same = all(torch.equal(a, b) for a, b in zip(*(arm.weights() for arm in arms.values()), strict=True))
    agent = arms["gathered"].agent
    batch = agent.memory.sample_rows(agent.config.batch_size)
    floor = []
    for _ in range(args.rounds):
        start = time.perf_counter()
        for _ in range(args.steps):
            agent.learn(*batch)
            agent.soft_update()
        floor.append((time.perf_counter() - start) / args.steps * 1e3)
    old, new, least = (statistics.median(v) for v in (*per_step.values(), floor))
    print(
        f"post 003 (PyTorch), ms per environment step, median of {args.rounds} rounds of {args.steps} steps, "
        f"memory filled with {args.transitions}; {platform.processor() or platform.machine()}, one torch thread"
    )
    if args.markdown:
        print("\n| | as written | gathered | the update alone |\n|---|---:|---:|---:|")
        print(f"| ms per step | {old:.3g} | {new:.3g} | {least:.3g} |")
        print(f"| against as written | 1x | {old / new:.2f}x | {old / least:.2f}x |")
    else:
        print(f"as written {old:.4g}   gathered {new:.4g} ({old / new:.2f}x)   the update alone {least:.4g}")
    print(f"same weights after {args.rounds * args.steps} steps each: {'yes' if same else 'NO'}")
    for name, (seeds, steps) in committed_steps().items():
        hours = steps * least / 1e3 / 3600
        print(
            f"{name} (post 003, PyTorch): {seeds} seeds, {steps / 1e6:.1f} million env steps; at the update alone "
            f"at least {hours:.1f} process-hours, {hours / 2:.1f} h on two cores"
        )
    if not same:
        sys.exit(1)


if __name__ == "__main__":
    main()
