"""Measure the error rates of ``keras-rl check``'s decision rules, and which rule the
pre-registered criterion picks (``keras_rl/check/rules.py``).

    python -m maintainers calibrate rules pendulum mountaincar --write
    python -m maintainers calibrate rules cartpole --make --workers 2 --write
    python -m maintainers calibrate rules --write     # rerender calibration.md from calibration.json

Inputs, all committed: the faithful baseline ``results/checks/<exp>/baseline`` (every seed it holds) and
each mutant's 10 seeds ``results/checks/<exp>/mutants/<name>`` (``--make`` runs the missing
ones with the commands it prints). For every tier and every candidate rule (each statistic
the tier lists, at each alpha of ``ALPHAS``), with the tier's number of fresh seeds n:

- false-alarm rate: n baseline seeds drawn as the "new" runs and tested against the rest of
  the baseline, 10,000 times;
- power against each mutant: n seeds drawn with replacement from the mutant's runs, tested
  against the whole baseline, 2,000 times; "gross" and "all" are the means over the mutants;
- for the chosen rule, the smallest delay d (in episodes) of the baseline's learning curves
  that the rule flags 80% of the time (a seed d episodes slower, and its statistic
  recomputed): the smallest shift in median episodes-to-threshold it detects.

The criterion: among candidates whose false-alarm rate is at most 1%, the most power against
the gross mutants, then against all of them; ties go to the rule listed first. ``--write``
puts the tables in ``keras_rl/check/calibration.json`` (package data) and ``results/checks/calibration.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.check.command import CALIBRATION
from keras_rl.check.rules import ALPHAS, CALIBRATED_TIERS, MUTANTS, RULES
from keras_rl.check.statistics import false_alarm_rate, power
from keras_rl.errors import ConfigError
from keras_rl.learners.table import batch_refusal
from keras_rl.registry import get_experiment
from keras_rl.runs.run_set import RunSet
from maintainers.calibrate.runs import (
    CHECKS,
    REPORT,
    TUNE,
    budget,
    choose,
    engine_args,
    halved,
    load,
    measure,
    power_cells,
    seed_count,
    seed_dirs,
    values,
)
from maintainers.checkout import ROOT
from maintainers.markdown import replace_block

MUTANT_SEEDS = "0-9"
MUTANT_BATCH = 10
"""Mutant seeds 10-29 of a Gymnasium-loop post (post 001) run in batches of 10 (``--seed-batch
10``), as the check's fresh seeds do; its seeds 0-9 ran solo, before it could batch (batched
against solo: ``results/mountaincar/seed-batch/report.md``). A config no stacked learner covers
(post 001's learning phase) runs solo. A post whose rules run on the compiled engine (posts 000
and 003 since issue 34 retired their stacked learners) runs every seed there, one per program."""
BASELINE_BATCH = {"mountaincar": 1}
"""How each Gymnasium-loop baseline was made (its summaries' ``--seed-batch``): one seed per run
for post 001."""


def make_commands(name: str) -> list[list[str]]:
    """The commands that make the baseline and every mutant's runs, where missing."""
    rules = [RULES[(name, t)] for t in CALIBRATED_TIERS]
    episodes = max(r.episodes for r in rules)
    # mutants batch as the check's fresh seeds do (auto runs a config no stacked learner covers alone)
    common = ["--no-progress", "--min-success-rate", "0", "--workers", "2", *engine_args(name, "auto")]
    out = []
    if not (CHECKS / name / "baseline").is_dir():
        out.append(
            [
                "keras-rl",
                "reproduce",
                name,
                "--seeds",
                "0-29",
                *engine_args(name, BASELINE_BATCH.get(name, 1)),
                "--no-progress",
                "--min-success-rate",
                "0",
                "--workers",
                "2",
                "--out",
                f"results/checks/{name}/baseline",
            ]
        )
    for m in MUTANTS[name]:
        folder = CHECKS / name / "mutants" / m.name
        sets = [a for k, v in m.overrides.items() for a in ("--set", f"{k}={v}")]
        if folder.is_dir() and seed_count(folder) < len(TUNE) + len(REPORT):
            # seeds 10-29 beside the committed 0-9, made alike; --make then moves them in (move_seeds)
            config = get_experiment(name).config_cls.for_variant("faithful").with_text_overrides(sets[1::2])
            batched = engine_args(name, 1 if batch_refusal(name, config) else MUTANT_BATCH)
            out.append(
                ["keras-rl", "reproduce", name, "--seeds", "10-29", "--episodes", str(episodes), *sets,
                 "--no-progress", "--min-success-rate", "0", "--workers", "2", *batched,
                 "--out", f"results/checks/{name}/mutants-seeds-10-29/{m.name}"]
            )  # fmt: skip
        if not folder.is_dir():
            out.append(
                [
                    "keras-rl",
                    "reproduce",
                    name,
                    "--seeds",
                    MUTANT_SEEDS,
                    "--episodes",
                    str(episodes),
                    *sets,
                    *common,
                    "--out",
                    f"results/checks/{name}/mutants/{m.name}",
                ]
            )
    return out


def move_seeds(src: Path, dst: Path) -> None:
    """Seeds made apart (a mutant's seeds 10-29) moved into the mutant's folder, whose
    summary.md and curves.png are then rebuilt; a seed already there is an error, before any moves."""
    moving = seed_dirs(src)
    clash = [d.name for d in moving if (dst / d.name).exists()]
    if clash:
        raise SystemExit(f"error: {dst} already has {', '.join(clash)}; nothing moved")
    for d in moving:
        d.rename(dst / d.name)
    subprocess.run([sys.executable, "-m", "keras_rl", "aggregate", str(dst)], cwd=ROOT, check=True)


def smallest_delay(name: str, rule, baseline_runs: list, target: float = 0.8) -> dict:
    """The smallest delay of the baseline's curves the rule flags ``target`` of the time.

    Searched only over the delays at which every run's delayed statistic is still defined
    (a final-window metric is undefined once the delay pushes the whole window before the
    first episode): a NaN there would count as a change and report a delay the rule never
    saw. Returns ``delay`` (None: not reached), ``defined_up_to`` and the tier's ``episodes``."""
    base = values(name, rule.statistic, rule.episodes, baseline_runs)
    ran = np.isfinite(base)  # a run that blew up is NaN at every delay

    def delayed(d: int) -> np.ndarray:
        return values(name, rule.statistic, rule.episodes, baseline_runs, d)

    def defined(d: int) -> bool:
        return bool(np.isfinite(delayed(d)[ran]).all())

    def flagged(d: int) -> bool:
        return power(base, delayed(d), rule.seeds, rule.statistic, rule.alpha, repeats=500) >= target

    top = rule.episodes
    if not defined(top):  # the largest delay where the statistic is defined (it is at 0)
        lo, hi = 0, top
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if defined(mid) else (lo, mid)
        top = lo
    out: dict = {"delay": None, "defined_up_to": top, "episodes": rule.episodes}
    if top == 0 or not flagged(top):
        return out
    lo, hi = 0, top
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if flagged(mid) else (mid, hi)
    out["delay"] = hi
    return out


def delay_text(found: dict) -> str:
    """A ``smallest_delay`` result in words."""
    if found["delay"] is not None:
        return f"{found['delay']} of {found['episodes']} episodes"
    if found["defined_up_to"] < found["episodes"]:
        return f"none up to {found['defined_up_to']} of {found['episodes']} episodes (later, the metric is undefined)"
    return f"none up to {found['episodes']} episodes"


OLD_TESTS = {  # the k-of-n threshold tests the smoke tier replaces: (passes k of n seeds, per-seed pass on rows)
    "pendulum": (
        "2 of 3 seeds reach EMA > -300 within 300 episodes",
        2,
        3,
        "episodes_to_threshold",
        300,
        lambda value: value <= 300,
    ),
    "cartpole": (
        "1 of 4 seeds reaches a 100-episode mean of 475 within 600 episodes",
        1,
        4,
        "success",
        600,
        lambda value: value == 1.0,
    ),
    "mountaincar": (
        "2 of 3 seeds meet post 001's criterion after 100 episodes",
        2,
        3,
        "success",
        100,
        lambda value: value == 1.0,
    ),
}


def old_test(name: str, baseline: list, mutants: dict | None, repeats: int = 10_000) -> dict:
    """The k-of-n test's false-alarm rate (it fails on baseline seeds) and, given mutant runs
    as long as it looks, its power (it fails on a mutant's seeds); n seeds drawn with
    replacement each time."""
    what, k, n, statistic, episodes, passes = OLD_TESTS[name]
    rng = np.random.default_rng(3)

    def fail_rate(runs) -> float:
        ok = np.asarray([passes(v) for v in values(name, statistic, episodes, runs)])
        return float(np.mean([ok[rng.integers(0, len(ok), n)].sum() < k for _ in range(repeats)]))

    out: dict[str, Any] = {"test": what, "false_alarm_rate": fail_rate(baseline)}
    if mutants:
        per_mutant = {m.name: fail_rate(runs) for m, runs in mutants.values()}
        gross = [per_mutant[m.name] for m, _ in mutants.values() if m.gross]
        out.update(
            power=per_mutant, power_gross=float(np.mean(gross)), power_all=float(np.mean(list(per_mutant.values())))
        )
    return out


def calibrate(name: str) -> dict:
    baseline = load(CHECKS / name / "baseline")
    missing = [m.name for m in MUTANTS[name] if not (CHECKS / name / "mutants" / m.name).is_dir()]
    if missing:  # false alarms need only the baseline; power waits for the mutants
        out: dict[str, Any] = {}
        for tier in CALIBRATED_TIERS:
            rule = RULES[(name, tier)]
            out[tier] = {
                "not_calibrated": f"no mutant runs yet ({', '.join(missing)})",
                "false_alarm_rates": [
                    {
                        "statistic": st,
                        "alpha": a,
                        "false_alarm_rate": false_alarm_rate(
                            values(name, st, rule.episodes, baseline), rule.seeds, st, a
                        ),
                    }
                    for st in rule.candidates
                    for a in ALPHAS
                ],
            }
        out["smoke"]["old_k_of_n_test"] = old_test(name, baseline, None)
        return out
    folders = {m.name: CHECKS / name / "mutants" / m.name for m in MUTANTS[name]}
    halves = halved(list(folders.values()))
    mutants = {m.name: (m, load(folders[m.name], TUNE if halves else None)) for m in MUTANTS[name]}
    held_back = {m.name: load(folders[m.name], REPORT) for m in MUTANTS[name]} if halves else None
    shortest = min(budget(CHECKS / name / "mutants" / m.name) for m in MUTANTS[name])
    out = {}
    for tier in CALIBRATED_TIERS:
        rule = RULES[(name, tier)]
        if shortest < rule.episodes:  # a mutant run cut short would look like a failure
            out[tier] = {"not_calibrated": f"the mutant runs have {shortest} episodes; this tier needs {rule.episodes}"}
            continue
        rows, chosen = choose(name, rule, baseline, mutants)
        entry = {
            "baseline_seeds": len(baseline),
            "mutant_seeds": {k: len(v[1]) for k, v in mutants.items()},
            "chosen_on": f"seeds {TUNE.start}-{TUNE.stop - 1}" if halves else "every seed",
            "candidates": rows,
            "chosen": chosen and {"statistic": chosen["statistic"], "alpha": chosen["alpha"]},
            "rule": {"statistic": rule.statistic, "alpha": rule.alpha},
        }
        if chosen and (chosen["statistic"], chosen["alpha"]) == (rule.statistic, rule.alpha):
            entry["detectable_delay_80"] = smallest_delay(name, rule, baseline)
        if held_back:  # the rule as committed, on the seeds no choice looked at
            base = values(name, rule.statistic, rule.episodes, baseline)
            report = {
                k: measure(name, tier, base, values(name, rule.statistic, rule.episodes, runs))
                for k, runs in held_back.items()
            }
            gross = [report[m.name]["power_alpha"] for m, _ in mutants.values() if m.gross]
            entry["held_back"] = {
                "seeds": f"{REPORT.start}-{REPORT.stop - 1}",
                "mutants": report,
                "power_gross": float(np.mean(gross)),
                "power_all": float(np.mean([r["power_alpha"] for r in report.values()])),
            }
        out[tier] = entry
    if "candidates" in out["smoke"]:  # power only where the mutants ran as long as the old test looks
        out["smoke"]["old_k_of_n_test"] = old_test(name, baseline, mutants if shortest >= OLD_TESTS[name][4] else None)
    return out


def criterion_by_seeds(name: str) -> dict:
    """The post's own success criterion on baseline seeds 0-9 (where post 001's was chosen)
    beside the rest of the committed baseline (where it was not)."""
    from keras_rl.report.stats import fisher_exact

    summaries = RunSet(CHECKS / name / "baseline").summaries()
    first = [s.success for s in summaries if s.seed < 10]
    rest = [s for s in summaries if s.seed >= 10]
    won = sum(s.success for s in rest)
    return {
        "criterion": summaries[0].criterion,
        "0-9": f"{sum(first)}/{len(first)}",
        "rest_seeds": f"{rest[0].seed}-{rest[-1].seed}" if rest else "none",
        "rest": f"{won}/{len(rest)}",
        "fisher_p": fisher_exact(sum(first), len(first), won, len(rest)),
    }


def family_block() -> str:
    """The family-wise section (``maintainers/calibrate/family.py --write``), kept across rewrites."""
    from maintainers.calibrate.family import BEGIN, END, render

    path = CHECKS / "family.json"
    text = (
        render(json.loads(path.read_text()))
        if path.is_file()
        else "Not computed yet: run python -m maintainers calibrate family --write"
    )
    return f"{BEGIN}\n{text}\n{END}"


def held_out_block() -> str:
    """The held-out section (``maintainers/calibrate/held_out.py --write``), kept across rewrites."""
    from maintainers.calibrate.held_out import BEGIN, END, render

    path = CHECKS / "held_out.json"
    text = render(json.loads(path.read_text()) if path.is_file() else {})
    return f"## Held-out mutants\n\n{BEGIN}\n{text}\n{END}"


def sensitive_block() -> str:
    """The sensitive tier's section (``maintainers/calibrate/sensitive.py --write``), kept across rewrites."""
    from keras_rl.check.command import SENSITIVE_RATES
    from maintainers.calibrate.sensitive import BEGIN, END, HEADING, render

    text = (
        render(json.loads(SENSITIVE_RATES.read_text()))
        if SENSITIVE_RATES.is_file()
        else "Not computed yet: run python -m maintainers calibrate sensitive --write"
    )
    return f"{HEADING}\n\n{BEGIN}\n{text}\n{END}"


def real_block() -> str:
    """The sensitive tier on real runs (``maintainers/calibrate/real.py --write``), kept across rewrites."""
    from keras_rl.check.command import SENSITIVE_RATES
    from maintainers.calibrate.real import BEGIN, END, HEADING, OUT, render

    text = (
        render(json.loads(OUT.read_text()), json.loads(SENSITIVE_RATES.read_text()))
        if OUT.is_file() and SENSITIVE_RATES.is_file()
        else "Not computed yet: run python -m maintainers calibrate real --write"
    )
    return f"{HEADING}\n\n{BEGIN}\n{text}\n{END}\n"


def markdown(results: dict) -> str:
    lines = [
        "# Error rates of `keras-rl check`'s rules",
        "",
        "False alarms: the tier's n seeds drawn from the baseline and tested against its other seeds, "
        "10,000 times. Power: n seeds drawn with replacement from a mutant's runs (where a post's mutants "
        f"have 30, the rule is chosen on seeds {TUNE.start}-{TUNE.stop - 1} and its power reported on seeds "
        f"{REPORT.start}-{REPORT.stop - 1}, which the choice never saw), tested against the whole baseline, "
        "2,000 times. Delay: the smallest delay of every baseline curve (in episodes) "
        "the rule flags 80% of the time. These are one post's rates at its own alpha; the whole",
        "command's are in the next section.",
        "",
        "## The whole command",
        "",
        family_block(),
        "",
    ]
    for name, measured in results.items():
        lines += [f"Command for {name}: `{measured['command']}`", ""]
        split = measured.get("criterion_by_seeds")
        if split:
            lines += [
                f"The post's own criterion on the baseline ({split['criterion']}): seeds 0-9 "
                f"{split['0-9']}, seeds {split['rest_seeds']} {split['rest']} (Fisher p = {split['fisher_p']:.3g}).",
                "",
            ]
        for tier, entry in measured["tiers"].items():
            rule = RULES[(name, tier)]
            if "not_calibrated" in entry:
                lines += [f"## {name}, {tier} tier: not calibrated ({entry['not_calibrated']})", ""]
                if entry.get("false_alarm_rates"):
                    lines += [
                        "False alarms alone (power needs the mutants):",
                        "",
                        "| statistic | alpha | false alarms |",
                        "|---|---|---|",
                    ]
                    lines += [
                        f"| {r['statistic']}"
                        + (" **(rule)**" if (r["statistic"], r["alpha"]) == (rule.statistic, rule.alpha) else "")
                        + f" | {r['alpha']} | {r['false_alarm_rate']:.2%} |"
                        for r in entry["false_alarm_rates"]
                    ]
                    lines.append("")
                old = entry.get("old_k_of_n_test")
                if old:
                    lines += [
                        f"The old slow test ({old['test']}) fails on baseline seeds "
                        f"{old['false_alarm_rate']:.2%} of the time.",
                        "",
                    ]
                continue
            mutants = list(entry["mutant_seeds"])
            sizes = sorted(set(entry["mutant_seeds"].values()))
            lines += [
                f"## {name}, {tier} tier ({rule.seeds} fresh seeds, {rule.episodes} episodes)",
                "",
                f"Baseline: {entry['baseline_seeds']} seeds. Chosen on: {entry.get('chosen_on', 'every seed')} "
                f"of each mutant ({' or '.join(map(str, sizes))} runs).",
                "",
                "| statistic | alpha | false alarms | gross | all | " + " | ".join(mutants) + " |",
                "|---|---|---|---|---|" + "---|" * len(mutants),
            ]
            for r in entry["candidates"]:
                mark = " **(rule)**" if (r["statistic"], r["alpha"]) == (rule.statistic, rule.alpha) else ""
                lines.append(
                    f"| {r['statistic']}{mark} | {r['alpha']} | {r['false_alarm_rate']:.2%} | "
                    f"{r['power_gross']:.0%} | {r['power_all']:.0%} | "
                    + " | ".join(f"{r['power'][m]:.0%}" for m in mutants)
                    + " |"
                )
            old = entry.get("old_k_of_n_test")
            if old and "power" in old:
                lines.append(
                    f"| the old slow test: {old['test']} | - | {old['false_alarm_rate']:.2%} | "
                    f"{old['power_gross']:.0%} | {old['power_all']:.0%} | "
                    + " | ".join(f"{old['power'][m]:.0%}" for m in mutants)
                    + " |"
                )
            elif old:
                lines.append(
                    f"| the old slow test: {old['test']} | - | {old['false_alarm_rate']:.2%} | "
                    "(mutants too short) | | " + " | ".join("" for _ in mutants) + " |"
                )
            chosen = entry["chosen"]
            lines += [
                "",
                f"The criterion picks: {chosen['statistic']} at alpha {chosen['alpha']}"
                if chosen
                else "No candidate keeps false alarms at or below 1%.",
            ]
            if "detectable_delay_80" in entry:
                lines.append(f"Smallest delay detected 80% of the time: {delay_text(entry['detectable_delay_80'])}.")
            lines.append("")
            if "held_back" in entry:
                lines += held_back_table(entry["held_back"], rule)
    lines += [held_out_block(), "", sensitive_block(), "", real_block() + "\n" + twins_block() + "\n" + torch_block()]
    return "\n".join(lines)


def _rates_block(name: str) -> str:
    """A section that ``maintainers/calibrate/<name>.py --write`` splices, rendered from its JSON and
    kept across rewrites of the page."""
    from importlib import import_module

    from keras_rl.check import command

    module = import_module(f"maintainers.calibrate.{name}")
    rates: Path = command.TWIN_RATES if name == "twins" else command.TORCH_RATES
    text = (
        module.render(json.loads(rates.read_text()))
        if rates.is_file()
        else f"Not computed yet: run python -m maintainers calibrate {name} --write"
    )
    return f"{module.HEADING}\n\n{module.BEGIN}\n{text}\n{module.END}\n"


def twins_block() -> str:
    """The twin check's section (``maintainers/calibrate/twins.py --write``)."""
    return _rates_block("twins")


def torch_block() -> str:
    """The PyTorch check's section (``maintainers/calibrate/torch.py --write``)."""
    return _rates_block("torch")


def held_back_table(held: dict, rule) -> list[str]:
    """The rule's power on the mutants' held-back seeds, as the held-out block reports it."""
    lines = [
        f"The rule on each mutant's held-back seeds {held['seeds']} (never used to choose it): power at alpha "
        f"{rule.alpha} [seed bootstrap 95%], at alpha / 3, and the seeds as disjoint real checks of {rule.seeds} "
        f"[Clopper-Pearson 95%]. Gross: {held['power_gross']:.0%}; all: {held['power_all']:.0%}.",
        "",
        "| mutant | median: mutant / baseline | power at alpha [seed bootstrap 95%] | at alpha / 3 | disjoint checks |",
        "|---|---|---|---|---|",
    ]
    lines += ["| " + " | ".join([name, *power_cells(r)]) + " |" for name, r in held["mutants"].items()]
    return [*lines, ""]


RULES_BEGIN, RULES_END = "<!-- check-rules:begin -->", "<!-- check-rules:end -->"


def rules_table(merged: dict) -> str:
    """results/README.md's table of the rules and their measured error rates (from calibration.json)."""
    lines = [
        "| post | tier | rule: statistic, test, alpha | fresh seeds x episodes | false alarms | power: gross | "
        "power: all mutants | smallest delay flagged 80% |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (name, tier), rule in RULES.items():
        if tier not in CALIBRATED_TIERS:  # the sensitive tier: its own section of calibration.md
            continue
        entry = merged.get(name, {}).get("tiers", {}).get(tier)
        mine = (
            entry
            and "candidates" in entry
            and next(
                (c for c in entry["candidates"] if (c["statistic"], c["alpha"]) == (rule.statistic, rule.alpha)), None
            )
        )
        test = "Fisher" if rule.statistic == "success" else "Mann-Whitney U"
        head = f"| {name} | {tier} | {rule.statistic}, {test}, {rule.alpha} | {rule.seeds} x {rule.episodes} |"
        if not mine:
            alone = entry and next(
                (
                    c
                    for c in entry.get("false_alarm_rates", [])
                    if (c["statistic"], c["alpha"]) == (rule.statistic, rule.alpha)
                ),
                None,
            )
            lines.append(
                head
                + (
                    f" {alone['false_alarm_rate']:.2%} | no mutants yet | | |"
                    if alone
                    else " not calibrated yet | | | |"
                )
            )
            continue
        found = entry.get("detectable_delay_80")
        power_of = entry.get("held_back", mine)  # the held-back seeds' power, once the mutants have them
        held = f" (seeds {entry['held_back']['seeds']}, held back)" if "held_back" in entry else ""
        lines.append(
            head
            + f" {mine['false_alarm_rate']:.2%} | {power_of['power_gross']:.0%}{held} | {power_of['power_all']:.0%} | "
            + (delay_text(found) if found else "not measured")
            + " |"
        )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    unknown = sorted(set(args.experiments) - set(MUTANTS))
    if unknown:
        raise ConfigError(f"unknown post {', '.join(unknown)} (choose from {', '.join(sorted(MUTANTS))})")
    for name in args.experiments:
        for cmd in make_commands(name):
            print(("running: " if args.make else "missing; make it with: ") + " ".join(cmd), file=sys.stderr)
            if args.make:
                subprocess.run([sys.executable, "-m", "keras_rl", *cmd[1:]], cwd=ROOT, check=True)
                made = ROOT / cmd[-1]
                if made.parent.name == "mutants-seeds-10-29":
                    move_seeds(made, CHECKS / name / "mutants" / made.name)
        if not (CHECKS / name / "baseline").is_dir():
            return 2
    command = " ".join(
        ["python -m maintainers calibrate rules", *args.experiments, *(["--make"] if args.make else []), "--write"]
    )
    results = {
        name: {"command": command, "criterion_by_seeds": criterion_by_seeds(name), "tiers": calibrate(name)}
        for name in args.experiments
    }
    path = CALIBRATION
    merged = json.loads(path.read_text()) if path.is_file() else {}
    merged.update(results)
    text = markdown({k: merged[k] for k in sorted(merged)})
    print(text)
    if args.write:
        atomic_write_text(path, json.dumps(merged, indent=2) + "\n")
        atomic_write_text(CHECKS / "calibration.md", text)
        readme = ROOT / "results" / "README.md"
        atomic_write_text(readme, replace_block(readme.read_text(), RULES_BEGIN, RULES_END, rules_table(merged)))
    return 0
