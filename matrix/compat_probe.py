"""Why a cell of the version matrix changes bits: the first numbers each post computes, dumped
in one interpreter and compared across two.

    python matrix/compat_probe.py dump OUT.npz          # in each virtualenv
    python matrix/compat_probe.py compare REF.npz CELL.npz [--json OUT.json]

For each post (Keras, faithful variant, seed 0, as a solo run builds it): the initial weights,
the first action on the env's first state, then one update on a fixed batch (drawn from NumPy's
``default_rng(0)``, in the learner's own row layout) and the losses and weights after it. The
comparison gives, per post and quantity, the largest absolute difference: 0 where the two
library versions compute the same bits, about 1e-7 (float32 rounding) where a kernel rounds
differently, more where the computation itself changed. ``compat_cell.py`` runs it in the
reference and in each cell (``probe.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

import numpy as np  # noqa: E402

POSTS = ("pendulum", "cartpole", "mountaincar")
NETWORKS = ("actor", "critic", "target_actor", "target_critic", "q_network", "target_network")


def weights(learner) -> list[np.ndarray]:
    out = []
    for name in NETWORKS:
        model = getattr(learner, name, None)
        if model is not None:
            out += [np.asarray(w) for w in model.get_weights()]
    return out


def probe(post: str) -> dict[str, np.ndarray]:
    from keras_rl.registry import build_agent, get_experiment
    from keras_rl.seeding import configure_tensorflow, seed_everything

    configure_tensorflow(1)
    experiment = get_experiment(post)
    config = experiment.config_cls.for_variant("faithful", seed=0)
    seed_everything(0)  # as a solo run: Keras seeded with the seed, then the env, then the learner
    env = experiment.make_env(config)
    env.action_space.seed(0)
    agent = build_agent(experiment, config, env)
    learner = agent.learner
    out: dict[str, np.ndarray] = {}
    for i, w in enumerate(weights(learner)):
        out[f"initial/{i}"] = w
    obs, _ = env.reset(seed=0)
    out["first_action"] = np.asarray(agent.greedy_action(obs), dtype=np.float64)
    width, batch = agent.buffer.layout.width, config.batch_size
    rows = np.random.default_rng(0).uniform(-1, 1, size=(batch, width)).astype(np.float32)
    losses = learner.train(rows)
    for name, value in losses.items():
        out[f"loss/{name}"] = np.asarray(value, dtype=np.float64)
    for i, w in enumerate(weights(learner)):
        out[f"updated/{i}"] = w
    return out


def dump(path: Path) -> None:
    arrays = {}
    for post in POSTS:
        arrays.update({f"{post}/{k}": v for k, v in probe(post).items()})
    np.savez(path, **arrays)


def compare(reference: Path, cell: Path) -> dict:
    a, b = np.load(reference), np.load(cell)
    result: dict = {}
    for post in POSTS:
        entry = {}
        for quantity in ("initial", "first_action", "loss", "updated"):
            keys = sorted(k for k in a.files if k.startswith(f"{post}/{quantity}"))
            if sorted(k for k in b.files if k.startswith(f"{post}/{quantity}")) != keys:
                entry[quantity] = "different shapes or names"
                continue
            diff = max(float(np.max(np.abs(a[k].astype(np.float64) - b[k].astype(np.float64)))) for k in keys)
            entry[quantity] = diff
        result[post] = entry
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    d = sub.add_parser("dump")
    d.add_argument("out", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("reference", type=Path)
    c.add_argument("cell", type=Path)
    c.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    if args.command == "dump":
        dump(args.out)
        return
    result = compare(args.reference, args.cell)
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
