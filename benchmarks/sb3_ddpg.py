"""Our solo post-000 step against Stable-Baselines3's DDPG with the post's settings, interleaved.

    pip install -e ".[bench]"          # stable-baselines3==2.9.2 (torch stays the pinned 2.13.0)
    python benchmarks/sb3_ddpg.py [--steps 2000] [--rounds 3]

Both learn Pendulum-v1 (g=10) with post 000's settings: 64-64 actor and critic, Adam 1e-3
for both, gamma 0.99, tau 0.001, batch 64, a 2000-transition buffer, one gradient step per
env step from step 1000 on, Ornstein-Uhlenbeck noise (theta 0.15, sigma 0.2, dt 0.1). SB3
runs with one torch thread and ours with one TensorFlow thread, in this one process. Each
round times a block of ``--steps`` training steps of each (after its warm-up: filling to
``train_start`` and the first updates, with tracing and XLA compilation, are not timed), so
the machine's load drifts over both alike; the ratio is SB3's median ms per step over ours.
A third arm is the compiled engine (``--engine compiled``): each round trains post 000's faithful
seed 0 for ``5 + steps/200`` episodes, and its steady rate is the wall time after episode 5
over the steps played since (``episodes.csv``), so its tracing and compilation are not timed
either.
Only this ratio means much: absolute times on a shared machine move 2x between runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import keras_rl  # noqa: E402,F401  (pins the Keras backend before anything imports keras)


def sb3_model():
    """SB3 DDPG on the post's env and settings, learning from step 1000 on, one update per step."""
    try:
        import torch
        from stable_baselines3 import DDPG
        from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise
    except ImportError:
        raise SystemExit('this benchmark needs the bench extra: pip install -e ".[bench]"') from None
    import gymnasium as gym
    import numpy as np

    torch.set_num_threads(1)
    env = gym.make("Pendulum-v1", g=10.0)
    noise = OrnsteinUhlenbeckActionNoise(mean=np.zeros(1), sigma=0.2 * np.ones(1), theta=0.15, dt=0.1)
    return DDPG(
        "MlpPolicy",
        env,
        learning_rate=1e-3,
        buffer_size=2000,
        learning_starts=1000,
        batch_size=64,
        tau=0.001,
        gamma=0.99,
        train_freq=1,
        gradient_steps=1,
        action_noise=noise,
        policy_kwargs={"net_arch": {"pi": [64, 64], "qf": [64, 64]}},
        seed=0,
        device="cpu",
        verbose=0,
    )


class Ours:
    """Post 000's faithful agent, solo (S=1), driven step by step as ``train.loop`` drives it."""

    def __init__(self) -> None:
        from keras_rl.registry import build_agent, get_experiment

        exp = get_experiment("pendulum")
        config = exp.config_cls.for_variant("faithful", stop_at_threshold=False)
        self.env = exp.make_env(config)
        self.env.action_space.seed(0)
        self.agent = build_agent(exp, config, self.env)
        self.action = None
        self.resets = 0

    def play(self, steps: int) -> None:
        for _ in range(steps):
            if self.action is None:
                obs, _ = self.env.reset(seed=self.resets)
                self.resets += 1
                self.action = self.agent.begin_episode(obs)
            obs, reward, terminated, truncated, _ = self.env.step(self.action)
            self.action = self.agent.step(float(reward), obs, terminated, truncated)


def compiled_rate(steps: int) -> float:
    """The compiled engine's steady ms per env step over ``steps`` steps after 5 episodes."""
    import shutil
    import tempfile

    from keras_rl.registry import get_experiment
    from keras_rl.runs.files import read_episodes
    from keras_rl.train.engine import get_engine
    from keras_rl.train.settings import TrainSettings

    exp = get_experiment("pendulum")
    episodes = 5 + max(1, steps // 200)
    config = exp.config_cls.for_variant("faithful", seed=0, episodes=episodes, stop_at_threshold=False)
    folder = Path(tempfile.mkdtemp(prefix="sb3-compiled-"))
    try:
        get_engine("compiled").train(exp, [config], [folder / "seed_0"], TrainSettings(progress=False))
        rows = read_episodes(folder / "seed_0" / "episodes.csv")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    seconds = rows[-1]["wall_seconds"] - rows[4]["wall_seconds"]
    return 1000 * seconds / (rows[-1]["total_steps"] - rows[4]["total_steps"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=2000, help="timed training steps per block (default 2000)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    args = parser.parse_args()
    if args.steps < 1 or args.rounds < 1:
        parser.error("--steps and --rounds must be at least 1")

    from keras_rl.seeding import configure_tensorflow

    configure_tensorflow(1)
    sb3, ours = sb3_model(), Ours()
    sb3.learn(total_timesteps=1100)  # fill to learning_starts, then 100 updates: untimed
    ours.play(1100)
    sb3_ms, our_ms, compiled_ms = [], [], []
    for _ in range(args.rounds):
        start = time.perf_counter()
        sb3.learn(total_timesteps=args.steps, reset_num_timesteps=False)
        sb3_ms.append((time.perf_counter() - start) / args.steps * 1e3)
        start = time.perf_counter()
        ours.play(args.steps)
        our_ms.append((time.perf_counter() - start) / args.steps * 1e3)
        compiled_ms.append(compiled_rate(args.steps))
    import stable_baselines3
    import torch

    s, o, c = statistics.median(sb3_ms), statistics.median(our_ms), statistics.median(compiled_ms)
    print(
        f"Pendulum-v1, post 000's settings, {args.rounds} interleaved rounds of {args.steps} training steps, "
        f"one thread each (SB3 {stable_baselines3.__version__}, torch {torch.__version__})"
    )
    print("| learner | ms per env step (median of rounds) | rounds |")
    print("|---|---|---|")
    print(f"| SB3 DDPG | {s:.3f} | {', '.join(f'{m:.3f}' for m in sb3_ms)} |")
    print(f"| keras-rl post 000, solo | {o:.3f} | {', '.join(f'{m:.3f}' for m in our_ms)} |")
    print(f"| keras-rl post 000, compiled engine | {c:.3f} | {', '.join(f'{m:.3f}' for m in compiled_ms)} |")
    print(f"ours is {s / o:.2f}x SB3's speed per step; the compiled engine {s / c:.1f}x")


if __name__ == "__main__":
    main()
