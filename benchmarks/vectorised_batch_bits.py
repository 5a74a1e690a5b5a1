"""What sharing a batch changes in one seed's bits on the vectorised engine's two programs.

    python benchmarks/vectorised_batch_bits.py [--steps 700]

Seed 1 of post 003 (PyTorch) alone, in a batch of 3 and in a batch of 8 (``VectorisedDQN``),
eager and compiled (``torch.compile``), ``--steps`` env steps each: are its weights, its
episodes' lengths and its episodes' losses the same bits in every batch? Not a timing: a fact
about the programs, which ``keras_rl/train/vectorised.py``'s docstring states.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

BATCHES = ([1], [0, 1, 2], [5, 1, 7, 3, 4, 2, 0, 6])


def seed_1(batch: list[int], compiled: bool, steps: int):
    """Seed 1's weights and its ended episodes after ``steps`` env steps in ``batch``."""
    from keras_rl.posts.cartpole import CartPoleDQNConfig
    from keras_rl.torch.vectorised import VectorisedDQN

    core = VectorisedDQN([CartPoleDQNConfig(seed=s) for s in batch], compile=compiled)
    ends = [e for e in core.play(steps) if e.seed == 1]
    k = batch.index(1)
    return {name: v[k].clone() for name, v in core.params.items()}, ends


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=700, help="env steps (training starts at the 128th)")
    args = parser.parse_args()
    if args.steps < 129:
        parser.error("--steps must be at least 129, so that seed 1 trains")
    import torch

    from keras_rl.torch import single_threaded

    single_threaded()
    print(f"seed 1, {args.steps} env steps, torch {torch.__version__}; alone against batches {BATCHES[1:]}")
    for compiled in (False, True):
        alone_weights, alone_ends = seed_1(BATCHES[0], compiled, args.steps)
        for batch in BATCHES[1:]:
            weights, ends = seed_1(batch, compiled, args.steps)
            same_weights = all(torch.equal(alone_weights[n], weights[n]) for n in weights)
            same_steps = [e.steps for e in ends] == [e.steps for e in alone_ends]
            gaps = [abs(a.loss_sum - b.loss_sum) / max(abs(a.loss_sum), 1e-300) for a, b in zip(alone_ends, ends)]
            program = "compiled" if compiled else "eager"
            print(
                f"{program:8s} batch of {len(batch)}: weights the same bits: {same_weights}; "
                f"episode lengths the same ({len(ends)} episodes): {same_steps}; losses the same bits: "
                f"{max(gaps) == 0} (largest relative difference {max(gaps):.2g})"
            )


if __name__ == "__main__":
    main()
