"""Where a version matrix cell's first episode parts from the reference's, step by step.

    python matrix/compat_first_episode.py dump OUT.npy [--experiment pendulum]   # in each virtualenv
    python matrix/compat_first_episode.py compare REF.npy CELL.npy

Post 000's (or another post's) faithful seed 0, built as a solo run builds it, plays its first
episode; each step's observation and action are recorded. ``compare`` names the first step and
column that differ, and the largest difference over the episode: it tells a changed
environment or explorer apart from the rounding of a math function.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

import numpy as np  # noqa: E402


def dump(out: Path, experiment_name: str) -> None:
    from keras_rl.registry import build_agent, get_experiment
    from keras_rl.seeding import configure_tensorflow, seed_everything

    configure_tensorflow(1)
    experiment = get_experiment(experiment_name)
    config = experiment.config_cls.for_variant("faithful", seed=0)
    seed_everything(0)
    env = experiment.make_env(config)
    env.action_space.seed(0)
    agent = build_agent(experiment, config, env)
    obs, _ = env.reset(seed=0)
    action, rows = agent.begin_episode(obs), []
    while action is not None:
        rows.append(np.r_[np.asarray(obs, np.float64).ravel(), np.asarray(action, np.float64).ravel()])
        obs, reward, terminated, truncated, _ = env.step(action)
        action = agent.step(float(reward), obs, terminated, truncated)
        if terminated or truncated:
            break
    np.save(out, np.array(rows))


def compare(a_path: Path, b_path: Path) -> None:
    a, b = np.load(a_path), np.load(b_path)
    steps = min(len(a), len(b))
    diff = np.abs(a[:steps] - b[:steps])
    differing = np.nonzero(diff.max(axis=1) > 0)[0]
    if len(a) != len(b):
        print(f"episode lengths differ: {len(a)} and {len(b)}")
    if not len(differing):
        print(f"the first {steps} steps are the same bits")
        return
    step = int(differing[0])
    columns = np.nonzero(diff[step] > 0)[0].tolist()
    print(
        f"first difference at step {step}, columns {columns} (observation then action), by {diff[step].max():.3g}; "
        f"the largest over the episode {diff.max():.3g}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    d = sub.add_parser("dump")
    d.add_argument("out", type=Path)
    d.add_argument("--experiment", default="pendulum")
    c = sub.add_parser("compare")
    c.add_argument("reference", type=Path)
    c.add_argument("cell", type=Path)
    args = parser.parse_args()
    if args.command == "dump":
        dump(args.out, args.experiment)
    else:
        compare(args.reference, args.cell)


if __name__ == "__main__":
    main()
