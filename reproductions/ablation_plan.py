"""How many seeds settle each quirk ablation the forest reads "inconclusive" (issue 52, item 5),
written down before the runs.

The rule (set 2026-11-27, before any seed past an ablation's 30 ran): take each ablation's
30-seed arm and its faithful arm as they are (``ABLATIONS``: the forest's pair), assume the
difference they show is the true one, and simulate comparisons at ``n`` seeds per arm by drawing
seeds, each with its success and its first passing episode, from each arm's own 30. A comparison
settles when either reading the forest makes is "different" or both are "equivalent within the
margin" (``report/equivalence.py``'s own functions: Newcombe's interval of the success
difference against ±0.15; the percentile-bootstrap interval of the median episodes ratio, a seed
that never reached the threshold counting as the budget plus one, against 0.90-1.10, with 1,000
resamples where the reports take 10,000). The plan is the smallest ``n`` of ``CANDIDATES`` at which
a comparison settles with probability at least 80%, run on the fastest certified engine that runs
the switch; its cost is the ablation arm's ``n`` seeds (the faithful arm is a committed set of at
least ``n`` seeds on that engine) at that engine's median seed time on this machine. Where no
candidate reaches 80%, or the cost passes ``AFFORDABLE_HOURS`` process-hours, the plan says the
ablation stays inconclusive, with the numbers, and nothing runs.

    python reproductions/ablation_plan.py            # print the plan
    python reproductions/ablation_plan.py --write    # results/ablation_plan.{json,md}
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from keras_rl.checkout import ROOT
from keras_rl.report.equivalence import median_ratio_equivalence, success_rate_equivalence
from keras_rl.runs.run_set import RunSet

RESULTS = ROOT / "results"
CANDIDATES = (30, 60, 100, 150, 200, 300, 400, 600, 1000)
PROBABILITY = 0.80
REPS = 200
RESAMPLES = 1_000
AFFORDABLE_HOURS = 20.0


@dataclass(frozen=True)
class Ablation:
    post: str
    switch: str
    """The forest's label: ``field=value``."""
    pilot: str
    """The committed 30-seed ablation arm (under results/)."""
    faithful: str
    """Its faithful arm in the forest."""
    engine: str
    """The fastest certified engine that runs the switch."""
    base: str
    """The committed faithful set on that engine the runs compare against."""


ABLATIONS = (
    Ablation(
        "pendulum",
        "target_copy_is_noop=false",
        "pendulum/ablations-compiled/target_copy_is_noop=false",
        "pendulum/ablations-compiled/base",
        "compiled",
        "checks/pendulum/baseline",
    ),
    Ablation(
        "cartpole",
        "weight_decay=0",
        "cartpole/ablations-compiled/weight_decay=0",
        "cartpole/ablations-compiled/base",
        "compiled",
        "checks/cartpole/baseline",
    ),
    *(
        Ablation(
            "mountaincar",
            switch,
            f"mountaincar/ablations/{switch}",
            "mountaincar/ablations/base",
            "compiled",
            "engines/mountaincar/compiled",
        )
        for switch in ("done_includes_truncation=false", "dqda_at_buffer_actions=false", "store_raw_next_state=false")
    ),
    # the compiled engine runs post 001 with its popping buffer and returns-as-rewards only
    # (train/compiled_scope.py): these two stay on the Gymnasium loop
    *(
        Ablation(
            "mountaincar",
            switch,
            f"mountaincar/ablations/{switch}",
            "mountaincar/ablations/base",
            "gymnasium",
            "checks/mountaincar/baseline,mountaincar/faithful-seeds-100-199,mountaincar/faithful-seeds-200-599",
        )
        for switch in ("episode_returns_as_rewards=false", "popping_buffer=false")
    ),
)


def arm(folder: str) -> tuple[np.ndarray, np.ndarray, int]:
    """(successes 0/1, first passing episode or budget + 1, budget) of each seed of an arm."""
    from keras_rl.report.certified import arm as records_of

    paths = tuple(str(RESULTS / f) for f in folder.split(","))
    records = list(records_of(paths, Path("/")).values())
    budget = int(records[0]["budget_episodes"])
    success = np.array([bool(r["success"]) for r in records])
    episodes = np.array([budget + 1 if r["reached_at_episode"] is None else r["reached_at_episode"] for r in records])
    return success, episodes.astype(float), budget


def settles(a, b, budget: int, rng: np.random.Generator) -> bool:
    """Whether a comparison of these two arms reads different on either quantity, or equivalent on both."""
    success = success_rate_equivalence(int(a[0].sum()), len(a[0]), int(b[0].sum()), len(b[0])).reading
    reached = [[None if e > budget else e for e in arm[1]] for arm in (a, b)]
    ratio = median_ratio_equivalence(reached[0], reached[1], budget, rng=rng, n_resamples=RESAMPLES).reading
    readings = {success, ratio}
    return "different" in readings or readings == {"equivalent within the margin"}


def seed_seconds(folder: str) -> tuple[float, str]:
    """A seed's process-seconds in a committed set (its batches' wall time over its seeds, as the
    manifest counts them; the first folder of a comma-joined arm) and how it ran: its engine, with
    "+batched" where its seeds were seed-batched."""
    runs = RunSet(RESULTS / folder.split(",")[0]).runs()
    batches: dict[tuple, float] = {}
    for run in runs:
        record = run.summary_record()
        key = tuple(record.get("provenance", {}).get("seed_batch") or [run.seed])
        batches[key] = max(batches.get(key, 0.0), float(record.get("wall_seconds") or 0.0))
    engine = runs[0].summary_record().get("provenance", {}).get("engine", "gymnasium")
    batched = any(len(key) > 1 for key in batches)
    return sum(batches.values()) / len(runs), engine + ("+batched" if batched else "")


def plan_one(ablation: Ablation, seed: int) -> dict:
    pilot, faithful = arm(ablation.pilot), arm(ablation.faithful)
    budget = pilot[2]
    rng = np.random.default_rng(seed)
    seconds, pilot_engine = seed_seconds(ablation.pilot)  # the switch's own cost, where its pilot ran on the engine
    if pilot_engine != ablation.engine:
        seconds, _ = seed_seconds(ablation.base)
    rows, chosen = [], None
    for n in CANDIDATES:
        hits = 0
        for _ in range(REPS):
            picks = [rng.integers(0, len(x[0]), n) for x in (pilot, faithful)]
            a, b = ((x[0][p], x[1][p]) for x, p in zip((pilot, faithful), picks))
            hits += settles(a, b, budget, rng)
        p = hits / REPS
        hours = n * seconds / 3600
        rows.append({"n": n, "p_settles": p, "process_hours": hours})
        if p >= PROBABILITY:
            chosen = n
            break
    base_seeds = len(arm(ablation.base)[0])
    entry = {
        "post": ablation.post,
        "switch": ablation.switch,
        "pilot": ablation.pilot,
        "faithful": ablation.faithful,
        "engine": ablation.engine,
        "pilot_engine": pilot_engine,
        "base": ablation.base,
        "base_seeds": base_seeds,
        "seed_seconds": seconds,
        "pilot_successes": [int(pilot[0].sum()), int(faithful[0].sum())],
        "probabilities": rows,
        "seeds_per_arm": chosen,
    }
    cost = rows[-1]["process_hours"]
    if chosen is None:
        entry["decision"] = f"stays inconclusive: no candidate up to {CANDIDATES[-1]} seeds settles it 80% of the time"
    elif cost > AFFORDABLE_HOURS:
        entry["decision"] = (
            f"stays inconclusive: {chosen} seeds would settle it but cost {cost:.1f} process-hours, "
            f"past the {AFFORDABLE_HOURS:g} the issue allows"
        )
    elif chosen > base_seeds:
        entry["decision"] = (
            f"runs {chosen} seeds; the faithful arm needs {chosen - base_seeds} more on {ablation.engine}"
        )
    else:
        entry["decision"] = f"runs {chosen} seeds of the ablation on the {ablation.engine} engine"
    return entry


def commands_of(entry: dict) -> list[str]:
    """The runs that settle it, where the plan runs any (``folder<TAB>keras-rl arguments``): the
    ablation's seeds past those its pilot already holds on the engine, and the faithful arm's past
    its committed set's, as new sets beside the pilot."""
    if entry["seeds_per_arm"] is None or entry["decision"].startswith("stays"):
        return []
    n, post, engine = entry["seeds_per_arm"], entry["post"], entry["engine"]
    first = 30 if entry["pilot_engine"] == engine else 0  # the pilot's seeds 0-29 ran solo on that engine already
    folder = f"results/{post}/ablations-{engine}"
    args = f"--engine {engine} --workers 2 --no-progress --min-success-rate 0"
    runs = [
        f"{folder}/{entry['switch']}-seeds-{first}-{n - 1}\treproduce {post} --seeds {first}-{n - 1} "
        f"--set {entry['switch']} {args}"
    ]
    if n > entry["base_seeds"]:
        b = entry["base_seeds"]
        runs.append(f"{folder}/base-seeds-{b}-{n - 1}\treproduce {post} --seeds {b}-{n - 1} {args}")
    return runs


def render(plan: list[dict]) -> str:
    lines = [
        "# Seeds that settle each inconclusive quirk ablation (planned 2026-11-27, before the runs)",
        "",
        "Generated by `python reproductions/ablation_plan.py --write`; the rule is in its docstring. Each cell: "
        f"seeds per arm: the probability that the comparison settles ({REPS} simulated comparisons, each arm "
        "drawn from its own 30 seeds), and the ablation arm's process-hours at the engine's median seed time.",
        "",
        "| post | ablation | pilot successes (ablation / faithful) | engine (faithful arm) | n: P(settles), hours "
        "| plan |",
        "|---|---|---|---|---|---|",
    ]
    for p in plan:
        cells = "; ".join(f"{r['n']}: {r['p_settles']:.2f}, {r['process_hours']:.1f} h" for r in p["probabilities"])
        base = p["base"].split(",")[0] + (" and more" if "," in p["base"] else "")
        lines.append(
            f"| {p['post']} | `{p['switch']}` | {p['pilot_successes'][0]}/30 / {p['pilot_successes'][1]}/30 "
            f"| {p['engine']} (`{base}`, {p['base_seeds']} seeds) | {cells} | {p['decision']} |"
        )
    runs = [c for p in plan for c in commands_of(p)]
    lines += ["", "The runs, in `maintainers/queues/ablations.tsv` (folder, then the `keras-rl` arguments):", ""]
    lines += [f"    {c.replace(chr(9), '  ')}" for c in runs] or ["    (none)"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write results/ablation_plan.{json,md} and the queue")
    args = parser.parse_args(argv)
    plan = [plan_one(a, i) for i, a in enumerate(ABLATIONS)]
    text = render(plan)
    print(text)
    if args.write:
        from keras_rl.runs.files import atomic_write_json, atomic_write_text

        atomic_write_json(RESULTS / "ablation_plan.json", plan)
        atomic_write_text(RESULTS / "ablation_plan.md", text)
        queue = ["# Issue 52 item 5: the runs results/ablation_plan.md plans (python reproductions/ablation_plan.py)"]
        queue += [c for p in plan for c in commands_of(p)]
        atomic_write_text(ROOT / "maintainers" / "queues" / "ablations.tsv", "\n".join(queue) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
