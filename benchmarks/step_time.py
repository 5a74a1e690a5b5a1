"""ms per env step (acting + one update) of our compiled loop vs the posts' own code paths.

    python benchmarks/step_time.py [--steps 400] [--json out.json]
    /usr/bin/time -v python benchmarks/step_time.py      # adds peak memory (Maximum resident set size)

Both sides run in this one process, with the same TensorFlow thread settings, over the
same number of env steps after ``train_start`` transitions are stored (filling is not
timed; a short warm-up, which includes tracing and XLA compilation, is not timed either).
Only ratios measured in one run mean anything on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from keras_rl.seeding import configure_tensorflow, seed_everything  # noqa: E402


def time_agent(experiment: str, steps: int, warmup: int, **overrides) -> float:
    """ms per env step of one of our agents (the same loop body as ``keras_rl.loop.run_seed``)."""
    from keras_rl.experiments import get_experiment

    exp = get_experiment(experiment)
    config = exp.config_cls.for_variant("faithful", **overrides)
    env = exp.make_env(config)
    env.action_space.seed(0)
    agent = exp.make_agent(config, env)
    train_start = getattr(config, "train_start", getattr(config, "batch_size", 0))

    def play(n: int) -> float:
        done_steps, start = 0, time.perf_counter()
        while done_steps < n:
            obs, _ = env.reset(seed=done_steps)
            action = agent.begin_episode(obs)
            while action is not None and done_steps < n:
                obs, reward, terminated, truncated, _ = env.step(action)
                action = agent.step(float(reward), obs, terminated, truncated)
                done_steps += 1
        return time.perf_counter() - start

    play(train_start + warmup)  # fill to the first update, then trace/compile/warm up
    assert agent.updates >= warmup
    before = agent.updates
    elapsed = play(steps)
    assert agent.updates - before == steps, "every timed step must include one update"
    return elapsed / steps * 1e3


def time_post000_eager(steps: int, warmup: int) -> float:
    import gymnasium as gym

    from keras_rl.networks import Critic, build
    from keras_rl.reference.post000_eager import PostActor, PostAgent, run_steps

    env = gym.make("Pendulum-v1", g=10)
    nets = [build(PostActor(1, 2.0), 3), build(Critic(), 3, 1), build(PostActor(1, 2.0), 3), build(Critic(), 3, 1)]
    agent = PostAgent(*nets)
    run_steps(agent, env, agent.train_start + warmup)
    start = time.perf_counter()
    updates = run_steps(agent, env, steps)
    elapsed = time.perf_counter() - start
    assert updates == steps
    return elapsed / steps * 1e3


def time_post001_updates(batches_wanted: int) -> tuple[float, float]:
    """ms per training batch (one critic + one literal actor update + soft updates):
    the post's ``Agent.train`` mirrored eagerly vs our compiled learner, same popped data."""
    from keras_rl.buffers import PoppingBuffer
    from keras_rl.configs import MountainCarDDPGConfig
    from keras_rl.episodic_ddpg import EpisodicDDPGAgent
    from keras_rl.reference.post001_eager import PostAgent, fill, functional_models

    import random

    rng = np.random.default_rng(0)
    n = 100 + 32 * batches_wanted
    actor, critic = functional_models()
    target_actor, target_critic = functional_models()
    post = PostAgent(actor, critic, target_actor, target_critic)
    fill(post, n, rng)
    post.train()  # warm up
    fill(post, n, rng)
    start = time.perf_counter()
    batches = post.train()
    post_ms = (time.perf_counter() - start) / batches * 1e3

    agent = EpisodicDDPGAgent(MountainCarDDPGConfig(), np.array([-1.2, -0.07]), np.array([0.6, 0.07]), 1, 999)
    buffer = PoppingBuffer(n + 1, agent.layout, random.Random(0))
    rows = rng.normal(size=(n, agent.layout.width)).astype(np.float32)
    buffer.add_rows(rows)
    agent.learner.train(buffer.sample_rows(32))  # trace and compile
    buffer.add_rows(rows[:32])
    start, ours_batches = time.perf_counter(), 0
    while len(buffer) > 100:
        agent.learner.train(buffer.sample_rows(32))
        ours_batches += 1
    ours_ms = (time.perf_counter() - start) / ours_batches * 1e3
    return post_ms, ours_ms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=400, help="timed env steps per side (default 400)")
    parser.add_argument("--warmup", type=int, default=50)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = parser.parse_args()
    configure_tensorflow(args.threads)
    seed_everything(0)
    import warnings

    warnings.filterwarnings("ignore")  # the post's tuple action makes Gymnasium's checker warn every step

    rows = []
    ours = time_agent("pendulum", args.steps, args.warmup)
    post = time_post000_eager(args.steps, args.warmup)
    rows.append(("pendulum (post 000)", "post's eager loop (get/set_weights)", post, "keras_rl compiled (XLA)", ours))
    try:
        import torch  # noqa: F401
    except ImportError:
        print("(no torch installed: the CartPole row needs the torch extra)")
    else:
        ours = time_agent("cartpole", args.steps, args.warmup)
        tutorial = time_agent("cartpole", args.steps, args.warmup, framework="torch")
        rows.append(("cartpole (post 003)", "PyTorch tutorial code (state-dict soft update)", tutorial,
                     "keras_rl compiled (XLA)", ours))

    post_ms, ours_ms = time_post001_updates(max(20, args.steps // 4))
    rows.append(("mountaincar (post 001)", "post's Agent.train, eager mirror (per batch)", post_ms,
                 "keras_rl compiled (XLA)", ours_ms))

    print(f"{'experiment':22s} {'baseline':48s} {'ms/step':>8s}   {'ours':26s} {'ms/step':>8s} {'speed-up':>9s}")
    result = {"steps": args.steps, "threads": args.threads, "rows": []}
    for name, base_name, base, ours_name, mine in rows:
        print(f"{name:22s} {base_name:48s} {base:8.3f}   {ours_name:26s} {mine:8.3f} {base / mine:8.1f}x")
        result["rows"].append({"experiment": name, "baseline": base_name, "baseline_ms_per_step": base,
                               "ours": ours_name, "ours_ms_per_step": mine, "speedup": base / mine})
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process: {peak_mb:.0f} MB")
    result["peak_rss_mb"] = peak_mb
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
