"""The sensitive check tier, sized by a power computation before its runs (issue 35, item 2):
post 000 (the tier's requirement: 80% power against a 10% move of its median), and post 003
with the same computation on its compiled engine's committed seeds (``--post cartpole``).

The question: how many fresh seeds (``n``) and how large a baseline (``m``) must ``keras-rl
check`` compare so that a change moving post 000's median episodes to threshold by 10% (either
way) is flagged with probability at least 80%, while the three-post command's family-wise
false-alarm rate stays at or under 1%?

- The statistic and test are the check's own for post 000: episodes to threshold, two-sided
  censored Mann-Whitney (``report/stats.censored_mann_whitney``; a seed that never reaches the
  threshold counts as budget + 1). The three-post command splits its 1% over the posts
  (``results/checks/family.json``: alpha / 3 each), so post 000's test runs at 0.01 / 3.
- The seeds' distribution is the compiled engine's 100 committed post-000 seeds
  (``results/engines/pendulum/compiled``: the engine the tier runs on, since a tier that sees
  10% must compare seeds of one engine). A regression that moves the median by a factor ``s``
  is modelled as each fresh seed's episodes times ``s`` (0.90 and 1.10), rounded.
- Each cell of (n, m) draws ``REPS`` checks: a baseline of ``m`` and ``n`` fresh seeds, each
  resampled from the 100; the power is the share of checks whose p is under alpha, and the
  false-alarm rate the same with ``s = 1``.
- The cost: ``n`` fresh compiled seeds on two workers at the committed seeds' median wall time
  (which includes each seed's own compilation: a kept program makes seeds after a worker's
  first cheaper, so the estimate is an upper bound).

The plan picks the cheapest (n, m) whose power is at least 80% against both shifts, with the
smallest baseline of those. Its runs (the baseline grown to ``m`` compiled seeds) come after
this plan in ``git log``.

    python reproductions/sensitive_plan.py            # print post 000's plan
    python reproductions/sensitive_plan.py --write    # results/checks/sensitive_plan.{json,md}
    python reproductions/sensitive_plan.py --post cartpole --write
                                                      # results/checks/sensitive_plan_cartpole.{json,md}

Post 003 (``--post cartpole``): its statistic is the check's for it, episodes to a 100-episode
mean of 475 within 600 (censored at 601); its source ``results/engines/cartpole/compiled``. Its
seeds cost about six times post 000's, so its plan also names the largest fresh count whose
seeds fit the tier's 15 minutes beside post 000's and post 001's (``BUDGET_MINUTES`` less the
other posts' share, ``OTHERS_MINUTES``), and picks the cheapest cell with 80% power, or else
the largest fresh count within that budget against the smallest baseline whose power is within
``SAME_POWER`` of that count's best.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/

import numpy as np

from keras_rl.atomic import atomic_write_json, atomic_write_text
from keras_rl.report.stats import censored_mann_whitney
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT

SOURCES = {post: ROOT / "results" / "engines" / post / "compiled" for post in ("pendulum", "cartpole")}
SOURCE = SOURCES["pendulum"]
OUT = ROOT / "results" / "checks"
FRESH = (10, 20, 30, 40, 50, 60, 80)
BASELINES = (100, 200, 300, 500)
BUDGET_MINUTES = 15.0
"""The tier's whole three-post command, at most (the issue's bound)."""
OTHERS_MINUTES = 6.0
"""Post 000's fresh seeds (1.4 minutes by its plan) and post 001's (at most 40 Gymnasium-loop
seeds of about 15 s, 5 minutes on two workers), rounded up with start-up: what post 003's
fresh seeds leave to the others."""
SHIFTS = (0.90, 1.10)
ALPHA = 0.01 / 3
POWER = 0.80
REPS = 1000
WORKERS = 2
SAME_POWER = 0.05
"""Power differences this small between baseline sizes are not worth growing a baseline for."""
POST_NAMES = {"pendulum": "post 000", "cartpole": "post 003"}


def source(folder: Path = SOURCE) -> tuple[np.ndarray, int, float]:
    """Each committed seed's episodes to threshold (budget + 1 where never), the budget, and
    the median wall seconds of a seed."""
    summaries = RunSet(folder).summaries()
    budget = summaries[0].budget_episodes
    episodes = np.array([s.reached_at_episode if s.success else budget + 1 for s in summaries], float)
    return episodes, budget, float(np.median([s.wall_seconds for s in summaries]))


def power(episodes: np.ndarray, budget: int, n: int, m: int, shift: float, rng: np.random.Generator) -> float:
    hits = 0
    for _ in range(REPS):
        base = rng.choice(episodes, m)
        fresh = np.minimum(np.round(rng.choice(episodes, n) * shift), budget + 1)
        a = [None if v > budget else int(v) for v in fresh]
        b = [None if v > budget else int(v) for v in base]
        hits += censored_mann_whitney(a, b, budget)[1] < ALPHA
    return hits / REPS


def worst(cell: dict) -> float:
    """A cell's power against the harder of the two shifts."""
    return min(cell[f"power_x{s:.2f}"] for s in SHIFTS)


def out_name(post: str) -> str:
    return "sensitive_plan" if post == "pendulum" else f"sensitive_plan_{post}"


def plan(post: str = "pendulum") -> dict:
    episodes, budget, seed_seconds = source(SOURCES[post])
    rng = np.random.default_rng(35)
    cells = []
    for m in BASELINES:
        for n in FRESH:
            row = {"fresh": n, "baseline": m, "false_alarm": power(episodes, budget, n, m, 1.0, rng)}
            for s in SHIFTS:
                row[f"power_x{s:.2f}"] = power(episodes, budget, n, m, s, rng)
            row["fresh_minutes"] = round(n * seed_seconds / WORKERS / 60, 2)
            cells.append(row)
    ok = [c for c in cells if min(c[f"power_x{s:.2f}"] for s in SHIFTS) >= POWER]
    chosen = min(ok, key=lambda c: (c["fresh"], c["baseline"])) if ok else None
    limit = BUDGET_MINUTES - OTHERS_MINUTES if post != "pendulum" else BUDGET_MINUTES
    affordable = [c for c in cells if c["fresh_minutes"] <= limit]
    if post != "pendulum" and (chosen is None or chosen["fresh_minutes"] > limit) and affordable:
        # no affordable cell reaches 80%: the largest affordable fresh count, against the smallest
        # baseline within SAME_POWER of that count's best (a bigger one buys only resampling noise)
        most = max(c["fresh"] for c in affordable)
        row = [c for c in affordable if c["fresh"] == most]
        best = max(worst(c) for c in row)
        chosen = min((c for c in row if worst(c) >= best - SAME_POWER), key=lambda c: c["baseline"])
    return {
        "post": post,
        "minutes_limit": limit,
        "source": str(SOURCES[post].relative_to(ROOT)),
        "seeds": len(episodes),
        "median_episodes": float(np.median(episodes)),
        "iqr": [float(q) for q in np.percentile(episodes, [25, 75])],
        "seed_seconds": seed_seconds,
        "alpha": ALPHA,
        "reps": REPS,
        "shifts": list(SHIFTS),
        "cells": cells,
        "chosen": chosen,
    }


def markdown(p: dict) -> str:
    post_flag = "" if p.get("post", "pendulum") == "pendulum" else f" --post {p['post']}"
    lines = [
        f"# The sensitive check tier for {POST_NAMES[p.get('post', 'pendulum')]}: sized before its runs",
        "",
        f"Generated by `python reproductions/sensitive_plan.py{post_flag} --write` (its docstring says how); written",
        "before the baseline it sizes was grown.",
        "",
        f"Source: `{p['source']}`, {p['seeds']} seeds, median episodes to threshold {p['median_episodes']:g} "
        f"(IQR {p['iqr'][0]:g}-{p['iqr'][1]:g}), a seed's median wall time {p['seed_seconds']:.1f} s. "
        f"Two-sided censored Mann-Whitney at alpha {p['alpha']:.4f} (the family's 1% over 3 posts); "
        f"{p['reps']} simulated checks per cell.",
        "",
        "| fresh seeds | baseline seeds | false alarms | power, median x0.90 | power, median x1.10 "
        "| fresh seeds' minutes on 2 workers |",
        "|---|---|---|---|---|---|",
    ]
    for c in p["cells"]:
        lines.append(
            f"| {c['fresh']} | {c['baseline']} | {c['false_alarm']:.4f} | {c['power_x0.90']:.2f} | "
            f"{c['power_x1.10']:.2f} | {c['fresh_minutes']:.1f} |"
        )
    c = p["chosen"]
    reaches = c is not None and min(c["power_x0.90"], c["power_x1.10"]) >= POWER
    if c is not None and not reaches:
        lines += [
            "",
            f"**No cell within {p['minutes_limit']:g} minutes of fresh seeds reaches 80% against both shifts.** "
            f"Chosen, the most fresh seeds within it, against the smallest baseline within {SAME_POWER} of "
            f"their best power: {c['fresh']} fresh seeds against a baseline of "
            f"{c['baseline']}: power {c['power_x0.90']:.2f} and {c['power_x1.10']:.2f}, false alarms "
            f"{c['false_alarm']:.4f}, about {c['fresh_minutes']:.1f} minutes of fresh seeds on two workers.",
            "",
        ]
        return "\n".join(lines)
    lines += [
        "",
        (
            f"**Chosen:** {c['fresh']} fresh seeds against a baseline of {c['baseline']}: power "
            f"{c['power_x0.90']:.2f} and {c['power_x1.10']:.2f}, false alarms {c['false_alarm']:.4f}, "
            f"about {c['fresh_minutes']:.1f} minutes of fresh seeds on two workers."
            if c
            else "**No cell reaches 80% against both shifts**: a larger baseline or more fresh seeds are needed."
        ),
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", action="store_true", help="write results/checks/sensitive_plan[_POST].{json,md}")
    parser.add_argument(
        "--post", choices=sorted(SOURCES), default="pendulum", help="the post to size (default pendulum)"
    )
    args = parser.parse_args()
    p = plan(args.post)
    if args.write:
        name = out_name(args.post)
        atomic_write_json(OUT / f"{name}.json", p)
        atomic_write_text(OUT / f"{name}.md", markdown(p))
        print(f"wrote {Path(OUT / f'{name}.md').relative_to(ROOT)} and its JSON")
    else:
        print(markdown(p))


if __name__ == "__main__":
    main()
