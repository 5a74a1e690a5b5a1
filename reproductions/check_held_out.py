"""Power of ``keras-rl check``'s rules against the held-out mutants (issue #21): changes written
down before any was run (``keras_rl/check/rules.py``, ``HELD_OUT``) and never used to choose a
rule, an alpha or a boundary, so their power is the honest estimate of what the check finds in
a change nobody tuned it for.

    python reproductions/check_held_out.py --make     # print the commands for the missing runs
    python reproductions/check_held_out.py            # print the table
    python reproductions/check_held_out.py --write    # results/checks/held_out.json and its block in calibration.md

Each held-out mutant has 30 seeds (``results/checks/<post>/held-out/<name>``), run as the
tuning mutants were (``--seed-batch auto``, the longest tier's episodes). For each tier's
rule, as the check runs it (n fresh seeds against the whole committed baseline):

- **power**, n seeds drawn with replacement from the mutant's 30, 2,000 times; at the rule's
  alpha (a one-post command) and at alpha / 3 (Holm's first level: what a change to one post
  must clear in the default three-post command);
- **disjoint checks**: the 30 seeds cut into floor(30 / n) groups of n, each a real check that
  could have been run; the count flagged, with its exact (Clopper-Pearson) 95% interval. Few
  checks make this interval wide: it says how little 30 runs of a mutant can prove on their own;
- **a seed bootstrap** of the power: the 30 seeds resampled 200 times, power recomputed (500
  draws each), the 2.5th-97.5th percentiles: the uncertainty that comes from having 30 runs;
- **the effect**: the statistic's median over the mutant's seeds against the baseline's.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "reproductions"))
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from keras_rl.check.rules import HELD_OUT, RULES, TIERS  # noqa: E402
from keras_rl.check.statistics import decide, power  # noqa: E402

CHECKS = ROOT / "results" / "checks"
SEEDS = "0-29"
POSTS = ("pendulum", "cartpole", "mountaincar")
BEGIN, END = "<!-- held-out:begin -->", "<!-- held-out:end -->"
HOLM_LEVEL = 3
"""Posts in the default command: a change to one post must clear alpha / 3 (Holm's first level)."""


def folder(post: str, name: str) -> Path:
    return CHECKS / post / "held-out" / name


def make_commands() -> list[list[str]]:
    """The commands that make the missing held-out runs, as the tuning mutants were made."""
    out = []
    for post in POSTS:
        episodes = max(RULES[(post, t)].episodes for t in TIERS)
        for m in HELD_OUT[post]:
            if folder(post, m.name).is_dir():
                continue
            sets = [a for k, v in m.overrides.items() for a in ("--set", f"{k}={v}")]
            out.append(
                ["keras-rl", "reproduce", post, "--seeds", SEEDS, "--episodes", str(episodes), *sets,
                 "--no-progress", "--min-success-rate", "0", "--workers", "2", "--seed-batch", "auto",
                 "--out", str(folder(post, m.name).relative_to(ROOT))]
            )  # fmt: skip
    return out


def clopper_pearson(k: int, n: int) -> tuple[float, float]:
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return float(ci.low), float(ci.high)


def measure(post: str, tier: str, baseline: np.ndarray, runs: np.ndarray) -> dict:
    """One held-out mutant under one tier's rule (``baseline`` and ``runs``: each seed's statistic)."""
    rule = RULES[(post, tier)]
    levels = {"alpha": rule.alpha, "holm_first": rule.alpha / HOLM_LEVEL}
    out: dict = {"seeds": len(runs), "n": rule.seeds, "statistic": rule.statistic}
    for key, alpha in levels.items():
        out[f"power_{key}"] = power(baseline, runs, rule.seeds, rule.statistic, alpha, rng=np.random.default_rng(11))
    groups = len(runs) // rule.seeds
    flagged = sum(
        decide(baseline, runs[g * rule.seeds : (g + 1) * rule.seeds], rule.statistic, rule.alpha).changed
        for g in range(groups)
    )
    out["disjoint"] = (
        {"checks": groups, "flagged": int(flagged), "ci95": clopper_pearson(int(flagged), groups)} if groups else None
    )
    rng = np.random.default_rng(12)
    boot = [
        power(baseline, runs[rng.integers(0, len(runs), len(runs))], rule.seeds, rule.statistic, rule.alpha, 500, rng)
        for _ in range(200)
    ]
    out["bootstrap95"] = (float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5)))
    finite = np.isfinite
    out["median_mutant"] = float(np.median(runs[finite(runs)])) if finite(runs).any() else None
    out["median_baseline"] = float(np.median(baseline[finite(baseline)]))
    return out


def compute() -> dict:
    from check_calibrate import load, values

    results: dict = {}
    for post in POSTS:
        present = [m for m in HELD_OUT[post] if folder(post, m.name).is_dir()]
        if not present:
            continue
        baseline_runs = load(CHECKS / post / "baseline")
        entry: dict = {"baseline_seeds": len(baseline_runs), "mutants": {}}
        for m in present:
            runs = load(folder(post, m.name))
            entry["mutants"][m.name] = {"what": m.what, "tiers": {}}
            for tier in TIERS:
                rule = RULES[(post, tier)]
                base = values(post, rule.statistic, rule.episodes, baseline_runs)
                mut = values(post, rule.statistic, rule.episodes, runs)
                entry["mutants"][m.name]["tiers"][tier] = measure(post, tier, base, mut)
        results[post] = entry
    return results


def render(results: dict) -> str:
    if not results:
        return "No held-out mutant has runs yet: `python reproductions/check_held_out.py --make` prints their commands."
    lines = [
        "Power against the held-out mutants, never used to choose a rule (`HELD_OUT` in",
        "`keras_rl/check/rules.py`), 30 seeds each. Generated by `python reproductions/check_held_out.py",
        "--write`. Power: n seeds drawn from the mutant's 30, at the rule's alpha (a one-post command) and at",
        "alpha / 3 (a change to one post in the default three-post command, Holm's first level); its seed",
        "bootstrap 95% interval; and the 30 seeds as floor(30 / n) disjoint real checks with their exact",
        "(Clopper-Pearson) 95% interval.",
        "",
        "| post | mutant | tier | statistic (n) | median: mutant / baseline | power at alpha [seed bootstrap 95%] "
        "| at alpha / 3 | disjoint checks flagged [Clopper-Pearson 95%] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for post, entry in results.items():
        for name, m in entry["mutants"].items():
            for tier, r in m["tiers"].items():
                med = "-" if r["median_mutant"] is None else f"{r['median_mutant']:.4g}"
                d = r["disjoint"]
                disjoint = f"{d['flagged']}/{d['checks']} [{d['ci95'][0]:.0%}, {d['ci95'][1]:.0%}]" if d else "none"
                lines.append(
                    f"| {post} | {name} ({m['what']}) | {tier} | {r['statistic']} ({r['n']}) | "
                    f"{med} / {r['median_baseline']:.4g} | {r['power_alpha']:.0%} "
                    f"[{r['bootstrap95'][0]:.0%}, {r['bootstrap95'][1]:.0%}] | {r['power_holm_first']:.0%} | "
                    f"{disjoint} |"
                )
    seen, unseen = [], []
    for post, entry in results.items():
        for name, m in entry["mutants"].items():
            best = max(r["power_alpha"] for r in m["tiers"].values())
            r = m["tiers"]["smoke"]
            shift = (
                ""
                if r["median_mutant"] is None
                else f" ({r['statistic']} median {r['median_mutant']:.4g} against {r['median_baseline']:.4g})"
            )
            if best >= 0.8:
                seen.append(f"{post} {name}{shift}")
            elif best < 0.2:
                unseen.append(f"{post} {name}{shift}")
    lines += [
        "",
        "What the check sees: flagged at least 80% of the time by a tier: "
        + ("; ".join(seen) if seen else "none")
        + ". What it cannot see: under 20% at both tiers, near its false-alarm rate, either because the "
        "change barely moves the statistic or because the baseline's seeds spread wider than it moves: "
        + ("; ".join(unseen) if unseen else "none")
        + ".",
    ]
    missing = [f"{p}: {m.name}" for p in POSTS for m in HELD_OUT[p] if not folder(p, m.name).is_dir()]
    if missing:
        lines += ["", "Held-out mutants without runs yet: " + "; ".join(missing) + "."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--make", action="store_true", help="print the commands for the missing held-out runs")
    parser.add_argument("--write", action="store_true", help="write results/checks/held_out.json and its block")
    args = parser.parse_args()
    if args.make:
        for command in make_commands():
            print(" ".join(command))
        return
    results = compute()
    text = render(results)
    if not args.write:
        print(text)
        return
    from check_family import write_with_block

    write_with_block(CHECKS / "held_out.json", results, BEGIN, END, text, "## Held-out mutants")


if __name__ == "__main__":
    main()
