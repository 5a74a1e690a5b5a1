"""``--workers 2`` on one machine: the standard library's process pool against a local Ray instance.

    python benchmarks/pool_vs_ray.py --seeds 4 --episodes 20 --rounds 2

The same jobs (post 000 on the compiled engine, ``--seeds`` seeds of ``--episodes`` episodes,
no early stop) run through ``dispatch/pool_backend.ProcessPool(2)`` and ``dispatch/ray_backend.RayBackend(2)``
(a local instance on loopback, started and shut down each round, as a command does), rounds
interleaved, each into a fresh folder. Wall seconds include each backend's start-up: that is what
a user waits for. Exits 1 unless both give the same ``episodes.csv`` (but wall time) for every
seed. Only the ratio within one run means much on a shared machine. Needs the ``ray`` extra.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()

    from keras_rl.dispatch.jobs import SeedJob, read_outcome
    from keras_rl.dispatch.pool_backend import ProcessPool
    from keras_rl.dispatch.ray_backend import RayBackend, require_ray
    from keras_rl.posts.pendulum import PendulumDDPGConfig
    from keras_rl.runs.files import seed_rows

    require_ray()
    config = PendulumDDPGConfig(episodes=args.episodes, stop_at_threshold=False)
    backends = {"process pool": lambda: ProcessPool(workers=2), "Ray, local": lambda: RayBackend(workers=2)}
    walls: dict[str, list[float]] = {name: [] for name in backends}
    rows: dict[str, dict[int, list]] = {}
    with tempfile.TemporaryDirectory(prefix="pool-vs-ray-") as tmp:
        for r in range(args.rounds):
            for name, make in backends.items():
                out = Path(tmp) / f"{r}-{name.split()[0]}"
                jobs = [
                    SeedJob.of(config.replace(seed=s), out / f"seed_{s}", engine="compiled") for s in range(args.seeds)
                ]
                start = time.perf_counter()
                outcome = read_outcome(jobs, make().run(jobs, progress=False))
                walls[name].append(time.perf_counter() - start)
                assert [s.status for s in outcome.summaries] == ["completed"] * args.seeds, outcome
                rows[name] = {s: seed_rows(out / f"seed_{s}" / "episodes.csv") for s in range(args.seeds)}
                print(f"round {r + 1}: {name}: {walls[name][-1]:.1f} s", flush=True)
    same = rows["process pool"] == rows["Ray, local"]
    pool, ray = (statistics.median(walls[n]) for n in backends)
    print()
    print(
        f"| `--workers 2`, {args.seeds} seeds x {args.episodes} episodes (post 000, compiled) "
        "| wall s (median) | rounds |"
    )
    print("|---|---:|---|")
    for name in backends:
        print(f"| {name} | {statistics.median(walls[name]):.1f} | {', '.join(f'{w:.1f}' for w in walls[name])} |")
    print(
        f"\nRay takes {ray / pool:.2f}x the process pool's wall time. "
        f"Same episodes.csv for every seed: {'yes' if same else 'NO'}"
    )
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
