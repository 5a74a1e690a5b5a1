"""How many seeds each Keras-against-PyTorch comparison needs, written down before the runs.

The rule (set 2026-11-24, before any seed past 29 of a comparison's PyTorch arm ran): take the
success rates and the episodes-to-threshold observed at 30 seeds per arm
(``results/compare/<post>/[matched-init/]result.json``), assume the true difference is zero
(both arms draw from the two arms' pooled 60 seeds), and find the smallest seeds-per-arm ``n``
at which the comparison's 90% interval fits its pre-registered margin with probability at
least 80%:

- success rate: Newcombe's interval of the difference (``report/stats.success_difference_ci``,
  as ``compare`` computes it) inside ±0.15, with each arm Binomial(n, pooled rate);
- median episodes to threshold: the percentile-bootstrap interval of the ratio of medians
  (seeds that never reached the threshold count as budget + 1, as ``compare`` counts them)
  inside 0.90-1.10, each arm resampled from the pooled 60 values. The plan uses 1,000
  bootstrap resamples per interval where the report uses 10,000 (the planning error this adds
  is well under the Monte Carlo error of the 80%).

A comparison needs the larger of its two quantities' ``n``, and never fewer than 100 seeds
per arm. Where no candidate up to the largest reaches 80%, the plan says so: more seeds would
not be expected to end that comparison "equivalent", and it runs to 100 for a sharper estimate.

    python reproductions/seed_plan.py            # print the plan
    python reproductions/seed_plan.py --write    # results/compare/seed_plan.{json,md}

The same computation for two arms already run past the plan (``--arms``: each arm one run-set
folder, or several joined by commas), pooled the same way, at the seeds per arm of
``--candidates``: how far off an inconclusive reading's margin is.

    python reproductions/seed_plan.py --arms \
        results/checks/mountaincar/baseline,results/mountaincar/faithful-seeds-100-199 \
        results/engines/mountaincar/compiled --candidates 200,400,800,1600 \
        --out results/engines/mountaincar/seeds_needed.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/

import numpy as np
from scipy import stats

from keras_rl.report.equivalence import MEDIAN_RATIO_MARGIN, SUCCESS_RATE_MARGIN, Arm
from keras_rl.report.stats import success_difference_ci
from maintainers.checkout import ROOT

CANDIDATES = (30, 60, 100, 150, 200, 300, 400, 600)
PROBABILITY = 0.80
MINIMUM = 100
REPS = 400
RESAMPLES = 1_000
POSTS = ("pendulum", "cartpole", "mountaincar")
OUT = ROOT / "results" / "compare"


def observed(post: str, matched: bool) -> dict:
    folder = OUT / post / ("matched-init" if matched else "")
    result = json.loads((folder / "result.json").read_text())
    budget = int(result["budget"])
    arms = {}
    for framework, arm in result["frameworks"].items():
        n = len(arm["seeds"])
        # the plan was drawn (2026-11-24) from the list the report kept then: the code's reading before
        # issue 52, which result.json keeps beside the plans' reading where the two differ (post 001)
        hits = [int(e) for e in arm.get("before_issue_52", arm)["episodes_to_threshold"]]
        arms[framework] = {
            "seeds": n,
            "successes": int(arm["successes"]),
            "episodes": hits + [budget + 1] * (n - len(hits)),
        }
    return {"budget": budget, "arms": arms}


def p_success_fits(rate: float, n: int, rng: np.random.Generator) -> float:
    a, b = rng.binomial(n, rate, REPS), rng.binomial(n, rate, REPS)
    fits = 0
    for ka, kb in zip(a, b):
        ci = success_difference_ci(int(ka), n, int(kb), n, confidence=0.90)
        fits += -SUCCESS_RATE_MARGIN < ci.low and ci.high < SUCCESS_RATE_MARGIN
    return fits / REPS


def p_ratio_fits(pool: np.ndarray, budget: int, n: int, rng: np.random.Generator) -> float:
    def ratio(x, y, axis=-1):
        return np.median(x, axis=axis) / np.median(y, axis=axis)

    fits = 0
    for _ in range(REPS):
        x, y = rng.choice(pool, n), rng.choice(pool, n)
        if np.median(x) > budget or np.median(y) > budget:
            continue  # no median to compare: not equivalent
        if np.ptp(x) == 0 and np.ptp(y) == 0:
            low = high = ratio(x, y)
        else:
            ci = stats.bootstrap(
                (x, y), ratio, n_resamples=RESAMPLES, confidence_level=0.90, method="percentile", random_state=rng
            ).confidence_interval
            low, high = ci.low, ci.high
        fits += 1 - MEDIAN_RATIO_MARGIN < low and high < 1 + MEDIAN_RATIO_MARGIN
    return fits / REPS


def plan_one(post: str, matched: bool, seed: int) -> dict:
    data = observed(post, matched)
    arms = data["arms"]
    successes = sum(a["successes"] for a in arms.values())
    seeds = sum(a["seeds"] for a in arms.values())
    rate = successes / seeds
    pool = np.array([e for a in arms.values() for e in a["episodes"]], float)
    rng = np.random.default_rng(seed)
    rows, needed = [], {}
    for n in CANDIDATES:
        row = {"n": n, "success": p_success_fits(rate, n, rng), "ratio": p_ratio_fits(pool, data["budget"], n, rng)}
        rows.append(row)
        for q in ("success", "ratio"):
            if q not in needed and row[q] >= PROBABILITY:
                needed[q] = n
        if len(needed) == 2:
            break
    reached = len(needed) == 2
    n_plan = max([MINIMUM, *needed.values()]) if reached else MINIMUM
    return {
        "post": post,
        "init": "matched" if matched else "default",
        "pooled_success_rate": rate,
        "observed": {fw: {"successes": a["successes"], "seeds": a["seeds"]} for fw, a in arms.items()},
        "probabilities": rows,
        "needed": needed,
        "reached_80": reached,
        "seeds_per_arm": n_plan,
    }


def render(plan: list[dict]) -> str:
    lines = [
        "# Seeds per arm for each Keras-against-PyTorch comparison (planned 2026-11-24, before the runs)",
        "",
        "Generated by `python reproductions/seed_plan.py --write`; the rule is in its docstring. The margins",
        f"are the ones set on 2026-11-23: ±{SUCCESS_RATE_MARGIN} success, ±{MEDIAN_RATIO_MARGIN:.0%} median episodes.",
        "Each cell is the probability that the 90% interval fits the margin if the true difference is zero",
        f"({REPS} simulated comparisons per cell, from the 30-seed arms pooled).",
        "",
        "| post | init | observed (keras / torch) | n per arm: P(success fits), P(ratio fits) "
        "| planned seeds per arm |",
        "|---|---|---|---|---|",
    ]
    for p in plan:
        obs = " / ".join(f"{v['successes']}/{v['seeds']}" for v in p["observed"].values())
        cells = "; ".join(f"{r['n']}: {r['success']:.2f}, {r['ratio']:.2f}" for r in p["probabilities"])
        said = str(p["seeds_per_arm"]) + ("" if p["reached_80"] else f" (80% not reached by {CANDIDATES[-1]})")
        lines.append(f"| {p['post']} | {p['init']} | {obs} | {cells} | {said} |")
    return "\n".join(lines) + "\n"


def run_set_arm(folders: str) -> tuple[int, int, list[float], int]:
    """(successes, seeds, episodes to threshold with never as budget + 1, budget) of an arm made
    of one or more run-set folders (the first folder holding a seed is read)."""
    from maintainers.certified import arm

    paths = [Path(f).resolve() for f in folders.split(",")]
    missing = [str(p) for p in paths if not p.is_dir()]
    if missing:
        raise SystemExit(f"error: {', '.join(missing)} is not a folder of run folders")
    records = arm(tuple(str(p) for p in paths), Path("/")).values()
    budgets = {int(r["budget_episodes"]) for r in records}
    if len(budgets) != 1:
        raise SystemExit(f"error: {folders}'s seeds ran different budgets ({sorted(budgets)})")
    budget = budgets.pop()
    seeds = Arm.of(records)
    episodes = [budget + 1.0 if e is None else float(e) for e in seeds.episodes()]
    return seeds.successes, len(episodes), episodes, budget


def arms_table(first: str, second: str, candidates: list[int], command: str) -> str:
    a, b = run_set_arm(first), run_set_arm(second)
    if a[3] != b[3]:
        raise SystemExit(f"error: the arms ran different budgets ({a[3]} and {b[3]} episodes)")
    pool = np.array(a[2] + b[2], float)
    rate = (a[0] + b[0]) / (a[1] + b[1])
    rng = np.random.default_rng(0)
    lines = [
        f"Generated by `{command}` (the rule of `reproductions/seed_plan.py`, from these arms pooled: "
        f"{a[0]}/{a[1]} and {b[0]}/{b[1]} successes; {REPS} simulated comparisons per cell).",
        "",
        "| seeds per arm | P(success interval fits ±0.15) | P(median-ratio interval fits 0.9-1.1) |",
        "|---|---|---|",
    ]
    for n in candidates:
        lines.append(f"| {n} | {p_success_fits(rate, n, rng):.2f} | {p_ratio_fits(pool, a[3], n, rng):.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write results/compare/seed_plan.{json,md}")
    parser.add_argument("--arms", nargs=2, metavar="FOLDERS", help="two arms already run (comma-joined folders)")
    parser.add_argument("--candidates", default="200,400,800", help="--arms: seeds per arm to try")
    parser.add_argument("--out", default=None, help="--arms: also write the table here")
    args = parser.parse_args(argv)
    if args.arms:
        try:
            candidates = [int(n) for n in args.candidates.split(",")]
        except ValueError:
            parser.error(f"--candidates takes seed counts joined by commas, got {args.candidates!r}")
        command = f"python reproductions/seed_plan.py --arms {' '.join(args.arms)} --candidates {args.candidates}" + (
            f" --out {args.out}" if args.out else ""
        )
        text = arms_table(*args.arms, candidates, command)
        print(text)
        if args.out:
            from keras_rl.atomic import atomic_write_text

            atomic_write_text(Path(args.out), text)
        return 0
    plan = [
        plan_one(post, matched, i) for i, (post, matched) in enumerate((p, m) for p in POSTS for m in (False, True))
    ]
    text = render(plan)
    print(text)
    if args.write:
        (OUT / "seed_plan.json").write_text(json.dumps(plan, indent=2) + "\n")
        (OUT / "seed_plan.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
