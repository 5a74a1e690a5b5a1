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
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy import stats

from keras_rl.checkout import ROOT
from keras_rl.report.equivalence import MEDIAN_RATIO_MARGIN, SUCCESS_RATE_MARGIN
from keras_rl.report.stats import success_difference_ci

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
        hits = [int(e) for e in arm["episodes_to_threshold"]]
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write results/compare/seed_plan.{json,md}")
    args = parser.parse_args(argv)
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
