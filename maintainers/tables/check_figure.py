"""``docs/check-example.png``: what ``check.png`` shows at the sensitive tier, drawn by the check's
own plot from committed runs: post 000's baseline against 80 real unchanged seeds no baseline holds
(the first of the no-change pool, ``results/checks/pendulum/no-change``), read by the tier's rule.

    python -m maintainers tables check-figure            # draw it under /tmp and say where
    python -m maintainers tables check-figure --write    # docs/check-example.png
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from maintainers.checkout import ROOT

FIGURE = ROOT / "docs" / "check-example.png"
BASELINE = ROOT / "results" / "checks" / "pendulum" / "baseline"
FRESH = ROOT / "results" / "checks" / "pendulum" / "no-change" / "seeds-10000-10199"
COMMAND = "python -m maintainers tables check-figure --write"


def draw(path: Path) -> str:
    """The figure at ``path``; its verdict in words."""
    from keras_rl.check.command import CheckResult, _plot, _statistic, baseline_values, error_rates
    from keras_rl.check.rules import UNPAIRED_SENSITIVE
    from keras_rl.check.statistics import decide
    from keras_rl.registry import get_experiment
    from keras_rl.runs.run_set import RunSet

    experiment, rule = get_experiment("pendulum"), UNPAIRED_SENSITIVE["pendulum"]
    baseline, baseline_rows = baseline_values(experiment, rule, BASELINE)
    runs = RunSet(FRESH).runs()[: rule.seeds]
    new_rows = {run.seed: run.rows() for run in runs}
    new = {seed: _statistic(experiment, rule, rows) for seed, rows in new_rows.items()}
    decision = decide(list(baseline.values()), list(new.values()), rule.statistic, rule.alpha)
    result = CheckResult("pendulum", rule, baseline, new, decision, [], error_rates(rule))
    _plot(path, experiment, result, baseline_rows, new_rows)
    return f"{result.verdict}, p = {decision.p:.3g}, {len(new)} fresh seeds against {len(baseline)}"


def run(args: argparse.Namespace) -> int:
    if args.write:
        print(f"{draw(FIGURE)}: wrote {FIGURE}")
        return 0
    path = Path(tempfile.mkdtemp(prefix="check-figure-")) / "check.png"
    print(f"{draw(path)}: drew {path}")
    return 0
