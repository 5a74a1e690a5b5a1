"""The sensitive tier measured on real runs outside any baseline (issue 52, item 4).

    python -m maintainers calibrate real            # print the block
    python -m maintainers calibrate real --write    # results/checks/real_checks.json and its calibration.md block

The plan was committed before the runs (``results/checks/real_checks_plan.md``; the runs are the
lines of ``maintainers/queues/issue52*.tsv``). What the resampled rates of
``calibrate sensitive`` cannot say, these say from runs that no baseline holds:

- **False alarms**: a pool of unchanged seeds cut, in seed order, into disjoint fresh sets of
  the rule's size; each set is one real check against the committed baseline. Flagged sets out
  of all, at alpha and at alpha / 3, with the exact (Clopper-Pearson) 95% interval.
- **Power**: each held-out mutant's runs (grown where the plan grew them) cut the same way; its
  true shift is the median of its seeds over the pool's median, with a seed bootstrap.
- **The fresh-seed count** (posts 000 and 003, whose statistic is episodes to threshold): n seeds
  drawn without replacement from the pool (never the baseline), their episodes to threshold
  scaled by 0.90 and 1.10, against the baseline; the smallest n with power at least 0.80 against
  both at alpha / 3 in at most 15 minutes. Only post 000's rule takes it; for post 003 it says
  what its tier can and cannot see.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from keras_rl.check.rules import HELD_OUT, UNPAIRED_SENSITIVE
from keras_rl.check.statistics import changed_many
from keras_rl.runs.run_set import RunSet
from maintainers.calibrate.runs import CHECKS, HOLM_LEVEL, clopper_pearson, load, shifted, splice_calibration, values

TIER = "sensitive"
OUT = CHECKS / "real_checks.json"
BEGIN, END = "<!-- real:begin -->", "<!-- real:end -->"
HEADING = "## The sensitive tier on real runs"
SIZES = (30, 40, 50, 60, 80, 100)
SHIFTS = (0.90, 1.10)
DRAWS = 2000
TARGET_POWER, BUDGET_MINUTES, WORKERS = 0.80, 15.0, 2
TARGET_FALSE_ALARMS = 0.01
"""Issue 52's target for post 000's sensitive tier: the three-post command's family-wise rate."""
GROWN = {
    "pendulum": "held-out-seeds-3200-3499",
    "cartpole": "held-out-seeds-30-79",
    "mountaincar": "held-out-seeds-30-109",
}
"""Where the plan grew a post's held-out mutants (their first seeds are in ``held-out``)."""
PLANNED_CHECK = {"pendulum": 50, "cartpole": 40, "mountaincar": 40}
"""The fresh seeds of one real check, as ``results/checks/real_checks_plan.md`` set them before the
runs (the rules' sizes then). Where a rule's size has since moved (post 000's to 80, by this
calibration's own re-derivation), its checks are cut at the rule's size too, beside the plan's."""
REAL_POSTS = ("pendulum", "cartpole", "mountaincar")
"""Posts with real no-change checks (post 003's added to the plan on 2026-11-28, before its runs)."""


def folders_under(folder: Path) -> list[Path]:
    """The run sets directly under ``folder``, in order of their first seed."""
    sets = [f for f in folder.iterdir() if f.is_dir() and RunSet(f).runs()] if folder.is_dir() else []
    return sorted(sets, key=lambda f: min(r.seed for r in RunSet(f).runs()))


def runs_of(folders: list[Path]) -> tuple[list, list[int], list[float]]:
    """Every run of ``folders`` in seed order: rows (None for one that blew up), seeds, wall seconds."""
    rows, seeds, walls = [], [], []
    for folder in folders:
        rows += load(folder)
        for run in RunSet(folder).runs():
            seeds.append(run.seed)
            walls.append(run.summary().wall_seconds)
    order = np.argsort(seeds, kind="stable")
    return [rows[i] for i in order], [seeds[i] for i in order], [walls[i] for i in order]


def disjoint_checks(baseline: np.ndarray, runs: np.ndarray, n: int, statistic: str, alpha: float) -> dict:
    """``runs`` cut in order into disjoint sets of ``n``, each one check against the whole baseline."""
    sets = len(runs) // n
    if sets == 0:
        return {"checks": 0, "flagged": 0, "ci95": None}
    fresh = runs[: sets * n].reshape(sets, n)
    flagged = int(changed_many(np.broadcast_to(baseline, (sets, len(baseline))), fresh, statistic, alpha).sum())
    return {"checks": sets, "flagged": flagged, "ci95": clopper_pearson(flagged, sets)}


def both_levels(baseline: np.ndarray, runs: np.ndarray, rule, n: int) -> dict:
    return {
        "n": n,
        "alpha": disjoint_checks(baseline, runs, n, rule.statistic, rule.alpha),
        "holm_first": disjoint_checks(baseline, runs, n, rule.statistic, rule.alpha / HOLM_LEVEL),
    }


def cuts(post: str, baseline: np.ndarray, runs: np.ndarray, rule) -> list[dict]:
    """The runs as real checks of the plan's size, and of the rule's where it differs."""
    sizes = dict.fromkeys([PLANNED_CHECK[post], rule.seeds])
    return [both_levels(baseline, runs, rule, n) for n in sizes]


def median_ratio(runs: np.ndarray, pool: np.ndarray, rng: np.random.Generator) -> dict:
    """The mutant's median over the pool's, with a 95% seed bootstrap (2,000 resamples of each)."""
    boot = [
        np.median(runs[rng.integers(0, len(runs), len(runs))]) / np.median(pool[rng.integers(0, len(pool), len(pool))])
        for _ in range(2000)
    ]
    return {
        "ratio": float(np.median(runs) / np.median(pool)),
        "ci95": (float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))),
    }


def held_back_power(baseline: np.ndarray, pool: np.ndarray, budget: int, alpha: float, n: int) -> dict:
    """n fresh seeds drawn from the pool without replacement, ``DRAWS`` times (from seed 52 + n):
    how often they are flagged against the baseline at ``alpha`` unchanged (false alarms) and with
    their episodes to threshold times 0.90 and 1.10 (a seed that never got there stays so)."""
    rng = np.random.default_rng(52 + n)
    fresh = np.stack([rng.choice(pool, n, replace=False) for _ in range(DRAWS)])
    bases = np.broadcast_to(baseline, (DRAWS, len(baseline)))
    row = {"n": n, "false_alarms": float(changed_many(bases, fresh, "episodes_to_threshold", alpha).mean())}
    for shift in SHIFTS:
        moved = shifted(fresh, shift, budget)
        row[f"x{shift:.2f}"] = float(changed_many(bases, moved, "episodes_to_threshold", alpha).mean())
    return row


def sizes(baseline: np.ndarray, pool: np.ndarray, budget: int, alpha: float, seed_minutes: float) -> list[dict]:
    """``held_back_power`` for each fresh-seed count of ``SIZES`` the pool can give, with the
    minutes its fresh seeds take on ``WORKERS`` workers."""
    return [
        {**held_back_power(baseline, pool, budget, alpha, n), "minutes": n * seed_minutes / WORKERS}
        for n in SIZES
        if n < len(pool)
    ]


def pool_values(post: str) -> np.ndarray | None:
    """Each unchanged seed's statistic (the post's sensitive rule's) from its no-change pool, or None."""
    rule = UNPAIRED_SENSITIVE[post]
    folders = folders_under(CHECKS / post / "no-change")
    return values(post, rule.statistic, rule.episodes, runs_of(folders)[0]) if folders else None


def post_entry(post: str) -> dict:
    rule = UNPAIRED_SENSITIVE[post]
    base = values(post, rule.statistic, rule.episodes, load(CHECKS / post / rule.baseline))
    _, pool_seeds, pool_walls = runs_of(folders_under(CHECKS / post / "no-change"))
    entry: dict = {
        "rule": {"statistic": rule.statistic, "alpha": rule.alpha, "seeds": rule.seeds, "episodes": rule.episodes},
        "baseline": f"results/checks/{post}/{rule.baseline}",
        "baseline_seeds": len(base),
        "pool_seeds": [min(pool_seeds), max(pool_seeds)] if pool_seeds else None,
        "pool_size": len(pool_seeds),
    }
    if not pool_seeds:
        return entry
    pool = pool_values(post)
    assert pool is not None
    entry["no_change"] = cuts(post, base, pool, rule)
    seed_minutes = float(np.median(pool_walls)) / 60
    entry["seed_minutes"] = seed_minutes
    rng = np.random.default_rng(53)
    mutants = {}
    for m in HELD_OUT[post]:
        folders = [CHECKS / post / "held-out" / m.name, CHECKS / post / GROWN.get(post, "-") / m.name]
        rows, seeds, _ = runs_of([f for f in folders if f.is_dir()])
        runs = values(post, rule.statistic, rule.episodes, rows)
        mutants[m.name] = {
            "what": m.what,
            "seeds": len(seeds),
            "shift": median_ratio(runs, pool, rng),
            "checks": cuts(post, base, runs, rule),
        }
    entry["mutants"] = mutants
    if rule.statistic == "episodes_to_threshold":
        table = sizes(base, pool, rule.episodes, rule.alpha / HOLM_LEVEL, seed_minutes)
        meets = [
            r for r in table if min(r[f"x{s:.2f}"] for s in SHIFTS) >= TARGET_POWER and r["minutes"] <= BUDGET_MINUTES
        ]
        entry["sizes"] = table
        entry["smallest_meeting_target"] = meets[0]["n"] if meets else None
    return entry


def compute() -> dict:
    posts = {post: post_entry(post) for post in REAL_POSTS}
    return {"tier": TIER, "holm_level": HOLM_LEVEL, "posts": posts}


def _checks(d: dict) -> str:
    if not d["checks"]:
        return "no check (fewer seeds than one check needs)"
    low, high = d["ci95"]
    return f"{d['flagged']}/{d['checks']} [{low:.0%}, {high:.0%}]"


def _size(post: str, n: int, entry: dict) -> str:
    """A check's size, labelled: the plan's, the rule's, or both."""
    said = [w for w, size in (("planned", PLANNED_CHECK[post]), ("the rule's", entry["rule"]["seeds"])) if size == n]
    return f"{n} ({' and '.join(said)})"


def against_target(p: dict, command_rate: float) -> list[str]:
    """Post 000's tier against issue 52's target, each part with its number: met, or missed by how much."""
    row = next(r for r in p["sizes"] if r["n"] == p["rule"]["seeds"])
    n = p["rule"]["seeds"]
    power = min(row["x0.90"], row["x1.10"])
    real = next((c["holm_first"] for c in p.get("no_change", []) if c["n"] == n), None)
    over = command_rate - TARGET_FALSE_ALARMS
    lines = [
        "",
        f"**Post 000 against the target** (power at least {TARGET_POWER:.0%} against a 10% shift of the median "
        f"either way, family-wise false alarms at most {TARGET_FALSE_ALARMS:.0%}, at most {BUDGET_MINUTES:g} "
        f"minutes), at the rule's {n} fresh seeds:",
        f"- power {row['x0.90']:.2f} / {row['x1.10']:.2f} on held-back seeds: "
        + ("meets it." if power >= TARGET_POWER else f"misses it by {TARGET_POWER - power:.2f}."),
        f"- {row['minutes']:.1f} minutes of fresh seeds on {WORKERS} workers, from the pool's median seed time "
        "(an estimate, not a timed check): "
        + ("meets it." if row["minutes"] <= BUDGET_MINUTES else f"misses it by {row['minutes'] - BUDGET_MINUTES:.1f}."),
        f"- false alarms: the three-post command's rate, resampled from the baselines, is {command_rate:.2%}: "
        + ("meets it" if over <= 0 else f"**misses it by {over * 100:.2f} points**")
        + f"; post 000's own rate at alpha / 3 on held-back seeds is {row['false_alarms']:.2%}"
        + (
            f", and its real no-change checks flagged {real['flagged']} of {real['checks']} "
            f"[{real['ci95'][0]:.0%}, {real['ci95'][1]:.0%}]: too few checks to bound a rate near "
            f"{TARGET_FALSE_ALARMS:.0%}."
            if real and real["checks"]
            else "."
        ),
    ]
    return lines


def render(data: dict, resampled: dict) -> str:
    """The block, from ``data`` (``compute()``) and ``resampled`` (the package's ``sensitive.json``)."""
    command_rate = resampled["command_false_alarm_holm"]
    resampled = resampled["posts"]
    lines = [
        "Generated by `python -m maintainers calibrate real --write` from runs that no baseline holds,",
        "planned before they ran (`results/checks/real_checks_plan.md`). Each real check is n fresh seeds",
        "in seed order against the committed baseline, as `keras-rl check --tier sensitive` runs it;",
        "brackets are exact (Clopper-Pearson) 95% intervals. The resampled rates (previous section)",
        "stand beside them.",
        "",
        "| post | n fresh | real runs | false alarms at alpha 0.01 | at alpha / 3 | resampled (alpha / 3) |",
        "|---|---|---|---|---|---|",
    ]
    for post, p in data["posts"].items():
        if "no_change" not in p:
            lines.append(f"| {post} | {p['rule']['seeds']} | none yet | - | - | - |")
            continue
        was = resampled.get(post, {}).get("rates", {}).get("false_alarm_holm_first")
        for cut in p["no_change"]:
            lines.append(
                f"| {post} | {_size(post, cut['n'], p)} | {p['pool_size']} unchanged seeds ({p['pool_seeds'][0]}-"
                f"{p['pool_seeds'][1]}) | {_checks(cut['alpha'])} | {_checks(cut['holm_first'])} | "
                f"{'-' if was is None or cut['n'] != p['rule']['seeds'] else f'{was:.2%}'} |"
            )
    lines += [
        "",
        "Power against real changes: each held-out mutant's seeds cut into disjoint checks. Its shift is",
        "the median of its seeds over the no-change pool's (95% seed bootstrap).",
        "",
        "| post | mutant | seeds | median, mutant / unchanged | n fresh | flagged at alpha 0.01 | at alpha / 3 |",
        "|---|---|---|---|---|---|---|",
    ]
    for post, p in data["posts"].items():
        for name, m in p.get("mutants", {}).items():
            s = m["shift"]
            for cut in m["checks"]:
                lines.append(
                    f"| {post} | {name} ({m['what']}) | {m['seeds']} | x{s['ratio']:.3f} [{s['ci95'][0]:.3f}, "
                    f"{s['ci95'][1]:.3f}] | {_size(post, cut['n'], p)} | {_checks(cut['alpha'])} "
                    f"| {_checks(cut['holm_first'])} |"
                )
    for post, p in data["posts"].items():
        if "sizes" not in p:
            continue
        lines += [
            "",
            f"{post}'s fresh-seed count re-derived on held-back seeds: n drawn from the {p['pool_size']} unchanged",
            f"seeds (never the baseline's), episodes to threshold x0.90 / x1.10, {DRAWS} draws per row, at alpha / 3;",
            f"minutes of fresh seeds on {WORKERS} workers at the pool's median {p['seed_minutes'] * 60:.1f} s a seed.",
            "",
            "| n fresh | power x0.90 | power x1.10 | false alarms | minutes |",
            "|---|---|---|---|---|",
        ]
        for r in p["sizes"]:
            mark = " **(rule)**" if r["n"] == p["rule"]["seeds"] else ""
            cells = [f"{r['n']}{mark}", f"{r['x0.90']:.2f}", f"{r['x1.10']:.2f}", f"{r['false_alarms']:.2%}"]
            lines.append("| " + " | ".join([*cells, f"{r['minutes']:.1f}"]) + " |")
        best = p["smallest_meeting_target"]
        rule_row = next((r for r in p["sizes"] if r["n"] == p["rule"]["seeds"]), None)
        if best is None:
            lines += [
                "",
                f"No n up to {SIZES[-1]} meets {TARGET_POWER:.0%} against both shifts in {BUDGET_MINUTES:g} minutes.",
            ]
        else:
            lines += [
                "",
                f"The smallest n with power at least {TARGET_POWER:.0%} against both shifts at alpha / 3 in at most "
                f"{BUDGET_MINUTES:g} minutes: **{best}**"
                + (
                    f"; the rule's {p['rule']['seeds']} gives {rule_row['x0.90']:.2f} / {rule_row['x1.10']:.2f}."
                    if rule_row
                    else "."
                ),
            ]
        if post == "pendulum" and rule_row:
            lines += against_target(p, command_rate)
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from keras_rl.atomic import atomic_write_json
    from keras_rl.check.command import SENSITIVE_RATES

    data = compute()
    text = render(data, json.loads(SENSITIVE_RATES.read_text()))
    if not args.write:
        print(text)
        return 0
    atomic_write_json(OUT, data)
    print(f"updated {OUT} and {splice_calibration(HEADING, BEGIN, END, text)}")
    return 0
