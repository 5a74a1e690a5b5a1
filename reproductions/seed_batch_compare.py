"""Two arms of the same seeds (seed-batched against solo, the compiled engine against the
Gymnasium loop): where they part, and whether it matters.

    python reproductions/seed_batch_compare.py results/mountaincar/faithful \
        results/mountaincar/seed-batch/batch10 --batch-size 10 --write results/mountaincar/seed-batch/report.md
    python reproductions/seed_batch_compare.py results/engines/pendulum/gymnasium \
        results/engines/pendulum/compiled --labels gymnasium,compiled --write results/engines/pendulum/report.md
    python reproductions/seed_batch_compare.py \
        results/checks/mountaincar/baseline,results/mountaincar/faithful-seeds-100-199 \
        results/engines/mountaincar/compiled --labels gymnasium,compiled --write results/engines/mountaincar/report.md

For each seed: the first episode whose row differs (every column but ``wall_seconds``: a
loss rounded differently in the 8th digit counts), the first episode whose score differs (the
seed played a different episode), and episodes to threshold both ways. Over the seeds: success
counts with Fisher's exact test,
the difference of median episodes-to-threshold with a 95% percentile-bootstrap CI, and the
Mann-Whitney U p (``keras_rl/report/stats.py``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.registry import get_experiment
from keras_rl.report.equivalence import CONVERGED_AT_END, Arm, framework_verdict, success_rate_equivalence
from keras_rl.report.stats import censored_mann_whitney, fisher_exact, median_difference_ci
from keras_rl.runs.run_set import RunSet
from keras_rl.runs.summary import RunSummary
from maintainers import plans


def rows(seed_dir: Path) -> list[dict[str, str]]:
    """A seed's rows as written, without wall time (its folder, or its set's runs.parquet)."""
    return RunSet.seed_at(seed_dir).text_rows()


def _first_difference(ra: list[dict], rb: list[dict], key) -> int | None:
    """The first episode (1-based) where ``key`` of the two runs' rows differs, or where one
    run stopped and the other went on; None if none."""
    first = next((i + 1 for i, (x, y) in enumerate(zip(ra, rb)) if key(x) != key(y)), None)
    return first if first or len(ra) == len(rb) else min(len(ra), len(rb)) + 1


def _batch_walls(summaries: list[RunSummary], size: int) -> str:
    """Each batch lasts until its last seed stops: the longest ``wall_seconds`` among its
    seeds. A batch is the seeds a run records as its ``seed_batch`` (the batches it was made
    in, whichever seeds they held), else ``size`` consecutive seeds of the batched folder (all
    of them, also those without a solo twin)."""
    ordered = sorted(summaries, key=lambda s: s.seed)
    batches: dict[tuple, list[float]] = {}
    for i, s in enumerate(ordered):
        made_in = s.provenance.get("seed_batch")
        batches.setdefault(tuple(made_in) if made_in else ("consecutive", i // size), []).append(s.wall_seconds)
    walls = [max(w) for w in batches.values()]
    return (
        f"the {len(walls)} batches the runs record (of up to {size} seeds) took "
        + ", ".join(f"{w:.0f} s" for w in walls)
        + " (each as long as its slowest seed)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "solo",
        help="the reference arm (solo seeds; the Gymnasium loop): a run-set folder, or several "
        "joined by commas (an arm that grew in steps; the first folder holding a seed is read)",
    )
    parser.add_argument("batched", help="the arm judged against it (one folder, or several joined by commas)")
    parser.add_argument("--batch-size", type=int, default=None, help="the --seed-batch the batched runs used")
    parser.add_argument(
        "--labels", default="solo,batched", help="the two arms' names in the report (default solo,batched)"
    )
    parser.add_argument("--write", type=Path, default=None, help="also write the report here (markdown)")
    args = parser.parse_args()
    ref, judged_arm = args.labels.split(",")

    def arm(folders: str) -> dict[int, Path]:
        """Seed -> the first of the comma-joined folders that holds it."""
        where: dict[int, Path] = {}
        for folder in map(Path, folders.split(",")):
            if not folder.is_dir():
                parser.error(f"{folder} is not a folder of run folders")
            for seed in RunSet(folder).seeds:
                where.setdefault(seed, folder)
        return where

    reference, judged_runs = arm(args.solo), arm(args.batched)
    seeds = sorted(reference)
    missing = [s for s in seeds if s not in judged_runs]
    if missing:
        parser.error(f"{args.batched} lacks seeds the reference holds: {missing[:10]}")
    flags = (f" --batch-size {args.batch_size}" if args.batch_size else "") + (
        f" --labels {args.labels}" if args.labels != "solo,batched" else ""
    )
    lines = [
        f"# {'Seed-batched vs solo' if args.labels == 'solo,batched' else f'{judged_arm} vs {ref}'}: "
        f"`{args.batched}` against `{args.solo}`",
        "",
        f"Command: `python reproductions/seed_batch_compare.py {args.solo} {args.batched}{flags}"
        + (f" --write {args.write}`" if args.write else "`"),
        "",
        f"| seed | first differing row | first differing score | {ref}: reached at | {judged_arm}: reached at |",
        "|---|---|---|---|---|",
    ]
    solo_s, batch_s = [], []
    for seed in seeds:
        a, b = (RunSet.seed_at(held[seed] / f"seed_{seed}").summary() for held in (reference, judged_runs))
        solo_s.append(a)
        batch_s.append(b)
        ra = rows(reference[seed] / f"seed_{seed}")
        rb = rows(judged_runs[seed] / f"seed_{seed}")
        first = _first_difference(ra, rb, lambda r: r)
        first_score = _first_difference(ra, rb, lambda r: (r["steps"], r["score"]))
        lines.append(
            f"| {seed} | {first or 'none (identical)'} | {first_score or 'none'} | {a.reached_at_episode} "
            f"| {b.reached_at_episode} |"
        )
    a_arm, b_arm = Arm.of(solo_s), Arm.of(batch_s)
    hits_a, hits_b = a_arm.hits(CONVERGED_AT_END), b_arm.hits(CONVERGED_AT_END)
    n = len(seeds)
    diff = median_difference_ci(hits_b, hits_a, np.random.default_rng(0)) if hits_a and hits_b else None
    budget = RunSet.seed_at(reference[seeds[0]] / f"seed_{seeds[0]}").config()["episodes"]
    _, p = censored_mann_whitney(b_arm.episodes(), a_arm.episodes(), budget)
    fisher = fisher_exact(b_arm.successes, n, a_arm.successes, n)
    headline, judged = framework_verdict(b_arm, a_arm, budget)
    same = sum(x == y for x, y in zip(a_arm.reached, b_arm.reached, strict=True))
    same_outcome = sum(
        (x, u) == (y, v) for x, u, y, v in zip(a_arm.reached, a_arm.success, b_arm.reached, b_arm.success, strict=True)
    )
    config = RunSet.seed_at(reference[seeds[0]] / f"seed_{seeds[0]}").config()
    threshold = float(config["threshold"])
    experiment = get_experiment(config["experiment"])
    metric = experiment.make_metric(experiment.config_cls.from_dict(config))

    def at_end(summaries: list) -> int:
        return sum(s.final_metric is not None and metric.passes(s.final_metric, threshold) for s in summaries)

    median = lambda arm: np.median([budget + 1 if e is None else e for e in arm.episodes()])  # noqa: E731
    lines += [
        "",
        f"- Success: {judged_arm} {b_arm.successes}/{n}, {ref} {a_arm.successes}/{n} (Fisher p = {fisher:.3g}).",
        f"- Same first passing episode (the table's last two columns): {same} of {n} seeds; the same first "
        f"passing episode and the same success: {same_outcome} of {n}.",
        f"- Median episodes to threshold over every seed (the first passing episode, {budget + 1} for a seed "
        f"that never passed): {judged_arm} {median(b_arm):g}, {ref} {median(a_arm):g}.",
        f"- Median episodes to threshold over the successful seeds only ({len(hits_b)} and {len(hits_a)}): "
        f"{judged_arm} {np.median(hits_b) if hits_b else 'n/a'}, {ref} {np.median(hits_a) if hits_a else 'n/a'}; "
        f"{judged_arm} minus {ref} {diff} (95% percentile bootstrap, 10000 resamples).",
        f"- Mann-Whitney U (two-sided, over every seed; one that never reached the threshold counts as "
        f"{budget + 1}) p = {p:.3g}.",
        f"- Equivalence under the margins set before the 30-seed runs (docs/findings.md): {headline}: "
        + "; ".join(e.sentence() for e in judged)
        + ".",
        f"- Success converged at the end (the metric at {threshold:g} or better after the last episode; the "
        f"second reading of success, printed beside the first passing one, which governs): {judged_arm} "
        f"{at_end(batch_s)}/{n}, {ref} {at_end(solo_s)}/{n}: "
        + success_rate_equivalence(at_end(batch_s), n, at_end(solo_s), n).sentence()
        + ".",
        f"- Wall time: the {ref} seeds took {sum(s.wall_seconds for s in solo_s):.0f} s of seed time in all; "
        + (
            _batch_walls(RunSet(Path(args.batched)).summaries(), args.batch_size)
            if args.batch_size
            else f"the {judged_arm} seeds {sum(s.wall_seconds for s in batch_s):.0f} s"
        )
        + ".",
        "",
    ]
    text = plans.disclosed("\n".join(lines), plans.report_path(args.write))
    print(text)
    if args.write:
        atomic_write_text(args.write, text)


if __name__ == "__main__":
    main()
