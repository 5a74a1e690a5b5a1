"""Speed of each post three ways: the post's original code path, our Keras, our PyTorch.

Pendulum and CartPole: ms per env step (acting + one update). MountainCar: ms per training
batch, since post 001 trains in bursts at episode ends. For CartPole the post *is* PyTorch,
so the original code path and our PyTorch version are the same code (the tutorial's).

    python benchmarks/step_time.py [--steps 400] [--json out.json]
    /usr/bin/time -v python benchmarks/step_time.py      # adds peak memory (Maximum resident set size)

Both sides run in this one process, with the same TensorFlow thread settings, over the
same number of env steps after ``train_start`` transitions are stored (filling is not
timed; a short warm-up, which includes tracing and XLA compilation, is not timed either).
Only ratios measured in one run mean anything on a shared machine.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from keras_rl.seeding import configure_tensorflow, seed_everything  # noqa: E402


def time_agent(experiment: str, steps: int, warmup: int, **overrides) -> float:
    """ms per env step of one of our agents (the same loop body as ``keras_rl.train.loop.run_seed``)."""
    from keras_rl.registry import build_agent, get_experiment

    exp = get_experiment(experiment)
    config = exp.config_cls.for_variant("faithful", **overrides)
    env = exp.make_env(config)
    env.action_space.seed(0)
    agent = build_agent(exp, config, env)
    train_start = config.train_start  # the warm-up has one name in every post

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

    from keras_rl.learners.networks import Critic, build
    from maintainers.reference.post000_eager import PostActor, PostAgent, run_steps

    env = gym.make("Pendulum-v1", g=10)
    nets = [build(PostActor(1, 2.0), 3), build(Critic(), 3, 1), build(PostActor(1, 2.0), 3), build(Critic(), 3, 1)]
    agent = PostAgent(*nets)
    run_steps(agent, env, agent.train_start + warmup)
    start = time.perf_counter()
    updates = run_steps(agent, env, steps)
    elapsed = time.perf_counter() - start
    assert updates == steps
    return elapsed / steps * 1e3


def time_post001_updates(batches_wanted: int, with_torch: bool) -> tuple[float, float, float | None]:
    """ms per training batch (one critic + one literal actor update + soft updates) on the
    same popped data: the post's ``Agent.train`` mirrored eagerly, our compiled Keras
    learner, and our PyTorch learner."""
    from maintainers.reference.post001_eager import PostAgent, fill, functional_models

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

    return (
        post_ms,
        time_post001_ours("keras", batches_wanted),
        (time_post001_ours("torch", batches_wanted) if with_torch else None),
    )


def time_post001_ours(framework: str, batches_wanted: int) -> float:
    """ms per training batch of our post 001 learner (``framework``), on one burst of popped data."""
    import random

    from keras_rl.buffers import PoppingBuffer
    from keras_rl.envs import EnvSpec
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig
    from keras_rl.registry import agent_for

    n = 100 + 32 * batches_wanted
    rows = np.random.default_rng(1).normal(size=(n, 2 * 2 + 1 + 2)).astype(np.float32)  # [s 2|a|r|s' 2|done]
    spec = EnvSpec(2, 1, 1.0, obs_low=np.array([-1.2, -0.07]), obs_high=np.array([0.6, 0.07]), max_episode_steps=999)
    agent = agent_for(MountainCarDDPGConfig(framework=framework), spec)
    buffer = PoppingBuffer(n + 1, agent.buffer.layout, random.Random(0))
    buffer.add_rows(rows)
    agent.learner.train(buffer.sample_rows(32))  # trace and compile / warm up
    buffer.add_rows(rows[:32])
    start, count = time.perf_counter(), 0
    while len(buffer) > 100:  # the post's burst: pop and train until 100 are left
        agent.learner.train(buffer.sample_rows(32))
        count += 1
    return (time.perf_counter() - start) / count * 1e3


Row = tuple[str, str, str, "float | None", float, "float | None"]


def keras_rows(steps: int, warmup: int) -> list[Row]:
    """Our Keras side of each post only (``--keras-only``)."""
    return [
        ("pendulum (post 000)", "env step", "-", None, time_agent("pendulum", steps, warmup), None),
        ("cartpole (post 003)", "env step", "-", None, time_agent("cartpole", steps, warmup), None),
        ("mountaincar (post 001)", "train batch", "-", None, time_post001_ours("keras", max(20, steps // 4)), None),
    ]


def all_rows(steps: int, warmup: int, has_torch: bool) -> list[Row]:
    """Each post three ways: the post's original code path, our Keras, our PyTorch."""
    keras_ms = time_agent("pendulum", steps, warmup)
    torch_ms = time_agent("pendulum", steps, warmup, framework="torch") if has_torch else None
    post_ms = time_post000_eager(steps, warmup)
    rows: list[Row] = [
        (
            "pendulum (post 000)",
            "env step",
            "the post's eager Keras loop (get/set_weights)",
            post_ms,
            keras_ms,
            torch_ms,
        )
    ]
    if has_torch:
        keras_ms = time_agent("cartpole", steps, warmup)
        tutorial = time_agent("cartpole", steps, warmup, framework="torch")
        # the post *is* PyTorch: our PyTorch version is the tutorial's own code path
        rows.append(
            (
                "cartpole (post 003)",
                "env step",
                "the PyTorch tutorial's code (= our PyTorch)",
                tutorial,
                keras_ms,
                tutorial,
            )
        )
    post_ms, keras_ms, torch_ms = time_post001_updates(max(20, steps // 4), has_torch)
    rows.append(
        ("mountaincar (post 001)", "train batch", "the post's Agent.train, eager mirror", post_ms, keras_ms, torch_ms)
    )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=400, help="timed env steps per side (default 400)")
    parser.add_argument("--warmup", type=int, default=50)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    parser.add_argument(
        "--keras-only",
        action="store_true",
        help="time only our Keras side of each post (the version matrix compares it across library versions)",
    )
    args = parser.parse_args()
    configure_tensorflow(args.threads)
    seed_everything(0)
    import warnings

    warnings.filterwarnings("ignore")  # the post's tuple action makes Gymnasium's checker warn every step
    import importlib.util

    has_torch = importlib.util.find_spec("torch") is not None
    if not has_torch:
        print("(no torch installed: the PyTorch column and the CartPole row need the torch extra)")

    # (experiment, unit, the post's original code path, its ms, our Keras ms, our PyTorch ms)
    rows = keras_rows(args.steps, args.warmup) if args.keras_only else all_rows(args.steps, args.warmup, has_torch)

    fmt = lambda v: f"{v:8.3f}" if v is not None else f"{'n/a':>8s}"  # noqa: E731
    print(
        f"{'experiment':23s} {'per':11s} {'original code path':46s} {'orig ms':>8s} {'Keras ms':>8s} "
        f"{'torch ms':>8s} {'orig/Keras':>10s} {'torch/Keras':>11s}"
    )
    result = {"steps": args.steps, "threads": args.threads, "rows": []}
    for name, unit, original, orig, mine, theirs in rows:
        torch_ratio = f"{theirs / mine:10.1f}x" if theirs is not None else f"{'n/a':>11s}"
        orig_ratio = f"{orig / mine:9.1f}x" if orig is not None else f"{'n/a':>10s}"
        print(f"{name:23s} {unit:11s} {original:46s} {fmt(orig)} {fmt(mine)} {fmt(theirs)} {orig_ratio} {torch_ratio}")
        result["rows"].append(
            {
                "experiment": name,
                "per": unit,
                "original": original,
                "original_ms": orig,
                "keras_ms": mine,
                "torch_ms": theirs,
                "original_over_keras": orig / mine if orig is not None else None,
                "torch_over_keras": theirs / mine if theirs is not None else None,
            }
        )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process: {peak_mb:.0f} MB")
    result["peak_rss_mb"] = peak_mb
    if args.json:
        from keras_rl.atomic import atomic_write_json

        atomic_write_json(args.json, result)


if __name__ == "__main__":
    main()
