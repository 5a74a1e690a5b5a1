"""The sequential check against the fixed-n rule, on the same simulated checks.

    python -m maintainers calibrate designs            # print the table
    python -m maintainers calibrate designs --write  # results/checks/sequential.md, keras_rl/check/sequential.json

For each post and tier: the design of ``keras_rl/check/sequential.py`` (looks at 5, 10, ...,
30 fresh seeds; futility above a bound from the second look), its efficacy level calibrated
on the committed baseline alone so that an unchanged learner is called changed at
most 1% / 3 of the time (so the three-post command stays under 1%, Bonferroni), then run on
the same draws as the fixed-n rule (its n fresh seeds, one look):

- under no change: pooled draws from the baseline's values (``NULL_REPEATS``);
- under each mutant of ``check/rules.MUTANTS``: fresh seeds drawn with replacement from its
  committed runs (``MUTANT_REPEATS``), against the whole baseline.

The fixed-n rule is shown at the rule's alpha (how each post's test runs; Holm over the
posts then) and at alpha / 3 (the same family-wise guarantee as the sequential design).
The efficacy level is calibrated on the baseline alone. Once every mutant of a post has 30
runs, the futility bound is chosen on their seeds 0-14 (``choose_futility``, among
``FUTILITY_CANDIDATES``, by a criterion written down before those runs were made), and the
mutant rows report the chosen design on seeds 15-29, which that choice never saw. Before then
the bound is the fixed 0.5 and a mutant's power is the power against its 10 runs'
distribution, resampled, a caveat the page states.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.check.command import SEQUENTIAL, baseline_values
from keras_rl.check.rules import CALIBRATED_TIERS, MUTANTS, RULES
from keras_rl.check.sequential import (
    DESIGN,
    calibrate,
    choose_futility,
    fixed_rule,
    mutant_pvalues,
    null_pvalues,
    simulate,
)
from keras_rl.registry import get_experiment
from maintainers.calibrate.runs import REPORT, TUNE, halved, load, values
from maintainers.checkout import ROOT

CHECKS = ROOT / "results" / "checks"
POSTS = ("pendulum", "cartpole", "mountaincar")
FAMILY_ALPHA = 0.01
NULL_REPEATS, MUTANT_REPEATS = 4000, 1000
COMMAND = "python -m maintainers calibrate designs --write"


def study(post: str, tier: str) -> dict:
    rule = RULES[(post, tier)]
    experiment = get_experiment(post)
    base_values, _ = baseline_values(experiment, rule, CHECKS / post / "baseline")
    baseline = np.asarray(list(base_values.values()), float)
    stages = sorted(set(DESIGN.stages) | {rule.seeds})
    columns = [stages.index(n) for n in DESIGN.stages]
    rng = np.random.default_rng(0)
    alpha = FAMILY_ALPHA / len(POSTS)
    null = null_pvalues(baseline, rule.statistic, stages, NULL_REPEATS, rng)
    folders = {m.name: CHECKS / post / "mutants" / m.name for m in MUTANTS[post]}
    folders = {k: f for k, f in folders.items() if f.is_dir()}
    halves = bool(folders) and halved(list(folders.values()))
    choice = None
    if halves:  # the futility bound chosen on seeds 0-14 of every mutant; power reported on 15-29
        tune = [
            mutant_pvalues(baseline, values(post, rule.statistic, rule.episodes, load(f, TUNE)), rule.statistic,
                           stages, MUTANT_REPEATS, rng)
            for f in folders.values()
        ]  # fmt: skip
        fixed = float(np.mean([fixed_rule(pm, stages, rule.seeds, alpha).changed for pm in tune]))
        design, table = choose_futility(null[:, columns], [pm[:, columns] for pm in tune], fixed, alpha, DESIGN)
        choice = {"chosen_on": f"seeds {TUNE.start}-{TUNE.stop - 1}", "fixed_power": fixed, "candidates": table}
    else:
        design = calibrate(DESIGN, null[:, columns], alpha)

    def row(name: str, pmatrix: np.ndarray, gross: bool | None) -> dict:
        seq = simulate(design, pmatrix[:, columns])
        return {
            "scenario": name,
            "gross": gross,
            "sequential_changed": seq.changed,
            "sequential_seeds": seq.seeds_mean,
            "fixed_changed_at_rule_alpha": fixed_rule(pmatrix, stages, rule.seeds, rule.alpha).changed,
            "fixed_changed_at_family_alpha": fixed_rule(pmatrix, stages, rule.seeds, alpha).changed,
            "repeats": len(pmatrix),
        }

    rows = [row("no change", null, None)]
    for mutant in MUTANTS[post]:
        if mutant.name not in folders:
            continue
        changed = values(post, rule.statistic, rule.episodes, load(folders[mutant.name], REPORT if halves else None))
        pm = mutant_pvalues(baseline, changed, rule.statistic, stages, MUTANT_REPEATS, rng)
        rows.append({**row(mutant.name, pm, mutant.gross), "mutant_runs": len(changed)})
    mutants = [r for r in rows if r["gross"] is not None]
    summary = {
        "mean_power_sequential": float(np.mean([r["sequential_changed"] for r in mutants])),
        "mean_power_fixed_family_alpha": float(np.mean([r["fixed_changed_at_family_alpha"] for r in mutants])),
        "mean_power_fixed_rule_alpha": float(np.mean([r["fixed_changed_at_rule_alpha"] for r in mutants])),
        "mean_seeds_sequential_mutants": float(np.mean([r["sequential_seeds"] for r in mutants])),
        "seeds_sequential_no_change": rows[0]["sequential_seeds"],
        "fixed_seeds": rule.seeds,
    }
    return {
        "post": post,
        "tier": tier,
        "baseline_seeds": len(baseline),
        "statistic": rule.statistic,
        "rule_alpha": rule.alpha,
        "family_alpha_per_post": alpha,
        "design": {"stages": list(design.stages), "efficacy": design.efficacy, "futility": design.futility},
        "rows": rows,
        "summary": summary,
        "futility_choice": choice,
        "reported_on": f"seeds {REPORT.start}-{REPORT.stop - 1}" if halves else "every run",
    }


def render(results: list[dict]) -> str:
    pct = lambda v: f"{100 * v:.1f}%"  # noqa: E731
    runs = sorted({row["mutant_runs"] for r in results for row in r["rows"] if "mutant_runs" in row})
    baselines = {r["post"]: r["baseline_seeds"] for r in results}
    lines = [
        "# The sequential check against the fixed-n rule",
        "",
        f"Generated by `{COMMAND}` (see its docstring for the method). The efficacy level is "
        f"calibrated per post on the baseline alone, for at most {FAMILY_ALPHA:.0%} / {len(POSTS)} per post; "
        "futility stops (p above the design's bound, from the second look) only end checks as consistent. "
        f"{NULL_REPEATS} simulated checks under no change, {MUTANT_REPEATS} per mutant (each drawn from its "
        f"{' or '.join(map(str, runs))} committed runs"
        + (
            ", its held-back seeds, which no choice looked at)."
            if all(r.get("futility_choice") for r in results)
            else ": a caveat, see the docstring)."
        )
        + f" Baselines: {', '.join(f'{p} {n} seeds' for p, n in baselines.items())}.",
        "",
    ]
    for r in results:
        s, d = r["summary"], r["design"]
        lines += [
            f"## {r['post']}, {r['tier']} tier ({r['statistic']})",
            "",
            f"Looks at {', '.join(map(str, d['stages']))} fresh seeds; changed below p = {d['efficacy']:.2g}; "
            f"consistent above p = {d['futility']:g}. The fixed-n rule: {s['fixed_seeds']} seeds, one look.",
            "",
            "| scenario | sequential: changed | sequential: seeds (mean) | fixed-n at the rule's alpha "
            f"({r['rule_alpha']:g}) | fixed-n at alpha / 3 ({r['family_alpha_per_post']:.3g}) |",
            "|---|---|---|---|---|",
        ]
        choice = r.get("futility_choice")
        if choice:
            lines[-4:-4] = [
                f"The futility bound was chosen on the mutants' {choice['chosen_on']} (criterion: "
                "`choose_futility` in `keras_rl/check/sequential.py`): the fewest seeds, averaged over no change "
                "and the mutants, among bounds with the fixed-n rule's power at alpha / 3 "
                f"({pct(choice['fixed_power'])} on those seeds); the mutant rows below are on the held-back "
                f"{r['reported_on']}.",
                "",
                "| futility | efficacy | false alarms | power (tuning seeds) | seeds: no change | seeds: mutants |",
                "|---|---|---|---|---|---|",
                *[
                    f"| {c['futility']:g} | {c['efficacy']:.2g} | {pct(c['false_alarm_rate'])} | {pct(c['power'])} "
                    f"| {c['seeds_no_change']:.1f} | {c['seeds_mutants']:.1f} |"
                    for c in choice["candidates"]
                ],
                "",
            ]
        for row in r["rows"]:
            name = row["scenario"] + (" (gross)" if row["gross"] else "")
            lines.append(
                f"| {name} | {pct(row['sequential_changed'])} | {row['sequential_seeds']:.1f} | "
                f"{pct(row['fixed_changed_at_rule_alpha'])} | {pct(row['fixed_changed_at_family_alpha'])} |"
            )
        ratio = s["mean_seeds_sequential_mutants"] / s["fixed_seeds"]
        lines += [
            "",
            f"Mean power over the mutants: sequential {pct(s['mean_power_sequential'])} with "
            f"{s['mean_seeds_sequential_mutants']:.1f} seeds on average ({ratio:.0%} of the fixed rule's "
            f"{s['fixed_seeds']}); fixed-n {pct(s['mean_power_fixed_family_alpha'])} at alpha / 3, "
            f"{pct(s['mean_power_fixed_rule_alpha'])} at the rule's alpha. Under no change the sequential "
            f"check uses {s['seeds_sequential_no_change']:.1f} seeds on average.",
            "",
        ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    results = [study(post, tier) for tier in CALIBRATED_TIERS for post in POSTS]
    text = render(results)
    if not args.write:
        print(text)
        return 0
    atomic_write_text(SEQUENTIAL, json.dumps({"command": COMMAND, "results": results}, indent=2) + "\n")
    atomic_write_text(CHECKS / "sequential.md", text + "\n")
    print(f"wrote {CHECKS / 'sequential.md'} and {SEQUENTIAL}")
    return 0
