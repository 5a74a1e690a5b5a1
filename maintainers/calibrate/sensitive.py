"""The sensitive tier's error rates, as ``keras-rl check --tier sensitive`` runs it (issue 35).

    python -m maintainers calibrate sensitive            # print the table
    python -m maintainers calibrate sensitive --write    # keras_rl/check/sensitive.json, its calibration.md block,
                                            # and docs/check.md's table of what each tier sees

The tier's sizes were computed before its runs (``reproductions/sensitive_plan.py``:
``results/checks/sensitive_plan.md`` for post 000, ``sensitive_plan_cartpole.md`` for post
003); this measures what the rules in ``rules.py`` then do against their committed baselines:

- **False alarms**: the rule's n fresh seeds against the whole baseline under no change, exact
  where the statistic has no ties and by pooled resamples where it has
  (``statistics.check_false_alarm_rate``), at alpha (a one-post command) and alpha / 3 (Holm's
  first level in the three-post command), and the command's rate with Holm, the posts' seeds
  being independent runs.
- **A 10% move** (posts whose statistic is episodes to threshold): n fresh seeds, their episodes
  times 0.90 or 1.10 (rounded; past the budget they never got there), tested against the whole
  baseline at alpha / 3. Where the post has a no-change pool of seeds no baseline holds (post 000,
  ``calibrate/real.py``), they are drawn from it without replacement (``real.held_back_power``, the
  figure ``calibrate real`` tables); otherwise from the baseline's own seeds with replacement,
  ``SHIFT_DRAWS`` times.
- **Post 001's statistic**: chosen among the rule's candidates by the rules' pre-registered
  criterion (``calibrate/runs.choose``) on the tuning mutants' seeds 0-14 (``MUTANTS``), at the
  tier's 40 fresh seeds; ``tests/test_sensitive_tier.py`` fails if the rule is not the one chosen.
- **Held-out mutants** (``HELD_OUT``, never used to choose): power at alpha and alpha / 3,
  a seed bootstrap, and the runs cut into disjoint real checks with their Clopper-Pearson
  interval (``calibrate/runs.measure``). Posts 000 and 003's are the compiled engine's, as
  their rules' fresh seeds are (``results/checks/<post>/held-out``: post 000's 200 seeds each,
  post 003's 30); post 001's the Gymnasium loop's 30, batched.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from keras_rl.check.rules import HELD_OUT, MUTANTS, UNPAIRED_SENSITIVE
from keras_rl.check.statistics import changed_many, check_false_alarm_rate, family_false_alarm_rate, power
from maintainers.calibrate import real
from maintainers.calibrate.runs import (
    CHECKS,
    HOLM_LEVEL,
    TUNE,
    choose,
    halved,
    load,
    measure,
    power_cells,
    shifted,
    splice_calibration,
    values,
)
from maintainers.checkout import ROOT

POSTS = ("pendulum", "cartpole", "mountaincar")
TIER = "sensitive"
SHIFTS = (0.90, 1.10)
SHIFT_DRAWS = 2000
REPEATS = 20_000
BEGIN, END = "<!-- sensitive:begin -->", "<!-- sensitive:end -->"
HEADING = "## The sensitive tier"
SEES_BEGIN, SEES_END = "<!-- check-sees:begin -->", "<!-- check-sees:end -->"
"""docs/check.md's table of what each tier sees of the held-out mutants."""


def shift_power(baseline: np.ndarray, n: int, budget: int, shift: float, alpha: float, rng) -> float:
    """How often n fresh seeds whose episodes to threshold are the baseline's times ``shift``
    are flagged against the whole baseline (``budget + 1``: never got there)."""
    fresh = np.stack([rng.choice(baseline, n) for _ in range(SHIFT_DRAWS)])
    moved = shifted(fresh, shift, budget)
    bases = np.broadcast_to(np.asarray(baseline, float), (SHIFT_DRAWS, len(baseline)))
    return int(changed_many(bases, moved, "episodes_to_threshold", alpha).sum()) / SHIFT_DRAWS


def post_entry(post: str) -> dict:
    rule = UNPAIRED_SENSITIVE[post]
    baseline_runs = load(CHECKS / post / rule.baseline)
    entry: dict = {
        "rule": {
            "statistic": rule.statistic,
            "alpha": rule.alpha,
            "seeds": rule.seeds,
            "episodes": rule.episodes,
            "engine": rule.engine,
            "baseline": f"results/checks/{post}/{rule.baseline}",
        },
        "baseline_seeds": len(baseline_runs),
    }
    if rule.candidates != (rule.statistic,):  # a choice was made among several
        folders = [CHECKS / post / "mutants" / m.name for m in MUTANTS[post]]
        seeds = TUNE if halved(folders) else None
        mutants = {m.name: (m, load(f, seeds)) for m, f in zip(MUTANTS[post], folders)}
        rows, chosen = choose(post, rule, baseline_runs, mutants)
        entry["selection"] = {
            "chosen_on": f"mutants' seeds {TUNE.start}-{TUNE.stop - 1}" if seeds else "every mutant seed",
            "candidates": rows,
            "chosen": chosen and {"statistic": chosen["statistic"], "alpha": chosen["alpha"]},
        }
    base = values(post, rule.statistic, rule.episodes, baseline_runs)
    rng = np.random.default_rng(35)
    rates: dict[str, Any] = {
        "false_alarm_rate": check_false_alarm_rate(base, rule.seeds, rule.statistic, rule.alpha, REPEATS, rng).rate,
        "false_alarm_holm_first": check_false_alarm_rate(
            base, rule.seeds, rule.statistic, rule.alpha / HOLM_LEVEL, REPEATS, rng
        ).rate,
    }
    if rule.statistic == "episodes_to_threshold":
        pool = real.pool_values(post)
        if pool is not None:  # held-back seeds no baseline holds (issue 52 item 4): the figure real.py tables
            row = real.held_back_power(base, pool, rule.episodes, rule.alpha / HOLM_LEVEL, rule.seeds)
            rates["shift_power"] = {f"x{s:.2f}": row[f"x{s:.2f}"] for s in SHIFTS}
            entry["shift_power_from"] = f"{len(pool)} held-back unchanged seeds (results/checks/{post}/no-change)"
        else:
            rates["shift_power"] = {
                f"x{s:.2f}": shift_power(base, rule.seeds, rule.episodes, s, rule.alpha / HOLM_LEVEL, rng)
                for s in SHIFTS
            }
            entry["shift_power_from"] = "the baseline's own seeds"
    held = {}
    for m in HELD_OUT[post]:
        folder = CHECKS / post / "held-out" / m.name
        if folder.is_dir():
            runs = values(post, rule.statistic, rule.episodes, load(folder))
            held[m.name] = {"what": m.what, **measure(post, TIER, base, runs)}
    entry["held_out"] = held
    if rule.candidates != (rule.statistic,):  # what each candidate would have seen: not an estimate
        entry["held_out_by_candidate"] = {
            statistic: {
                m.name: power(
                    values(post, statistic, rule.episodes, baseline_runs),
                    values(post, statistic, rule.episodes, load(CHECKS / post / "held-out" / m.name)),
                    rule.seeds,
                    statistic,
                    rule.alpha / HOLM_LEVEL,
                    rng=np.random.default_rng(13),
                )
                for m in HELD_OUT[post]
                if (CHECKS / post / "held-out" / m.name).is_dir()
            }
            for statistic in rule.candidates
        }
    entry["held_out_folder"] = f"results/checks/{post}/held-out"
    measured = [r["power_alpha"] for r in held.values()]
    rates["held_out_power"] = float(np.mean(measured)) if measured else None
    if rule.candidates != (rule.statistic,):  # chosen on the tuning mutants: the chosen row's power
        chosen = next(
            c for c in entry["selection"]["candidates"] if (c["statistic"], c["alpha"]) == (rule.statistic, rule.alpha)
        )
        rates["power_gross"], rates["power_all"] = chosen["power_gross"], chosen["power_all"]
    entry["rates"] = rates
    return entry


def compute() -> dict:
    posts = {post: post_entry(post) for post in POSTS}
    family = family_false_alarm_rate([p["rates"]["false_alarm_holm_first"] for p in posts.values()])
    return {"tier": TIER, "holm_level": HOLM_LEVEL, "posts": posts, "command_false_alarm_holm": family}


def render(data: dict) -> str:
    posts = data["posts"]
    lines = [
        "The sensitive tier (`keras-rl check --tier sensitive`), as its rules run: generated by",
        "`python -m maintainers calibrate sensitive --write` (its docstring says how). "
        "Its sizes were set before its runs",
        "(`results/checks/sensitive_plan.md`, `results/checks/sensitive_plan_cartpole.md`).",
        "",
        "| post | statistic (first episodes) | engine | n fresh | baseline | false alarms at alpha 0.01 "
        "| at alpha / 3 | power, median x0.90 / x1.10 (at alpha / 3; fresh seeds drawn from) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for post, p in posts.items():
        r, rates = p["rule"], p["rates"]
        shift = rates.get("shift_power")
        moved = (
            f"{shift['x0.90']:.2f} / {shift['x1.10']:.2f} ({p['shift_power_from']})"
            if shift
            else "- (not episodes to threshold)"
        )
        lines.append(
            f"| {post} | {r['statistic']} ({r['episodes']}) | {r['engine']} | {r['seeds']} | {p['baseline_seeds']} "
            f"(`{r['baseline']}`) | {rates['false_alarm_rate']:.2%} | {rates['false_alarm_holm_first']:.2%} | {moved} |"
        )
    lines += [
        "",
        f"The three-post command (`keras-rl check --tier sensitive`, Holm over the three): false alarms "
        f"**{data['command_false_alarm_holm']:.2%}** when nothing changed.",
    ]
    for post, p in posts.items():
        if "selection" not in p:
            continue
        sel = p["selection"]
        lines += [
            "",
            f"{post}'s statistic, chosen by the rules' criterion on the tuning mutants ({sel['chosen_on']}; "
            f"{p['rule']['seeds']} fresh seeds against the baseline): chosen **{sel['chosen']['statistic']}** at "
            f"alpha {sel['chosen']['alpha']}.",
            "",
            "| statistic | alpha | false alarms | power, gross mutants | power, all mutants |",
            "|---|---|---|---|---|",
        ]
        for c in sel["candidates"]:
            lines.append(
                f"| {c['statistic']} | {c['alpha']} | {c['false_alarm_rate']:.2%} | {c['power_gross']:.0%} "
                f"| {c['power_all']:.0%} |"
            )
    for post, p in posts.items():
        by = p.get("held_out_by_candidate")
        if not by:
            continue
        names = list(next(iter(by.values())))
        lines += [
            "",
            f"What each of {post}'s candidates would see of its held-out mutants (power at alpha / 3, "
            f"{p['rule']['seeds']} fresh seeds). Not an estimate of the rule's power: choosing the statistic on "
            "these rows would tune it to the mutants that exist to measure it untuned.",
            "",
            "| statistic | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names),
        ]
        for statistic, row in by.items():
            lines.append(f"| {statistic} | " + " | ".join(f"{row[n]:.0%}" for n in names) + " |")
    lines += [
        "",
        "Held-out mutants at the sensitive tier (never used to choose; the 95% intervals are a seed",
        "bootstrap of the power and Clopper-Pearson on the disjoint real checks):",
        "",
        "| post | mutant | runs (folder) | statistic (n) | median: mutant / baseline "
        "| power at alpha [seed bootstrap 95%] | at alpha / 3 | disjoint checks flagged [Clopper-Pearson 95%] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for post, p in posts.items():
        for name, r in p["held_out"].items():
            runs = f"{r['seeds']} (`{p['held_out_folder']}`)"
            cells = [post, f"{name} ({r['what']})", runs, f"{r['statistic']} ({r['n']})"]
            lines.append("| " + " | ".join(cells + power_cells(r)) + " |")
    return "\n".join(lines)


def sees_table(data: dict, held_out: dict) -> str:
    """docs/check.md's "what the check can and cannot see": each held-out mutant's power at each
    tier (one post's command, at alpha), from held_out.json (smoke, full) and this tier's data."""
    lines = [
        "| post | held-out mutant | smoke | full | sensitive | sensitive: median, mutant / baseline |",
        "|---|---|---|---|---|---|",
    ]
    for post, entry in data["posts"].items():
        for name, r in entry["held_out"].items():
            tiers = held_out.get(post, {}).get("mutants", {}).get(name, {}).get("tiers", {})
            cells = [f"{tiers[t]['power_alpha']:.0%}" if t in tiers else "-" for t in ("smoke", "full")]
            med = "-" if r["median_mutant"] is None else f"{r['median_mutant']:.4g}"
            lines.append(
                f"| {post} | {name} ({r['what']}) | {' | '.join(cells)} | **{r['power_alpha']:.0%}** "
                f"| {med} / {r['median_baseline']:.4g} ({entry['rule']['statistic']}) |"
            )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    data = compute()
    text = render(data)
    if not args.write:
        print(text)
        return 0
    import json

    from keras_rl.atomic import atomic_write_json, atomic_write_text
    from keras_rl.check.command import SENSITIVE_RATES
    from maintainers.markdown import replace_block

    atomic_write_json(SENSITIVE_RATES, data)
    docs = ROOT / "docs" / "check.md"
    held = json.loads((CHECKS / "held_out.json").read_text())
    atomic_write_text(docs, replace_block(docs.read_text(), SEES_BEGIN, SEES_END, sees_table(data, held)))
    page = splice_calibration(HEADING, BEGIN, END, text)
    print(f"updated {SENSITIVE_RATES}, {page} and {docs}")
    return 0
