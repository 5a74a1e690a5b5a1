"""What the check's calibration scripts share: committed runs read back, each run's statistic,
and the power report of a rule against a set of changed runs.

``rules.py``, ``held_out.py``, ``designs.py`` and ``sensitive.py`` (``python -m maintainers calibrate``)
import from here (and from nothing of each other's but the blocks they render), so there is one
reader of the runs, one power report and one candidate choice (``choose``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.check.rules import ALPHAS, CALIBRATED_TIERS, RULES, UNPAIRED_SENSITIVE
from keras_rl.check.statistics import decide, false_alarm_rate, power, seed_statistic
from keras_rl.registry import get_experiment
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT

CHECKS = ROOT / "results" / "checks"
HOLM_LEVEL = 3
"""Posts in the default command: a change to one post must clear alpha / 3 (Holm's first level)."""
TUNE, REPORT = range(0, 15), range(15, 30)
"""Issue #21, item 4: once every mutant of a post has 30 runs, seeds 0-14 choose (the rule in
``calibrate/rules.py``, the futility bound in ``calibrate/designs.py``) and seeds 15-29, never
looked at in those choices, report the power."""


def seed_dirs(folder: Path) -> list[Path]:
    """The live ``seed_<n>/`` folders of ``folder`` (what ``--make`` moves)."""
    return RunSet(folder).seed_dirs()


def seed_count(folder: Path) -> int:
    """The seeds ``folder`` holds, in folders or packed."""
    return len(RunSet(folder).runs())


def budget(folder: Path) -> int:
    """The episode budget the runs in ``folder`` were made with (the smallest, if they differ)."""
    return min(config["episodes"] for config in RunSet(folder).configs())


def load(folder: Path, seeds: range | None = None) -> list[list[dict] | None]:
    """Each run's episode rows, in seed order (``None`` for a run that blew up); only
    ``seeds`` if given, and then every one of them must be there."""
    runs = RunSet(folder).runs()
    if seeds is not None:
        have = {r.seed: r for r in runs}
        missing = [s for s in seeds if s not in have]
        if missing:
            raise SystemExit(f"error: {folder} has no seed_{missing[0]} ({len(missing)} of seeds {seeds} missing)")
        runs = [have[s] for s in seeds]
    out = []
    for run in runs:
        summary = run.summary()
        if summary.status not in ("completed", "non_finite_loss"):
            raise SystemExit(f"error: {run.where} did not finish ({summary.status})")
        out.append(run.rows() if summary.status == "completed" else None)
    if not out:
        raise SystemExit(f"error: no runs under {folder}")
    return out


def values(name: str, statistic: str, episodes: int, runs: list, delay: int = 0) -> np.ndarray:
    """Each run's statistic (NaN for a run that blew up), its curve optionally ``delay`` episodes late."""
    experiment = get_experiment(name)
    config = experiment.config_cls.for_variant("faithful")
    metric = experiment.make_metric(config)

    def one(rows):
        if rows is None:
            return float("nan")
        rows = [rows[0]] * delay + rows if delay else rows
        return seed_statistic(
            statistic, rows, episodes, lambda m: metric.passes(m, config.threshold), experiment.success_at_end
        )

    return np.asarray([one(r) for r in runs], float)


def halved(folders: list[Path]) -> bool:
    """Whether every mutant folder holds the 30 runs the tuning and reporting halves need."""
    return all(seed_count(f) >= len(TUNE) + len(REPORT) for f in folders)


def splice_calibration(heading: str, begin: str, end: str, text: str) -> Path:
    """``text`` between ``begin`` and ``end`` in ``results/checks/calibration.md``; a block the page
    lacks is added at its end, under ``heading``. Returns the page."""
    from keras_rl.atomic import atomic_write_text
    from maintainers.markdown import replace_block

    page = CHECKS / "calibration.md"
    current = page.read_text()
    if begin not in current:
        current = current.rstrip("\n") + f"\n\n{heading}\n\n{begin}\n{end}\n"
    atomic_write_text(page, replace_block(current, begin, end, text))
    return page


def clopper_pearson(k: int, n: int) -> tuple[float, float]:
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return float(ci.low), float(ci.high)


def measure(post: str, tier: str, baseline: np.ndarray, runs: np.ndarray) -> dict:
    """A tier's rule, as the check runs it, against one set of changed runs (``baseline`` and
    ``runs``: each seed's statistic): power at alpha and at alpha / 3 (n seeds drawn with
    replacement, 2,000 times), the runs cut into disjoint real checks with their exact
    (Clopper-Pearson) 95% interval, a seed bootstrap of the power, and both medians."""
    rule = UNPAIRED_SENSITIVE[post] if tier == "sensitive" else RULES[(post, tier)]
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


def power_cells(r: dict) -> list[str]:
    """A ``measure`` result as table cells: the medians, power at alpha [seed bootstrap 95%],
    at alpha / 3, and the disjoint checks flagged [Clopper-Pearson 95%]."""
    med = "-" if r["median_mutant"] is None else f"{r['median_mutant']:.4g}"
    d = r["disjoint"]
    return [
        f"{med} / {r['median_baseline']:.4g}",
        f"{r['power_alpha']:.0%} [{r['bootstrap95'][0]:.0%}, {r['bootstrap95'][1]:.0%}]",
        f"{r['power_holm_first']:.0%}",
        f"{d['flagged']}/{d['checks']} [{d['ci95'][0]:.0%}, {d['ci95'][1]:.0%}]" if d else "none (n > seeds)",
    ]


def choose(name: str, rule, baseline: list, mutants: dict) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """The pre-registered criterion on one rule's candidates: each statistic at each alpha of
    ``ALPHAS``, its false-alarm rate on the baseline and its power against each mutant's runs
    (``mutants``: name -> (Mutant, runs)); chosen, among those with false alarms at most 1%,
    the most power against the gross mutants, then against all, then the first listed."""
    rows: list[dict[str, Any]] = []
    for statistic in rule.candidates:
        base = values(name, statistic, rule.episodes, baseline)
        for alpha in ALPHAS:
            per_mutant = {
                m.name: power(base, values(name, statistic, rule.episodes, runs), rule.seeds, statistic, alpha)
                for m, runs in mutants.values()
            }
            gross = [per_mutant[m.name] for m, _ in mutants.values() if m.gross]
            rows.append(
                {
                    "statistic": statistic,
                    "alpha": alpha,
                    "seeds": rule.seeds,
                    "episodes": rule.episodes,
                    "false_alarm_rate": false_alarm_rate(base, rule.seeds, statistic, alpha),
                    "power": per_mutant,
                    "power_gross": float(np.mean(gross)),
                    "power_all": float(np.mean(list(per_mutant.values()))),
                }
            )
    eligible = [r for r in rows if r["false_alarm_rate"] <= 0.01]
    chosen = max(eligible, key=lambda r: (r["power_gross"], r["power_all"], -rows.index(r))) if eligible else None
    return rows, chosen


def engine_args(name: str, batch: int | str) -> list[str]:
    """How a post's check runs are made: on its rules' engine, named (``--engine auto`` would pick
    the compiled engine for a Keras post); batched ``batch`` on the Gymnasium loop."""
    engine = RULES[(name, CALIBRATED_TIERS[0])].engine
    if engine != "gymnasium":
        return ["--engine", engine]
    return ["--engine", "gymnasium", *(["--seed-batch", str(batch)] if batch != 1 else [])]


def shifted(episodes: np.ndarray, shift: float, budget: int) -> np.ndarray:
    """Episodes to threshold times ``shift``, rounded, censored at ``budget + 1`` (never got
    there); a seed that never got there stays so: the change a power figure is measured against."""
    return np.where(episodes > budget, budget + 1, np.minimum(np.round(episodes * shift), budget + 1))
