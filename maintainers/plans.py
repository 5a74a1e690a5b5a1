"""Each committed plan, the run sets it governs, and every way the runs departed from it
(issue 52, item 2).

A plan is read as written when every seed it governs started after the plan was committed
(``summary.json``'s ``provenance.started_at`` against the commit that added the plan) and its
verdict is read once, at the seeds it planned. Seeds a plan names as made before it (a pilot it
was sized from, a committed set it reuses) are not governed. Everything else is a deviation, and
``DEVIATIONS`` discloses it: the reports print it beside the verdict it touches and the forest
marks the row; ``tests/test_plan_order.py`` fails on an earlier seed no deviation discloses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from keras_rl.runs.run_set import RunSet
from maintainers.certified import KERAS_ARMS, TORCH_ARMS


@dataclass(frozen=True)
class Plan:
    path: str
    """The plan, under the repository root."""
    governs: dict[str, range | None]
    """Run set under results/ -> the seeds the plan governs in it (None: every seed it holds)."""
    section: str = ""
    """A section added to the plan later, before its own runs: it governs from ``commit`` on."""
    commit: str | None = None
    """The commit whose time the seeds must follow (None: the one that added ``path``)."""


@dataclass(frozen=True)
class Deviation:
    plan: str
    """The plan departed from (``Plan.path``)."""
    text: str
    """The disclosure, one or two sentences, as the reports print it."""
    verdicts: tuple[str, ...]
    """The verdicts it touches, as the forest names their rows ("group: label")."""
    reports: tuple[str, ...] = ()
    """The reports (under the repository root) that print it beside the verdict."""
    early: dict[str, range] = field(default_factory=dict)
    """Run set -> its seeds that started before the plan was committed."""


@dataclass(frozen=True)
class PlanEdit:
    plan: str
    commit: str
    """The commit (8 hex digits) that edited the plan after some of its runs had started."""
    what: str
    """What it changed, and why no reading moved with it."""


PLAN_EDITS: tuple[PlanEdit, ...] = (
    PlanEdit(
        "results/checks/real_checks_plan.md",
        "b8529904",
        "corrected the time in the heading of its post 001 and post 003 section (05:55 was a slip for commit "
        "0b012ef9 at 05:48) while post 001's runs ran; no rule, size or reading changed",
    ),
)
"""Edits of a plan made after its runs began that touch no verdict's row (a deviation discloses
those that do, beside the verdict): each named, with what it changed."""


def governed_records(plan: Plan, root: Path) -> dict[str, list[dict]]:
    """Each set's summary records of the seeds ``plan`` governs (a set still to be run holds none)."""
    out: dict[str, list[dict]] = {}
    for folder, governed in plan.governs.items():
        where = root / "results" / folder
        if where.is_dir():
            out[folder] = [r for r in RunSet(where).summary_records() if governed is None or int(r["seed"]) in governed]
    return out


def _git(root: Path, *args: str) -> str | None:
    import subprocess

    done = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True)
    return done.stdout.strip() if done.returncode == 0 else None


def is_shallow(root: Path) -> bool:
    """Whether ``root`` is a shallow clone, which lacks the commits that added the plans."""
    return _git(root, "rev-parse", "--is-shallow-repository") == "true"


def plan_time(plan: Plan, root: Path):
    """When the plan (or its later section, ``plan.commit``) was committed: the seeds it governs must
    follow it. None where the clone lacks that commit."""
    from datetime import datetime

    if plan.commit is None:
        added = (_git(root, "log", "--diff-filter=A", "--format=%cI", "--", plan.path) or "").split()
        return datetime.fromisoformat(added[-1]) if added else None
    when = _git(root, "show", "-s", "--format=%cI", plan.commit)
    return datetime.fromisoformat(when) if when else None


def early_seeds(plan: Plan, root: Path, when=None) -> dict[str, list[int]]:
    """Each governed set's seeds that started before the plan was committed (or before ``when``)."""
    from datetime import datetime

    when = when or plan_time(plan, root)
    early: dict[str, list[int]] = {}
    for folder, records in governed_records(plan, root).items():
        for r in records:
            started = r.get("provenance", {}).get("started_at")
            if started and datetime.fromisoformat(started) < when:
                early.setdefault(folder, []).append(int(r["seed"]))
    return early


def code_versions(plan: Plan, root: Path) -> dict[str, dict[str, list[int]]]:
    """Set -> commit (8 hex digits) -> the governed seeds made at it, for each set made at more than one."""
    out: dict[str, dict[str, list[int]]] = {}
    for folder, records in governed_records(plan, root).items():
        commits: dict[str, list[int]] = {}
        for r in records:
            commits.setdefault(str(r.get("provenance", {}).get("commit"))[:8], []).append(int(r["seed"]))
        if len(commits) > 1:
            out[folder] = commits
    return out


def edits_during_runs(plan: Plan, root: Path) -> list[str]:
    """The commits (8 hex digits) that changed ``plan.path`` after the first seed it governs started and
    before the last did, other than the commits that add the plan or one of its sections (``PLANS``)."""
    import subprocess
    from datetime import datetime

    starts = [
        datetime.fromisoformat(r["provenance"]["started_at"])
        for records in governed_records(plan, root).values()
        for r in records
        if r.get("provenance", {}).get("started_at")
    ]
    if not starts:
        return []
    log = subprocess.run(
        ["git", "log", "--format=%H %cI", "--", plan.path], cwd=root, capture_output=True, text=True, check=True
    ).stdout.split("\n")
    added = subprocess.run(
        ["git", "log", "--diff-filter=A", "--format=%H", "--", plan.path], cwd=root, capture_output=True, text=True
    ).stdout.split()
    sections = {p.commit for p in PLANS if p.path == plan.path and p.commit} | set(added)
    out = []
    for line in filter(None, log):
        commit, when = line.split()
        if min(starts) < datetime.fromisoformat(when) <= max(starts) and not any(
            commit.startswith(s) for s in sections
        ):
            out.append(commit[:8])
    return out


def queued_sets(name: str = "*.tsv") -> list[str]:
    """The run sets (under ``results/``) that the committed queues of long runs make
    (``maintainers/queues/<name>``; every queue by default), in the queues' order."""
    from maintainers.checkout import ROOT

    return [
        line.split("\t")[0].removeprefix("results/")
        for path in sorted((ROOT / "maintainers" / "queues").glob(name))
        for line in path.read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]


def ablation_arms(
    switch: str, first: tuple[str, ...], second: tuple[str, ...], folders: list[str]
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """An ablation's two arms as a plan grows them: ``first`` (its pilot) and the ``folders``
    named ``<switch>-seeds-A-B``, against ``second`` (its base) and those named ``base-seeds-A-B``
    (the names ``reproductions/ablation_plan.py`` gives its runs)."""
    named = lambda prefix: tuple(f for f in folders if f.rpartition("/")[2].startswith(prefix))  # noqa: E731
    return first + named(f"{switch}-seeds-"), second + named("base-seeds-")


_PILOT = range(30, 10**6)
"""results/compare/seed_plan.md was sized from the 30-seed arms (seeds 0-29): it governs seeds 30 on."""

PLANS: tuple[Plan, ...] = (
    Plan(
        "results/compare/seed_plan.md",
        {folder: _PILOT for arms in (*KERAS_ARMS.values(), *TORCH_ARMS.values()) for folder in arms},
    ),
    Plan("results/engines/pendulum/plan.md", {"engines/pendulum/compiled": None, "engines/pendulum/gymnasium": None}),
    Plan("results/engines/cartpole/plan.md", {"engines/cartpole/compiled": None, "engines/cartpole/gymnasium": None}),
    Plan(
        "results/engines/mountaincar/plan.md",
        # the Gymnasium arm's seeds 0-99 are the committed check baseline, named by the plan as made before it
        {"engines/mountaincar/compiled": None, "mountaincar/faithful-seeds-100-199": None},
    ),
    Plan(
        "results/cartpole/tutorial-fix/plan.md",
        {
            f"cartpole/tutorial-fix/{arm}": None
            for arm in ("issue-3080", "issue-3080-torch", "pr-3384", "pr-3384-torch")
        },
    ),
    Plan(  # its addenda, each before its own runs: they govern from their own commits on
        "results/cartpole/tutorial-fix/plan.md",
        {"cartpole/tutorial-fix/pr-3384": None, "cartpole/tutorial-fix/pr-3384-torch": range(30)},
        section="PR #3384's values read, and its arms",
        commit="56448599",
    ),
    Plan(
        "results/cartpole/tutorial-fix/plan.md",
        {"cartpole/tutorial-fix/pr-3384-torch": range(30, 100)},
        section="PR #3384's PyTorch arm to 100 seeds",
        commit="2e611217",
    ),
    Plan("results/checks/sensitive_plan.md", {"checks/pendulum/baseline": range(100, 200)}),
    # sized from the compiled engine's first 100 seeds of post 003, which it names
    Plan("results/checks/sensitive_plan_cartpole.md", {"checks/cartpole/baseline": range(100, 200)}),
    Plan(
        "results/checks/real_checks_plan.md",
        {
            "checks/pendulum/no-change/seeds-10000-10199": None,
            "checks/pendulum/no-change/seeds-10200-10399": None,
            "checks/pendulum/no-change/seeds-10400-10599": None,
            "checks/pendulum/no-change/seeds-10600-10799": None,
            "checks/pendulum/no-change/seeds-10800-10999": None,
            "checks/pendulum/held-out-seeds-3200-3499/noise_sigma_x2": None,
            "checks/pendulum/held-out-seeds-3200-3499/batch_32": None,
        },
    ),
    Plan(
        "results/checks/real_checks_plan.md",
        {
            "checks/mountaincar/no-change/seeds-20000-20199": None,
            **{
                f"checks/mountaincar/held-out-seeds-30-109/{m}": None
                for m in ("actor_lr_x3", "train_start_x2", "batch_64", "input_noise_x0.5")
            },
        },
        section="Post 001 and post 003",
        commit="0b012ef9",
    ),
    Plan(
        "results/checks/real_checks_plan.md",
        {folder: None for folder in queued_sets("issue52-post003.tsv")},
        section="Post 003",
        commit="5cc6d9d3",
    ),
    Plan("results/cartpole/vectorised-torch/plan.md", {"cartpole/vectorised-torch/seeds-0-199": None}),
    Plan(  # issue 53 item 5: the proposals on the vectorised engine, once it is certified
        "results/cartpole/tutorial-fix/plan.md",
        {folder: None for folder in queued_sets("tutorial-fix-vectorised.tsv")},
        section="the three PyTorch arms on 100 seeds of the vectorised engine",
        commit="3458f801",
    ),
    Plan(  # issue 52 item 5: the runs that settle the inconclusive quirk ablations
        "results/ablation_plan.md",
        {folder: None for folder in queued_sets("ablations.tsv")},
    ),
    Plan(  # its second look, at an ablation its planned seeds left unsettled
        "results/ablation_plan_second.md",
        {folder: None for folder in queued_sets("ablations-second.tsv")},
    ),
)

DEVIATIONS: tuple[Deviation, ...] = (
    Deviation(
        "results/compare/seed_plan.md",
        "The Keras arm's seeds 30-99 of post 001 are the check's baseline (`results/checks/mountaincar/baseline`), "
        "run 2026-11-22 to 11-24, before this plan was committed (11-24 23:08), when 68/100 successes had been "
        "published: they were not run to the plan.",
        (
            "Keras vs PyTorch, the planned seeds: mountaincar, default init (200 planned)",
            "Keras vs PyTorch, the planned seeds: mountaincar, matched init (600 planned)",
        ),
        ("results/README.md", "results/compare/mountaincar/cause.md"),  # cause.md reads this arm at 200 seeds
        {"checks/mountaincar/baseline": range(30, 100)},
    ),
    Deviation(
        "results/engines/mountaincar/plan.md",
        "45 of the Gymnasium arm's seeds 100-199 (100-144, from `results/mountaincar/faithful-seeds-100-199`, "
        "made for the Keras-against-PyTorch arm) started before this plan was committed (first at 18:47, "
        "the plan at 19:04 on 2026-11-25).",
        ("compiled engine vs Gymnasium loop: mountaincar",),
        ("results/engines/mountaincar/report.md",),
        {"mountaincar/faithful-seeds-100-199": range(100, 145)},
    ),
    Deviation(
        "results/compare/seed_plan.md",
        "`results/compare/mountaincar/cause.md` reads post 001 with matched init at 200 of the 600 seeds per arm "
        "the plan set: an interim look the plan does not provide for (`keras_rl/report/certified.py` takes none). "
        "The verdict stands at 600 seeds; the 200-seed reading is reported as the cause experiment only.",
        ("Keras vs PyTorch, the planned seeds: mountaincar, matched init (600 planned)",),
        ("results/compare/mountaincar/cause.md", "results/README.md"),
    ),
    Deviation(
        "results/cartpole/vectorised-torch/plan.md",
        "The arm holds three code versions, as its seeds' recorded commits show. 13 seeds (1, 2, 4, 5, 7-12, 14, "
        "15 and 44) were made at 6678043e, before 4942498a changed `train/vectorised.py` (a batch sheds each "
        "finished seed; its tests found the certification's S=8 program's bits unchanged). 147 were made at "
        "8e5c4029. 40 (0, 3, 6, 13, 16-43, 45-47, 192, 193, 195, 197 and 199) stopped with an error at 8e5c4029, "
        "when a pool worker passed torch's recompile limit (`FailOnRecompileLimitHit`); they were run again from "
        "their first episode at 2f5f8cf7, which fixes that and changes no bits: seeds 48-55 run whole at 2f5f8cf7 "
        "equal their rows made at 8e5c4029 in every column but wall time (the plan's addendum gives the commands).",
        (
            "vectorised PyTorch engine vs the tutorial's own code: cartpole",
            # the proposals on the vectorised engine are read against this arm's seeds 0-99
            *(
                f"the tutorial's community fix vs as published: cartpole, pytorch/tutorials {values} values "
                "(PyTorch, the vectorised engine)"
                for values in ("#3080's", "PR #3384's")
            ),
        ),
        (
            "results/cartpole/vectorised-torch/report.md",
            "results/cartpole/tutorial-fix/report-issue-3080-vectorised.md",
            "results/cartpole/tutorial-fix/report-pr-3384-vectorised.md",
        ),
    ),
    Deviation(
        "results/cartpole/tutorial-fix/plan.md",
        "The plan's addendum for PR #3384's PyTorch arm to 100 seeds was edited twice while its seeds 30-99 ran "
        "(2026-11-26 14:50 to 18:25): 533b38b3 (15:37) changed when the arm lands (in one piece at seeds 0-99, "
        "not as it goes) and 5beaa16c (15:55) the expected precision, drawn from a committed command. Neither "
        "edit changed the arm's seeds, its reading or its margin.",
        (
            "the tutorial's community fix vs as published: cartpole, pytorch/tutorials PR #3384's values "
            "(the tutorial's PyTorch code), second look",
        ),
    ),
    Deviation(
        "results/ablation_plan.md",
        "The plan ran `popping_buffer=false`'s 600 seeds as one set; it was run as twelve sets of 50, the same "
        "seeds and arguments, after 189 seeds of the one set were lost with a session's worktree "
        "(`maintainers/queues/ablations.tsv`). Every one of the 600 planned seeds is in the verdict.",
        ("mountaincar ablation vs faithful, the planned seeds: popping_buffer=false (600 planned)",),
    ),
)


def deviations_of(verdict: str) -> list[Deviation]:
    """The deviations that touch a verdict (a forest row, "group: label")."""
    return [d for d in DEVIATIONS if verdict in d.verdicts]


def deviations_reading(folders: list[str]) -> list[Deviation]:
    """The deviations whose early seeds lie in any of these run sets (what a report reads)."""
    wanted = set(folders)
    return [d for d in DEVIATIONS if wanted & set(d.early)]


def number(deviation: Deviation) -> int:
    """Its mark's number: its place in ``DEVIATIONS``, from 1."""
    return DEVIATIONS.index(deviation) + 1


def mark(verdict: str) -> str:
    """The marks a verdict's row carries (" †1 †3"), or ""."""
    return "".join(f" †{number(d)}" for d in deviations_of(verdict))


def notes(deviations: list[Deviation]) -> list[str]:
    """One line per deviation, as the reports and the forest print them."""
    return [f"- †{number(d)} (`{d.plan}`): {d.text}" for d in deviations]


def disclosure(report: str) -> str:
    """The section a report prints about the deviations it touches ("" if none): ``report`` is its
    path under the repository root."""
    touching = [d for d in DEVIATIONS if report in d.reports]
    if not touching:
        return ""
    return "\n".join(["## Deviations from the plan", "", *notes(touching), ""])


def report_path(written: Path | None) -> str | None:
    """A report's path under the repository root, as ``Deviation.reports`` names it (None for no
    file, or a file outside the checkout)."""
    from maintainers.checkout import ROOT

    if written is None or not written.resolve().is_relative_to(ROOT):
        return None
    return written.resolve().relative_to(ROOT).as_posix()


def disclosed(text: str, report: str | None) -> str:
    """A report's ``text`` with ``disclosure(report)`` after it, one blank line between (``text``
    as it is if the report touches no deviation)."""
    section = disclosure(report) if report else ""
    return text.rstrip("\n") + "\n\n" + section if section else text
