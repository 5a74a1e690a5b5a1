"""Post 003 in PyTorch per seed-env-step: the tutorial's own code (gathered, as the runs use it;
``benchmarks/torch_tutorial_step.py``) against the vectorised engine (``keras_rl/torch/vectorised.py``)
at S = 1, 8 and 32 seeds, eager and compiled (``torch.compile``), on this CPU, one torch thread.

    python benchmarks/torch_vectorised.py [--rounds 5] [--markdown]

Every arm starts with its memory full (10,000 CartPole transitions from random actions, where a
600-episode seed spends nearly all of its steps) and past its warm-up, so every step trains; the
arms take turns, a round each, and the table gives the median round. Compiling happens before the
first round and is reported apart. Only ratios within one run mean much on a shared machine.
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


class Vectorised:
    """S seeds on the vectorised engine, their memories filled with random transitions."""

    def __init__(self, seeds: int, compiled: bool, transitions: int, steps: int):
        import torch

        from keras_rl.posts.cartpole import CartPoleDQNConfig
        from keras_rl.torch.vectorised import VectorisedDQN

        self.engine = e = VectorisedDQN([CartPoleDQNConfig(seed=s) for s in range(seeds)], compile=compiled)
        g = torch.Generator().manual_seed(0)
        mem, n = e.memory, transitions
        mem["state"][:, :n] = torch.rand(seeds, n, 4, generator=g) * 0.2 - 0.1
        mem["next_state"][:, :n] = torch.rand(seeds, n, 4, generator=g) * 0.2 - 0.1
        mem["action"][:, :n] = torch.randint(0, 2, (seeds, n), generator=g)
        mem["reward"][:, :n] = 1.0
        mem["non_final"][:, :n] = torch.rand(seeds, n, generator=g) > 0.05
        e.t = n
        e.clock.fill_(n)
        self.seeds = seeds
        start = time.perf_counter()
        e.play(steps)  # a round's chunk: compiles, where compiled
        self.warm_seconds = time.perf_counter() - start if compiled else None

    def steps(self, n: int) -> float:
        start = time.perf_counter()
        self.engine.play(n)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seed-steps", type=int, default=1000, help="seed-env-steps per arm per round")
    parser.add_argument("--sizes", default="1,8,32", help="the S to measure, comma-separated")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    if args.rounds < 1 or args.seed_steps < 32:
        parser.error("--rounds must be at least 1 and --seed-steps at least 32")
    import torch

    from benchmarks.torch_tutorial_step import Arm
    from keras_rl.torch import single_threaded

    single_threaded()
    sizes = [int(s) for s in args.sizes.split(",")]
    arms: dict[str, object] = {"the tutorial's code (gathered)": Arm(False, 10_000)}
    for compiled in (False, True):
        for s in sizes:
            name = f"vectorised, S={s}, {'compiled' if compiled else 'eager'}"
            arms[name] = Vectorised(s, compiled, 10_000, max(1, args.seed_steps // s))
    per: dict[str, list[float]] = {name: [] for name in arms}
    for _ in range(args.rounds):
        for name, arm in arms.items():
            seeds = getattr(arm, "seeds", 1)
            steps = max(1, args.seed_steps // seeds)
            per[name].append(arm.steps(steps) / (steps * seeds) * 1e3)
    ms = {name: statistics.median(v) for name, v in per.items()}
    base = ms["the tutorial's code (gathered)"]
    print(
        f"post 003 (PyTorch), ms per seed-env-step, median of {args.rounds} rounds of {args.seed_steps} seed-steps, "
        f"memories full (10,000); {platform.processor() or platform.machine()}, torch {torch.__version__}, one thread"
    )
    if args.markdown:
        print("\n| arm | ms per seed-env-step | against the tutorial's code | compile, s |\n|---|---:|---:|---:|")
    for name, value in ms.items():
        warm = getattr(arms[name], "warm_seconds", None)
        if args.markdown:
            print(f"| {name} | {value:.3g} | {base / value:.2f}x | {'' if warm is None else f'{warm:.0f}'} |")
        else:
            compile_note = "" if warm is None else f"  (compile {warm:.0f} s)"
            print(f"{name:40s} {value:8.4f} ms  {base / value:5.2f}x{compile_note}")


if __name__ == "__main__":
    main()
