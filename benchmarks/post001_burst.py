"""Would post 001 pay on the compiled engine? Its training burst as one XLA program against the
loop's one call per batch (issue 34's "post 001, solo, per training batch: measured; build it
if at least 2x").

    python benchmarks/post001_burst.py                     # 28 batches a burst, 5 rounds
    python benchmarks/post001_burst.py --batches 56 --rounds 9

Post 001 trains in bursts (``agents/schedules.Bursts``): once its popping buffer holds more than
1,000 transitions it pops batch after batch of 32, each its own update, until 100 are left:
about 28 updates every ~900 env steps. Today each update is one call of the learner's compiled
``train`` (an XLA program per batch). A compiled engine for post 001 would run a whole burst as
one program: the learner's own ``update`` traced into a loop over the burst's batches (no second
copy of the update), one host call per burst. Both arms start from the same weights and
optimizer state and train on the same popped batches; the script checks they end within 1e-6
of each other, then times them, alternating, in this one process.

The env steps between bursts are not in either arm: post 001's acting (999 steps an episode,
one actor call each) would be compiled too, and is measured by ``benchmarks/step_time.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from datetime import date

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batches", type=int, default=28, help="updates a burst (default 28: 1,000 down to 100)")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    if args.batches < 1 or args.rounds < 1:
        parser.error("--batches and --rounds must be at least 1")

    import numpy as np
    import tensorflow as tf

    from keras_rl.envs import EnvSpec
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig
    from keras_rl.registry import agent_for
    from keras_rl.seeding import configure_tensorflow, seed_everything

    configure_tensorflow(1)
    seed_everything(0)
    config = MountainCarDDPGConfig()
    spec = EnvSpec(2, 1, 1.0, obs_low=np.array([-1.2, -0.07]), obs_high=np.array([0.6, 0.07]), max_episode_steps=999)
    learner = agent_for(config, spec).learner
    width = learner.layout.width
    rows = np.random.default_rng(1).normal(size=(args.batches, config.batch_size, width)).astype(np.float32)
    rows[..., -1] = rows[..., -1] > 0  # done flags
    start = learner.state_dict()

    def per_batch() -> dict:
        for k in range(args.batches):
            losses = learner.train(rows[k])
        return losses

    names = learner.loss_names
    burst_rows = tf.constant(rows)

    @tf.function(jit_compile=True)
    def burst(batches):
        out = tf.TensorArray(tf.float32, args.batches, element_shape=[len(names)])
        for k in tf.range(args.batches):
            losses = learner.update(batches[k])
            out = out.write(k, tf.stack([losses[n] for n in names]))
        return out.stack()

    program = burst.get_concrete_function(tf.TensorSpec(rows.shape, tf.float32))

    # the same computation: from the same state, both arms end within 1e-6
    learner.load_state_dict(start)
    per_batch()
    after_calls = [v.copy() for v in learner.state_dict()["variables"]]
    learner.load_state_dict(start)
    program(burst_rows).numpy()
    after_burst = learner.state_dict()["variables"]
    worst = max(float(np.max(np.abs(a - b))) if a.size else 0.0 for a, b in zip(after_calls, after_burst))
    if worst > 1e-6:
        raise SystemExit(f"the arms part: the largest weight difference after a burst is {worst:.2e}")

    times: dict[str, list[float]] = {"one call per batch (today)": [], "one program per burst": []}
    for _ in range(args.rounds):
        learner.load_state_dict(start)
        t = time.perf_counter()
        per_batch()
        times["one call per batch (today)"].append((time.perf_counter() - t) / args.batches * 1e3)
        learner.load_state_dict(start)
        t = time.perf_counter()
        program(burst_rows).numpy()
        times["one program per burst"].append((time.perf_counter() - t) / args.batches * 1e3)

    med = {arm: statistics.median(ts) for arm, ts in times.items()}
    print(
        f"`python benchmarks/post001_burst.py --batches {args.batches} --rounds {args.rounds}` ({date.today()}, "
        f"{platform.machine()}, one TensorFlow thread; post 001's faithful learner, {args.batches} batches of "
        f"{config.batch_size} a burst, medians of {args.rounds} rounds; the arms end within {worst:.1e}):\n"
    )
    print("| arm | ms per training batch | rounds |")
    print("|---|---|---|")
    for arm, ts in times.items():
        print(f"| {arm} | {med[arm]:.3f} | {', '.join(f'{t:.3f}' for t in ts)} |")
    ratio = med["one call per batch (today)"] / med["one program per burst"]
    print(f"\nA burst as one program: **{ratio:.2f}x** per training batch (issue 34 builds it at 2x or more).")


if __name__ == "__main__":
    main()
