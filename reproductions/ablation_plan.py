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

The second look (rule set 2026-11-27, after ``store_raw_next_state=false`` read equivalent on
success and inconclusive on the median ratio at its 150 planned seeds, 1 (0.968 to 1.13), and
before any seed past them ran): an ablation that the forest reads at its planned seeds as still
unsettled (no reading different, not both equivalent) is planned once more by the same rule, each
arm now drawn from its own planned seeds instead of the pilot's 30, over the candidates above the
first plan's count, and run to it where affordable. There is no third look: what the second
leaves unsettled stays so, with its numbers. The forest marks the row as a second look; its
interval is not adjusted for the first look (the same seeds are read again with more beside them).

    python reproductions/ablation_plan.py --second            # print the second look's plan
    python reproductions/ablation_plan.py --second --write    # results/ablation_plan_second.{json,md}
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/

import numpy as np

from keras_rl.report.equivalence import median_ratio_equivalence, success_rate_equivalence
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT

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


def arm(folder: str, below: int | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """(successes 0/1, first passing episode or budget + 1, budget) of each seed of an arm (its
    seeds below ``below`` only, where given: an arm read at its planned seeds)."""
    from maintainers.certified import arm as records_of

    paths = tuple(str(RESULTS / f) for f in folder.split(","))
    held = records_of(paths, Path("/"))
    records = [held[s] for s in sorted(held) if below is None or s < below]
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


def simulate(ablation_arm, faithful_arm, budget: int, candidates, seconds: float, rng) -> tuple[list[dict], int | None]:
    """Each candidate ``n``'s chance that a comparison settles, drawing each arm's ``n`` seeds from
    its own, until one reaches ``PROBABILITY``: (the rows, the chosen ``n`` or None)."""
    rows, chosen = [], None
    for n in candidates:
        hits = 0
        for _ in range(REPS):
            picks = [rng.integers(0, len(x[0]), n) for x in (ablation_arm, faithful_arm)]
            a, b = ((x[0][p], x[1][p]) for x, p in zip((ablation_arm, faithful_arm), picks))
            hits += settles(a, b, budget, rng)
        p = hits / REPS
        rows.append({"n": n, "p_settles": p, "process_hours": n * seconds / 3600})
        if p >= PROBABILITY:
            chosen = n
            break
    return rows, chosen


def decision(chosen: int | None, cost: float, base_seeds: int, engine: str, candidates) -> str:
    if chosen is None:
        return f"stays inconclusive: no candidate up to {candidates[-1]} seeds settles it 80% of the time"
    if cost > AFFORDABLE_HOURS:
        return (
            f"stays inconclusive: {chosen} seeds would settle it but cost {cost:.1f} process-hours, "
            f"past the {AFFORDABLE_HOURS:g} the issue allows"
        )
    if chosen > base_seeds:
        return f"runs {chosen} seeds; the faithful arm needs {chosen - base_seeds} more on {engine}"
    return f"runs {chosen} seeds of the ablation on the {engine} engine"


def plan_one(ablation: Ablation, seed: int) -> dict:
    pilot, faithful = arm(ablation.pilot), arm(ablation.faithful)
    budget = pilot[2]
    rng = np.random.default_rng(seed)
    seconds, pilot_engine = seed_seconds(ablation.pilot)  # the switch's own cost, where its pilot ran on the engine
    if pilot_engine != ablation.engine:
        seconds, _ = seed_seconds(ablation.base)
    rows, chosen = simulate(pilot, faithful, budget, CANDIDATES, seconds, rng)
    base_seeds = len(arm(ablation.base)[0])
    return {
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
        "decision": decision(chosen, rows[-1]["process_hours"], base_seeds, ablation.engine, CANDIDATES),
    }


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


def first_look_arms(entry: dict) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The sets each arm of ``entry`` is read from at its planned seeds, as the forest reads them:
    the pilot where it ran on the plan's engine and the plan's runs, against its base and the
    plan's base runs."""
    from maintainers.plans import ablation_arms

    folders = [c.split("\t")[0].removeprefix("results/") for c in commands_of(entry)]
    pilot = (entry["pilot"],) if entry["pilot_engine"] == entry["engine"] else ()
    return ablation_arms(entry["switch"], pilot, tuple(entry["base"].split(",")), folders)


def unsettled(row: dict | None) -> bool:
    """A forest row read (not pending) with no reading different and not both equivalent."""
    if row is None or row["pending"]:
        return False
    readings = {row["success"]["reading"], row["speed"]["reading"]}
    return "different" not in readings and readings != {"equivalent within the margin"}


def second_look(entry: dict, row: dict, seed: int) -> dict:
    """The second look's plan for a first look the forest read unsettled (the docstring's rule)."""
    n, post, engine, switch = entry["seeds_per_arm"], entry["post"], entry["engine"], entry["switch"]
    ablation_sets, faithful_sets = first_look_arms(entry)
    ablation_arm, faithful_arm = arm(",".join(ablation_sets), below=n), arm(",".join(faithful_sets), below=n)
    candidates = [c for c in CANDIDATES if c > n]
    rng = np.random.default_rng(seed)
    rows, chosen = simulate(ablation_arm, faithful_arm, ablation_arm[2], candidates, entry["seed_seconds"], rng)
    base_seeds = len(arm(",".join(faithful_sets))[0])
    cost = rows[-1]["process_hours"]
    runs = []
    if chosen is not None and cost <= AFFORDABLE_HOURS:
        folder = f"results/{post}/ablations-{engine}"
        args = f"--engine {engine} --workers 2 --no-progress --min-success-rate 0"
        runs.append(
            f"{folder}/{switch}-seeds-{n}-{chosen - 1}\treproduce {post} --seeds {n}-{chosen - 1} --set {switch} {args}"
        )
        if chosen > base_seeds:
            span = f"{base_seeds}-{chosen - 1}"
            runs.append(f"{folder}/base-seeds-{span}\treproduce {post} --seeds {span} {args}")
    return {
        "post": post,
        "switch": switch,
        "engine": engine,
        "first_seeds": n,
        "first_reading": {
            k: {x: row[k][x] for x in ("estimate", "low", "high", "reading")} for k in ("success", "speed")
        },
        "ablation_sets": list(ablation_sets),
        "faithful_sets": list(faithful_sets),
        "faithful_seeds": base_seeds,
        "seed_seconds": entry["seed_seconds"],
        "successes_at_first_look": [int(ablation_arm[0].sum()), int(faithful_arm[0].sum())],
        "probabilities": rows,
        "seeds_per_arm": chosen,
        "decision": decision(chosen, cost, base_seeds, engine, candidates).replace("runs", "runs to", 1),
        "runs": runs,
    }


def second_plan(plan: list[dict]) -> list[dict]:
    """A second look for every planned ablation the committed forest reads unsettled."""
    import json

    forest = json.loads((RESULTS / "forest.json").read_text())["rows"]
    out = []
    for i, entry in enumerate(plan):
        if entry["seeds_per_arm"] is None or entry["decision"].startswith("stays"):
            continue
        group = f"{entry['post']} ablation vs faithful, the planned seeds"
        label = f"{entry['switch']} ({entry['seeds_per_arm']} planned)"
        row = next((r for r in forest if r["group"] == group and r["label"] == label), None)
        if unsettled(row):
            out.append(second_look(entry, row, 100 + i))
    return out


def render_second(plan: list[dict]) -> str:
    lines = [
        "# The second look at the quirk ablations still unsettled at their planned seeds (planned 2026-11-27, "
        "before the runs)",
        "",
        "Generated by `python reproductions/ablation_plan.py --second --write`; the rule is in its docstring "
        "(the second look). Each cell: seeds per arm: the probability that the comparison settles "
        f"({REPS} simulated comparisons, each arm drawn from its own planned seeds), and the ablation arm's "
        "process-hours. The reading at the second look is not adjusted for the first.",
        "",
        "| post | ablation | first look: seeds, success difference, median ratio | n: P(settles), hours | plan |",
        "|---|---|---|---|---|",
    ]

    def reading(v: dict) -> str:
        return f"{v['estimate']:.3g} ({v['low']:.3g} to {v['high']:.3g}): {v['reading']}"

    for p in plan:
        cells = "; ".join(f"{r['n']}: {r['p_settles']:.2f}, {r['process_hours']:.1f} h" for r in p["probabilities"])
        first = p["first_reading"]
        lines.append(
            f"| {p['post']} | `{p['switch']}` | {p['first_seeds']}; {reading(first['success'])}; "
            f"{reading(first['speed'])} | {cells} | {p['decision']} |"
        )
    runs = [c for p in plan for c in p["runs"]]
    lines += ["", "The runs, in `maintainers/queues/ablations-second.tsv` (folder, then the `keras-rl` arguments):", ""]
    lines += [f"    {c.replace(chr(9), '  ')}" for c in runs] or ["    (none)"]
    return "\n".join(lines) + "\n"


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


def write(name: str, plan: list[dict], text: str, queue: str, heading: str, runs: list[str]) -> None:
    """``results/<name>.{json,md}`` and the queue of the runs it plans, ``maintainers/queues/<queue>``:
    once. A plan is written before its runs; redrawn after them it would read other data (the
    second look's, a forest that has read it), so a committed one is never replaced by accident."""
    from keras_rl.atomic import atomic_write_json, atomic_write_text
    from keras_rl.errors import ConfigError

    if (RESULTS / f"{name}.json").exists():
        raise ConfigError(
            f"results/{name}.json exists: a plan is written once, before its runs; delete it (and say why in "
            "the commit) to plan again, or leave out --write to print what it would say now"
        )
    atomic_write_json(RESULTS / f"{name}.json", plan)
    atomic_write_text(RESULTS / f"{name}.md", text)
    atomic_write_text(ROOT / "maintainers" / "queues" / queue, "\n".join([f"# {heading}", *runs]) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write results/ablation_plan.{json,md} and the queue")
    parser.add_argument(
        "--second", action="store_true", help="the second look, from the committed plan and forest (its own files)"
    )
    args = parser.parse_args(argv)
    if args.second:
        import json

        second = second_plan(json.loads((RESULTS / "ablation_plan.json").read_text()))
        text = render_second(second)
        print(text)
        if args.write:
            heading = "Issue 52 item 5, the second look: results/ablation_plan_second.md's runs"
            write(
                "ablation_plan_second",
                second,
                text,
                "ablations-second.tsv",
                heading,
                [c for p in second for c in p["runs"]],
            )
        return 0
    plan = [plan_one(a, i) for i, a in enumerate(ABLATIONS)]
    text = render(plan)
    print(text)
    if args.write:
        heading = "Issue 52 item 5: the runs results/ablation_plan.md plans (python reproductions/ablation_plan.py)"
        write("ablation_plan", plan, text, "ablations.tsv", heading, [c for p in plan for c in commands_of(p)])
    return 0


if __name__ == "__main__":
    from keras_rl.errors import ConfigError

    try:
        raise SystemExit(main())
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
