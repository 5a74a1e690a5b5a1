"""Keras against PyTorch at the planned seeds (issue 35 item 1): which run sets make each arm,
and the reading once both arms hold the seeds the plan asked for.

The plan (``results/compare/seed_plan.md``, committed 2026-11-24 before the runs it governs,
``reproductions/seed_plan.py``) sets, per post and init, how many seeds each arm needs so
that the 90% interval fits the margins with 80% probability if the true difference is zero;
never fewer than 100. A comparison is read on seeds 0 to N-1 of both arms and on nothing
else, and not before both arms hold all of them: no peeking at a partial set, no stopping
when a reading happens to look good.

An arm is several committed run sets, because the long arms grew in steps, each step from a
clean worktree at one committed version (the first 30 seeds came from ``compare``). Where two
sets hold the same seed (the Keras arms' seeds 0-29 are also seeds 0-29 of the engine and
check baselines, the same runs bit for bit but wall time), the first set listed is read, and
the two must agree on the outcome, or the arm is refused.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.errors import RunFolderError
from keras_rl.runs.reuse import OUTCOMES
from maintainers.checkout import ROOT

RESULTS = ROOT / "results"
PLAN = RESULTS / "compare" / "seed_plan.json"

KERAS_ARMS = {
    "pendulum": ("pendulum/faithful", "engines/pendulum/gymnasium", "pendulum/faithful-seeds-100-149"),
    "cartpole": ("cartpole/faithful", "engines/cartpole/gymnasium", "cartpole/faithful-seeds-100-199"),
    "mountaincar": (
        "mountaincar/faithful",
        "checks/mountaincar/baseline",
        "mountaincar/faithful-seeds-100-199",
        "mountaincar/faithful-seeds-200-599",
    ),
}
"""Keras's arm of each post (the same arm for both inits: matched init changes PyTorch's side)."""

TORCH_ARMS = {
    ("pendulum", False): (
        "pendulum/faithful-torch",
        "pendulum/faithful-torch-seeds-30-149",  # seeds 30-89 (two processes: one core each)
        "pendulum/faithful-torch-seeds-90-149",  # seeds 90-139
        "pendulum/faithful-torch-seeds-140-149",
    ),
    ("pendulum", True): ("pendulum/faithful-torch-matched-init", "pendulum/faithful-torch-matched-init-seeds-30-99"),
    ("cartpole", False): (
        "cartpole/faithful-torch",
        "cartpole/faithful-torch-seeds-30-199",  # seeds 30-113, at 5d750908
        "cartpole/faithful-torch-seeds-114-199",  # at 56448599 (the compact checkpoint; the same arithmetic)
    ),
    ("cartpole", True): ("cartpole/faithful-torch-matched-init", "cartpole/faithful-torch-matched-init-seeds-30-199"),
    ("mountaincar", False): ("mountaincar/faithful-torch", "mountaincar/faithful-torch-seeds-30-199"),
    ("mountaincar", True): (
        "mountaincar/faithful-torch-matched-init",
        "mountaincar/faithful-torch-matched-init-seeds-30-199",  # seeds 30-114 (two processes: one core each)
        "mountaincar/faithful-torch-matched-init-seeds-115-199",
        "mountaincar/faithful-torch-matched-init-seeds-200-599",
    ),
}


@dataclass(frozen=True)
class Certification:
    post: str
    matched_init: bool
    planned: int
    """Seeds per arm, from the plan (seeds 0 to planned - 1)."""

    @property
    def keras(self) -> tuple[str, ...]:
        return KERAS_ARMS[self.post]

    @property
    def torch(self) -> tuple[str, ...]:
        return TORCH_ARMS[(self.post, self.matched_init)]

    @property
    def label(self) -> str:
        return f"{self.post}, {'matched' if self.matched_init else 'default'} init"


def certifications() -> list[Certification]:
    """One per post and init, in the plan's order, each with the plan's seeds per arm."""
    plan = json.loads(PLAN.read_text())
    return [Certification(p["post"], p["init"] == "matched", int(p["seeds_per_arm"])) for p in plan]


def arm(folders: tuple[str, ...], root: Path = RESULTS) -> dict[int, dict[str, Any]]:
    """Seed -> the ``summary.json`` of its finished run (completed, or stopped by a non-finite
    loss: ``runs.reuse.OUTCOMES``), over the run sets of one arm (a set not committed yet holds
    nothing). A seed held twice must have the same outcome in both sets."""
    return {seed: record for seed, (_, record) in arm_where(folders, root).items()}


def arm_where(folders: tuple[str, ...], root: Path = RESULTS) -> dict[int, tuple[str, dict[str, Any]]]:
    """``arm``, each seed with the folder it is read from (the first listed that holds it)."""
    from keras_rl.runs.run_set import RunSet

    seeds: dict[int, tuple[str, dict[str, Any]]] = {}
    for folder in folders:
        if not (root / folder).is_dir():
            continue
        for record in RunSet(root / folder).summary_records():
            if record.get("status") not in OUTCOMES:  # interrupted or failed: not yet what the seed does
                continue
            seed = int(record["seed"])
            if seed not in seeds:
                seeds[seed] = (folder, record)
                continue
            where, held = seeds[seed]
            if (held["success"], held["reached_at_episode"]) != (record["success"], record["reached_at_episode"]):
                raise RunFolderError(
                    f"seed {seed} is in {where} and {folder} with different outcomes "
                    f"({held['reached_at_episode']} and {record['reached_at_episode']}): not the same run, "
                    "so they cannot make one arm"
                )
    return seeds


def reading(c: Certification, root: Path = RESULTS) -> dict[str, Any]:
    """Both arms on seeds 0 to planned - 1: how many each holds so far and, once both hold all
    of them, the two readings (``report.equivalence.framework_verdict``)."""
    from keras_rl.report.equivalence import Arm, framework_verdict

    wanted = range(c.planned)
    keras, torch = arm(c.keras, root), arm(c.torch, root)
    held = [sum(s in keras for s in wanted), sum(s in torch for s in wanted)]
    out: dict[str, Any] = {"label": c.label, "planned": c.planned, "held": held, "pending": min(held) < c.planned}
    if out["pending"]:
        return out
    records = [[keras[s] for s in wanted], [torch[s] for s in wanted]]
    arms = [Arm.of(rs) for rs in records]
    budgets = {int(r["budget_episodes"]) for rs in records for r in rs}
    if len(budgets) != 1:
        raise RunFolderError(f"{c.label}: the arms' seeds ran different budgets ({sorted(budgets)})")
    headline, judged = framework_verdict(arms[0], arms[1], budgets.pop())
    out.update(headline=headline, successes=[a.successes for a in arms], arms=arms, judged=judged)
    return out
