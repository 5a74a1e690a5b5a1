"""Post 003's PyTorch checkpoints: the tutorial's replay memory pickled as a list of small
tensors (the layout before ``ReplayMemory.arrays``) against one array per field.

    python benchmarks/checkpoint.py                   # a full memory (10,000 transitions), 5 rounds
    python benchmarks/checkpoint.py --episodes 200    # and whole seeds of 200 episodes, each layout
    python benchmarks/checkpoint.py --markdown        # the table for docs/performance.md

Each round writes the checkpoint of one ``TutorialDQNAgent`` whose memory holds
``--transitions`` CartPole transitions (random actions, as the agent stores them: a
``[1, 4]`` float32 state, a ``[1, 1]`` action, ``None`` after a terminal step, a ``[1]``
reward) through ``runs/checkpoint.write_checkpoint``, once per layout, interleaved; then
reads it back. A run writes one every 10 episodes (``TrainSettings.checkpoint_every``), 60
in a 600-episode seed, most with a full memory.

``--episodes N`` adds the end-to-end arm: seed 0 of ``reproduce cartpole --framework torch``
for N episodes through ``train/loop.run_seed``, once with each layout per round (the list
layout by giving ``arrays`` back as a list, which ``restore`` also reads). Only ratios
within one run mean much on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def filled_agent(transitions: int, as_written: bool = False, env=None):
    """Seed 0's ``TutorialDQNAgent`` with ``transitions`` CartPole transitions from random
    actions in its memory, stepped on ``env`` (a new CartPole when none is given)."""
    import gymnasium as gym
    import torch

    from keras_rl.envs import EnvSpec
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.torch.dqn_tutorial import TutorialDQNAgent

    env = env or gym.make("CartPole-v1")
    config = CartPoleDQNConfig(seed=0, framework="torch")
    agent = TutorialDQNAgent(config, EnvSpec(4, 1, n_actions=2), env.action_space, as_written=as_written)
    env.action_space.seed(0)
    obs, _ = env.reset(seed=0)
    state = torch.tensor(obs, dtype=torch.float32).unsqueeze(0)
    for _ in range(transitions):
        action = env.action_space.sample()
        obs, reward, terminated, truncated, _ = env.step(action)
        next_state = None if terminated else torch.tensor(obs, dtype=torch.float32).unsqueeze(0)
        agent.memory.push(state, torch.tensor([[action]]), next_state, torch.tensor([reward]))
        state = next_state
        if terminated or truncated:
            obs, _ = env.reset()
            state = torch.tensor(obs, dtype=torch.float32).unsqueeze(0)
    return agent


def as_list(memory):
    return list(memory.memory)


def time_checkpoints(agent, rounds: int) -> dict[str, dict[str, float]]:
    from keras_rl.runs.checkpoint import read_checkpoint, write_checkpoint

    times: dict[str, dict[str, list[float]]] = {k: {"write": [], "read": [], "bytes": []} for k in ("list", "arrays")}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            for layout in ("list", "arrays"):
                folder = Path(tmp) / layout
                folder.mkdir(exist_ok=True)
                memory = as_list(agent.memory) if layout == "list" else agent.memory.arrays()
                start = time.perf_counter()
                write_checkpoint(folder, {"agent": {"memory": memory}})
                times[layout]["write"].append(time.perf_counter() - start)
                start = time.perf_counter()
                agent.memory.restore(read_checkpoint(folder)["agent"]["memory"])
                times[layout]["read"].append(time.perf_counter() - start)
                times[layout]["bytes"].append((folder / "checkpoint.pkl").stat().st_size)
    return {k: {m: statistics.median(v) for m, v in d.items()} for k, d in times.items()}


def time_seeds(episodes: int, rounds: int) -> dict[str, float]:
    from keras_rl.registry import get_experiment
    from keras_rl.torch.dqn_tutorial import ReplayMemory
    from keras_rl.train.loop import run_seed
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("cartpole")
    arrays = ReplayMemory.arrays
    walls: dict[str, list[float]] = {"list": [], "arrays": []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for layout in ("list", "arrays"):
                ReplayMemory.arrays = as_list if layout == "list" else arrays  # type: ignore[method-assign]
                try:
                    config = exp.config_cls.for_variant("faithful", seed=0, framework="torch", episodes=episodes)
                    start = time.perf_counter()
                    run_seed(exp, config, Path(tmp) / f"{layout}-{r}", TrainSettings(progress=False))
                    walls[layout].append(time.perf_counter() - start)
                finally:
                    ReplayMemory.arrays = arrays  # type: ignore[method-assign]
    return {k: statistics.median(v) for k, v in walls.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transitions", type=int, default=10_000, help="the memory's size (the tutorial's capacity)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--episodes", type=int, default=0, help="also train whole seeds of N episodes, each layout")
    parser.add_argument("--markdown", action="store_true", help="print the result as a Markdown table")
    args = parser.parse_args()
    if args.rounds < 1 or args.transitions < 1 or args.episodes < 0:
        parser.error("--rounds and --transitions must be at least 1, --episodes at least 0")
    from keras_rl.torch import single_threaded

    single_threaded()
    checkpoints = time_checkpoints(filled_agent(args.transitions), args.rounds)
    seeds = time_seeds(args.episodes, max(1, args.rounds // 5)) if args.episodes else None
    old, new = checkpoints["list"], checkpoints["arrays"]
    rows = [
        ("write one checkpoint (s)", old["write"], new["write"]),
        ("read it back (s)", old["read"], new["read"]),
        ("its size (MB)", old["bytes"] / 1e6, new["bytes"] / 1e6),
    ]
    if seeds:
        rows.append((f"a seed of {args.episodes} episodes (s)", seeds["list"], seeds["arrays"]))
    print(f"post 003 (PyTorch) checkpoints, {args.transitions} transitions, median of {args.rounds} rounds;")
    print(f"{platform.processor() or platform.machine()}, one torch thread")
    if args.markdown:
        print("\n| | list of tensors | arrays | ratio |\n|---|---:|---:|---:|")
        for name, a, b in rows:
            print(f"| {name} | {a:.3g} | {b:.3g} | {a / b:.1f}x |")
    else:
        for name, a, b in rows:
            print(f"{name:34s} list {a:10.4g}   arrays {b:10.4g}   {a / b:6.1f}x")


if __name__ == "__main__":
    main()
