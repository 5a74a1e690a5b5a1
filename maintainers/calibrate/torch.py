"""``check --framework torch``'s rates on real runs (``results/checks/torch_plan.md``, committed first).

    python -m maintainers calibrate torch [--write]

For each PyTorch rule (``rules.TORCH_RULES``), from committed runs only, none of which chose the rule
(it is the Keras rule of the same post and tier, taken over as it stands):

- false alarms on real changes of arithmetic (the plan's ``FALSE_ALARMS``: the engine swap);
- power against real changes of the algorithm (``POWER``: the tutorial's two community fixes), each
  with its true shift, the ratio of its seeds' median statistic to the baseline's.

Each is read resampled (``DRAWS`` draws of the rule's n seeds without replacement, each tested as the
check tests them, against the baseline less the drawn seed numbers so that no seed meets its twin)
and as disjoint real checks (consecutive blocks of n seeds) with a Clopper-Pearson interval. Writes
``keras_rl/check/torch.json`` (package data, which the check quotes) and the block "The PyTorch
check" in ``results/checks/calibration.md``.
"""

from __future__ import annotations

import argparse

import numpy as np

from keras_rl.check.command import TORCH_RATES, rule_fields
from keras_rl.check.rules import TORCH_RULES, CheckRule
from keras_rl.check.statistics import changed_many
from keras_rl.runs.run_set import RunSet
from maintainers.calibrate.runs import CHECKS, clopper_pearson, load, splice_calibration, values
from maintainers.checkout import ROOT

PLAN = CHECKS / "torch_plan.md"
BEGIN, END = "<!-- torch:begin -->", "<!-- torch:end -->"
HEADING = "## The PyTorch check (issue 70): its rules' error rates on real runs"
DRAWS = 10_000
RESULTS = ROOT / "results"
FALSE_ALARMS: dict[tuple[str, str], dict[str, list[str]]] = {
    ("cartpole", "smoke"): {
        "the engine swap (the tutorial's code on the Gymnasium loop)": [
            "cartpole/faithful-torch",
            "cartpole/faithful-torch-seeds-30-199",
            "cartpole/faithful-torch-seeds-114-199",
        ],
    },
}
"""Rule -> real changes of arithmetic that keep the algorithm -> the committed sets that hold them."""
POWER: dict[tuple[str, str], dict[str, list[str]]] = {
    ("cartpole", "smoke"): {
        "pytorch/tutorials #3080's values": ["cartpole/tutorial-fix/issue-3080-vectorised"],
        "pytorch/tutorials PR #3384's values": ["cartpole/tutorial-fix/pr-3384-vectorised"],
    },
}
"""Rule -> real changes of the algorithm, on the rule's engine -> the committed sets that hold them."""


def statistics(rule: CheckRule, sets: list[str]) -> dict[int, float]:
    """Seed -> the rule's statistic over every seed of ``sets`` (under ``results/``)."""
    out: dict[int, float] = {}
    for name in sets:
        folder = RESULTS / name
        out.update(zip(RunSet(folder).seeds, values(rule.experiment, rule.statistic, rule.episodes, load(folder))))
    return out


def reading(rule: CheckRule, baseline: dict[int, float], changed: dict[int, float], seed: int = 70) -> dict:
    """The rule against one real change: resampled and as disjoint real checks."""
    rng = np.random.default_rng(seed)
    seeds = np.asarray(sorted(changed))
    if set(changed) - set(baseline):  # then a draw would meet fewer baseline twins than it left out
        raise SystemExit(f"error: the baseline lacks seeds {sorted(set(changed) - set(baseline))[:5]} of the change")
    n = rule.seeds
    news, bases = [], []
    for _ in range(DRAWS):
        drawn = set(rng.choice(seeds, size=n, replace=False).tolist())
        news.append([changed[s] for s in sorted(drawn)])
        bases.append([v for s, v in sorted(baseline.items()) if s not in drawn])
    flagged = changed_many(np.asarray(bases), np.asarray(news), rule.statistic, rule.alpha)
    blocks = [seeds[i : i + n] for i in range(0, len(seeds) - n + 1, n)]
    real = []
    for block in blocks:
        left_out = set(block.tolist())
        rest = [v for s, v in sorted(baseline.items()) if s not in left_out]
        real.append(bool(changed_many([rest], [[changed[int(s)] for s in block]], rule.statistic, rule.alpha)[0]))
    low, high = clopper_pearson(sum(real), len(real))
    return {
        "seeds": len(seeds),
        "true_shift": float(np.nanmedian(list(changed.values())) / np.nanmedian(list(baseline.values()))),
        "resampled": float(np.mean(flagged)),
        "real_checks": {"flagged": int(sum(real)), "checks": len(real), "ci95": [low, high]},
    }


def compute() -> dict:
    data: dict = {}
    for (post, tier), rule in TORCH_RULES.items():
        baseline = statistics(rule, [f"checks/{post}/{rule.baseline}"])
        false, power = (
            {name: reading(rule, baseline, statistics(rule, sets)) for name, sets in changes[post, tier].items()}
            for changes in (FALSE_ALARMS, POWER)
        )
        data.setdefault(post, {})[tier] = {
            "rule": rule_fields(rule),
            "baseline_seeds": len(baseline),
            "false_alarm_rate": max(r["resampled"] for r in false.values()),
            "false_alarms": false,
            "real_power": power,
            "plan": str(PLAN.relative_to(ROOT)),
        }
    return data


def _checks(r: dict) -> str:
    c = r["real_checks"]
    return f"{c['flagged']} of {c['checks']} ({c['ci95'][0]:.0%}-{c['ci95'][1]:.0%})"


def render(data: dict) -> str:
    lines = [
        "Generated by `python -m maintainers calibrate torch --write` (`maintainers/calibrate/torch.py`), as",
        f"`{PLAN.relative_to(ROOT)}` planned before it ran: each rule against committed real runs, resampled",
        f"({DRAWS:,} draws of its n seeds, each against the baseline less the drawn seed numbers) and as",
        "disjoint real checks of n consecutive seeds (Clopper-Pearson 95%). No run here chose the rule.",
        "",
        "| post | tier | rule | change | kind | seeds | true shift of the median | flagged, resampled "
        "| real checks flagged |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for post, tiers in data.items():
        for tier, entry in tiers.items():
            r = entry["rule"]
            rule = f"{r['statistic']}, {r['seeds']} seeds x {r['episodes']} episodes, {r['engine']}, alpha {r['alpha']}"
            for kind, group in (("false alarm", entry["false_alarms"]), ("power", entry["real_power"])):
                for name, m in group.items():
                    lines.append(
                        f"| {post} | {tier} | {rule} | {name} | {kind} | {m['seeds']} | x{m['true_shift']:.3f} | "
                        f"{m['resampled']:.1%} | {_checks(m)} |"
                    )
    lines += [
        "",
        "No gross mutant of post 003 exists in PyTorch, so the smoke tier's power against gross breakage is not",
        "measured for it. Posts 000 and 001 have no PyTorch rule yet (the plan says why).",
    ]
    return "\n".join(lines)


DOCS = ROOT / "docs" / "check.md"
DOCS_BEGIN, DOCS_END = "<!-- torch-rates:begin -->", "<!-- torch-rates:end -->"


def summary(data: dict) -> str:
    """The rates in a sentence each, for docs/check.md."""
    lines = []
    for post, tiers in data.items():
        for tier, entry in tiers.items():
            for kind, group in (("false alarms on", entry["false_alarms"]), ("power against", entry["real_power"])):
                for name, m in group.items():
                    lines.append(
                        f"- {post}, {tier}: {kind} {name} ({m['seeds']} seeds, median x{m['true_shift']:.2f}): "
                        f"{m['resampled']:.1%} resampled, {_checks(m)} real checks"
                    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from keras_rl.atomic import atomic_write_json, atomic_write_text
    from maintainers.markdown import replace_block

    data = compute()
    text = render(data)
    print(text)
    if args.write:
        atomic_write_json(TORCH_RATES, data)
        atomic_write_text(DOCS, replace_block(DOCS.read_text(), DOCS_BEGIN, DOCS_END, summary(data)))
        print(f"updated {TORCH_RATES}, {DOCS} and {splice_calibration(HEADING, BEGIN, END, text)}")
    return 0
