"""Post 003 on many seeds at once on the vectorised PyTorch engine (issue 53 item 4): a thousand
seeds of the tutorial's DQN on one GPU, or any number on a CPU, in one process.

    python benchmarks/thousand_seeds.py --seeds 0-999 --device cuda --cuda-graph --out DIR [--max-seconds 330]

Steps every seed until each has played its budget (600 episodes) or ``--max-seconds`` of stepping
have passed, reading the episodes back once per chunk and shedding the seeds that played their
budget (as a run's batch does), and writes to ``DIR``:

- ``episodes.csv.gz``: one row per finished episode within its seed's budget (seed, episode,
  steps, the mean loss of its updates);
- ``report.json``: the device and its torch, CUDA and GPU names, the seeds, the steps, the compile
  and stepping seconds, the whole set's wall time, ms per seed-env-step after the first chunk
  (which compiles; every seed stepped counts), each chunk's batch size and seconds, and on a GPU
  the CartPole step there against the CPU's and, with ``--cuda-graph``, the graphed step against
  the eager one bit for bit.

Needs only torch, numpy and gymnasium (the device machines have no TensorFlow).
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def seed_range(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def env_agreement(device) -> dict:
    """CartPole's step on ``device`` against the CPU's (bit for bit Gymnasium's, tests/test_torch_envs.py)
    from 1,000 random states and actions: the largest state difference and the flags that differ."""
    import torch

    from keras_rl.torch.envs import CartPole

    g = torch.Generator().manual_seed(3)
    bounds = torch.tensor([2.4, 3.0, 0.21, 3.0], dtype=torch.float64)
    states = (torch.rand(1000, 4, generator=g, dtype=torch.float64) * 2 - 1) * bounds
    actions = torch.randint(0, 2, (1000,), generator=g)
    cpu = CartPole().step(states, actions)
    dev = [x.cpu() for x in CartPole().step(states.to(device), actions.to(device))]
    return {
        "states": 1000,
        "max_abs_state_difference": float((cpu[0] - dev[0]).abs().max()),
        "observations_bit_equal": bool(torch.equal(cpu[1], dev[1])),
        "terminated_flags_differing": int((cpu[3] != dev[3]).sum()),
    }


def graph_agreement(device, seeds: int = 16, chunks: int = 4, chunk: int = 100) -> dict:
    """The CUDA-graph step (``VectorisedDQN(cuda_graph=True)``) against the eager step on ``device``:
    the same seeds played side by side, shedding half the batch after the second chunk (a new
    graph), and every episode and parameter compared bit for bit."""
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.torch.vectorised import VectorisedDQN

    configs = [CartPoleDQNConfig(seed=s) for s in range(seeds)]
    eager, graphed = VectorisedDQN(configs, device=device), VectorisedDQN(configs, device=device, cuda_graph=True)
    same = True
    for i in range(chunks):
        same &= eager.play(chunk) == graphed.play(chunk)
        if i == 1:
            eager.keep(list(range(0, seeds, 2)))
            graphed.keep(list(range(0, seeds, 2)))
    worst = max(float((eager.params[k] - graphed.params[k]).abs().max()) for k in eager.params)
    return {
        "seeds": seeds,
        "env_steps": chunks * chunk,
        "episodes_equal": bool(same),
        "max_abs_parameter_difference": worst,
    }


def eager_baseline(configs, device, steps: int = 200) -> dict:
    """The eager step's time on the same seeds and device, in the same run as the graphed one: a
    fresh engine played to where its memory trains, then ``steps`` training steps timed."""
    import torch

    from keras_rl.torch.vectorised import VectorisedDQN

    engine = VectorisedDQN(configs, device=device)
    engine.play(configs[0].train_start)
    torch.cuda.synchronize()
    start = time.perf_counter()
    engine.play(steps)
    seconds = time.perf_counter() - start
    return {
        "S": len(configs),
        "training_steps": steps,
        "ms_per_step": seconds * 1e3 / steps,
        "ms_per_seed_env_step": seconds * 1e3 / (steps * len(configs)),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-999", help="a range, FIRST-LAST")
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--chunk", type=int, default=500, help="env steps between reads of the episodes")
    parser.add_argument("--max-seconds", type=float, default=330.0, help="stop stepping after this long")
    parser.add_argument("--no-compile", action="store_true")
    parser.add_argument(
        "--cuda-graph",
        action="store_true",
        help="record the eager step as a CUDA graph (no compile; implies --no-compile)",
    )
    parser.add_argument("--episodes", type=int, help="each seed's budget (default the post's, 600)")
    args = parser.parse_args()
    args.no_compile |= args.cuda_graph
    import numpy as np
    import torch

    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.torch.vectorised import VectorisedDQN

    seeds = seed_range(args.seeds)
    args.out.mkdir(parents=True, exist_ok=True)
    device = torch.device(args.device)
    if device.type == "cpu":
        torch.set_num_threads(1)
    configs = [CartPoleDQNConfig(seed=s, **({"episodes": args.episodes} if args.episodes else {})) for s in seeds]
    budget = configs[0].episodes
    report: dict = {
        "command": " ".join(["python", *sys.argv]),
        "torch": torch.__version__,
        "cuda": torch.version.cuda,
        "device": torch.cuda.get_device_name(device) if device.type == "cuda" else platform.processor() or "cpu",
        "seeds": f"{seeds[0]}-{seeds[-1]}",
        "S": len(seeds),
        "budget_episodes": budget,
        "compiled": not args.no_compile,
        "cuda_graph": args.cuda_graph,
    }
    if device.type == "cuda":
        report["env_on_this_device"] = env_agreement(device)
    if args.cuda_graph:
        report["cuda_graph_against_eager"] = graph_agreement(device)
        report["eager_baseline"] = eager_baseline(configs, device)
        print(json.dumps(report, indent=2), flush=True)
    set_start = start = time.perf_counter()
    engine = VectorisedDQN(
        configs, device=device, compile=not args.no_compile, cuda_graph=args.cuda_graph, chunk=args.chunk
    )
    report["build_seconds"] = round(time.perf_counter() - start, 2)
    steps = {s: [] for s in seeds}
    losses = {s: [] for s in seeds}

    def take(ends):
        for e in ends:
            if e.episode <= budget:
                steps[e.seed].append(e.steps)
                losses[e.seed].append(e.loss_sum / e.updates if e.updates else float("nan"))

    def shed():  # the seeds that played their budget leave the batch, as a run's do
        rest = [k for k, s in enumerate(engine.seeds) if len(steps[s]) < budget]
        if rest and len(rest) < len(engine.seeds):
            engine.keep(rest)

    # the first chunk compiles both programs (before and after the memory holds a batch)
    start = time.perf_counter()
    take(engine.play(args.chunk))
    if device.type == "cuda":
        torch.cuda.synchronize()
    report["first_chunk_seconds"] = round(time.perf_counter() - start, 2)
    shed()
    stepping_start, stepped, chunks = time.perf_counter(), 0, []
    while min(len(v) for v in steps.values()) < budget:
        if time.perf_counter() - stepping_start > args.max_seconds:
            break
        size, chunk_start = len(engine.seeds), time.perf_counter()
        take(engine.play(args.chunk))
        shed()
        chunks.append([engine.t, size, round(time.perf_counter() - chunk_start, 4)])
        stepped += args.chunk * size
        done = sum(len(v) >= budget for v in steps.values())
        report["progress"] = {  # rewritten after every chunk: a run stopped from outside keeps it
            "stepping_seconds": round(time.perf_counter() - stepping_start, 2),
            "env_steps_per_seed": engine.t,
            "ms_per_seed_env_step": (time.perf_counter() - stepping_start) * 1e3 / stepped,
            "seeds_that_played_their_budget": done,
            "chunks": chunks,
        }
        (args.out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
        print(
            f"{time.perf_counter() - stepping_start:7.1f} s  step {engine.t:7d}  seeds done {done}/{len(seeds)}  "
            f"batch {len(engine.seeds):4d}  "
            f"episodes min {min(len(v) for v in steps.values())}",
            flush=True,
        )
    wall = time.perf_counter() - stepping_start
    within = sum(sum(v) for v in steps.values())
    report.update(
        {
            "env_steps_per_seed": engine.t,
            "stepping_seconds": round(wall, 2),
            "set_wall_seconds": round(time.perf_counter() - set_start, 2),
            "ms_per_seed_env_step": wall * 1e3 / stepped if stepped else None,
            "seed_env_steps_stepped": stepped + args.chunk * len(seeds),
            "seed_env_steps_within_budgets": within,
            "share_of_seed_env_steps_within_budgets": within / (stepped + args.chunk * len(seeds)),
            "chunks": {"columns": ["env_steps_per_seed", "seeds_in_batch", "seconds"], "rows": chunks},
            "seeds_that_played_their_budget": sum(len(v) >= budget for v in steps.values()),
            "stopped_by": "budget" if min(len(v) for v in steps.values()) >= budget else "max-seconds",
        }
    )
    rows = [(s, i + 1, n, loss) for s in seeds for i, (n, loss) in enumerate(zip(steps[s], losses[s]))]
    with gzip.open(args.out / "episodes.csv.gz", "wt", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["seed", "episode", "steps", "loss"])
        w.writerows((s, e, n, f"{loss:.6g}") for s, e, n, loss in rows)
    reached = []
    for s in seeds:
        d = np.asarray(steps[s], dtype=np.float64)
        if len(d) >= 100:
            mean = np.convolve(d, np.ones(100) / 100, mode="valid")  # mean of episodes i-99..i, from i = 100
            hit = np.nonzero(mean >= configs[0].threshold)[0]
            reached.append(int(hit[0]) + 100 if len(hit) else None)
        else:
            reached.append(None)
    played = [len(steps[s]) >= budget for s in seeds]
    report["success_rate_of_seeds_that_played_their_budget"] = (
        sum(r is not None for r, p in zip(reached, played) if p) / sum(played) if any(played) else None
    )
    report["median_episode_reached"] = float(np.median([r for r in reached if r is not None])) if any(reached) else None
    (args.out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
