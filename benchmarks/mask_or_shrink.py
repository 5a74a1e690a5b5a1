"""Mask or shrink: what finished seeds cost a seed-batched run, measured.

    python benchmarks/mask_or_shrink.py results/pendulum/seed-batch/batch10 --batch-size 10
    python benchmarks/mask_or_shrink.py results/cartpole/seed-batch/batch10 --batch-size 10 \
        --write results/cartpole/seed-batch/mask_or_shrink.md

The batched loop masks a seed that has finished: its slice stays in the compiled call, so
the call's cost does not fall as seeds finish (its env, buffer and records stop at once).
Shrinking would rebuild the stacked learner from the running seeds' slices each time one
finishes: a cheaper call from then on, for a rebuild and a fresh compile each time.

This measures both sides here, now: the compiled train-and-act call at every batch size
from 1 to S (``benchmarks/seed_batch.py``'s ``learner_call_ms``), and the rebuild (stacking
and compiling the learner's steps for k seeds). It reads how many seeds were still running
at each vector step from the committed batched runs (each seed's ``total_steps``), and
prints the learner time of each batch under three policies: mask = vector steps x call(S);
shrink at every finish = the sum over vector steps of call(running seeds) + one rebuild per
finish; shrink once, when half the seeds have finished, to the other half.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from keras_rl.runs.files import atomic_write_text
from keras_rl.runs.run_set import RunSet


def rebuild_seconds(experiment: str, seeds: int) -> float:
    """Stack ``seeds`` seeds' learner and compile its steps (what one shrink costs)."""
    import numpy as np

    from keras_rl.learners.table import stacked_implementation
    from keras_rl.registry import get_experiment

    exp = get_experiment(experiment)
    configs = [exp.config_cls.for_variant("faithful", seed=s) for s in range(seeds)]
    env = exp.make_env(configs[0])
    spec = exp.env_spec(env)
    env.close()
    start = time.perf_counter()
    learner = stacked_implementation(experiment, "keras").load()(configs, spec)
    layout = learner.layout if hasattr(learner, "layout") else learner.learner.layout
    rows = np.zeros((seeds, configs[0].batch_size, layout.width), np.float32)
    states = rows[:, 0, : layout.obs_dim]
    learner.train_and_act(rows, states)
    learner.act(states)
    learner.step_without_batch(states)
    learner.train(rows)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("batched", type=Path, help="a folder of seed-batched runs (seed_<n>/summary.json)")
    parser.add_argument("--batch-size", type=int, required=True, help="the --seed-batch the runs used")
    parser.add_argument("--write", type=Path, default=None, help="also write the table here (markdown)")
    args = parser.parse_args()
    summaries = RunSet(args.batched).summaries()
    if not summaries:
        raise SystemExit(f"error: no seed_<n>/summary.json under {args.batched}")
    experiment = summaries[0].experiment

    from seed_batch import learner_call_ms

    from keras_rl.seeding import configure_tensorflow

    configure_tensorflow(1)
    size = args.batch_size
    call = {k: learner_call_ms(experiment, k) / 1000 for k in range(1, size + 1)}
    rebuild = {k: rebuild_seconds(experiment, k) for k in sorted({1, size // 2, size - 1} - {0})}

    def rebuild_cost(k: int) -> float:  # nearest measured size
        return rebuild[min(rebuild, key=lambda m: abs(m - k))]

    lines = [
        f"# Mask or shrink: `{args.batched}` (batches of {size})",
        "",
        f"Command: `python benchmarks/mask_or_shrink.py {args.batched} --batch-size {size}"
        + (f" --write {args.write}`" if args.write else "`"),
        "",
        "Measured here: the compiled train-and-act call per vector step, "
        + ", ".join(f"{k} seeds {call[k] * 1000:.2f} ms" for k in call)
        + "; a rebuild (stack and compile) "
        + ", ".join(f"{k} seeds {v:.1f} s" for k, v in rebuild.items())
        + ".",
        "",
        "| batch (seeds) | vector steps | seed steps run | learner s, mask | learner s, shrink at every finish "
        "| learner s, shrink once at half | best |",
        "|---|---|---|---|---|---|---|",
    ]
    for i in range(0, len(summaries), size):
        group = summaries[i : i + size]
        ends = sorted(s.total_steps for s in group)
        mask = ends[-1] * call[len(group)]
        shrink, previous, running = 0.0, 0, len(group)
        for end in ends:
            shrink += (end - previous) * call[running]
            previous, running = end, running - 1
            if running:
                shrink += rebuild_cost(running)
        half = ends[len(group) // 2 - 1] if len(group) > 1 else ends[-1]  # when half the seeds have finished
        kept = len(group) - len(group) // 2
        once = half * call[len(group)] + (
            rebuild_cost(kept) + (ends[-1] - half) * call[kept] if kept < len(group) else 0.0
        )
        best = min((mask, "mask"), (shrink, "shrink at every finish"), (once, "shrink once"))[1]
        lines.append(
            f"| {group[0].seed}..{group[-1].seed} | {ends[-1]} | {sum(ends)} | {mask:.0f} | {shrink:.0f} "
            f"| {once:.0f} | {best} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        atomic_write_text(args.write, text)


if __name__ == "__main__":
    main()
