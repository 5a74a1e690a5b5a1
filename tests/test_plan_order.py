"""Plans precede their runs (issue 52, item 2): every seed a committed plan governs started after
the commit that added the plan, or a disclosed deviation (``maintainers/plans.py``) names it."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from maintainers.plans import DEVIATIONS, PLANS, deviations_of, early_seeds, is_shallow, plan_time

ROOT = Path(__file__).resolve().parents[1]


def shallow() -> bool:
    return is_shallow(ROOT)


def _full_clone() -> None:
    if shallow():
        pytest.skip(
            "cannot run on a shallow clone: it reads each plan's commits; clone with history "
            "(git clone without --depth, or git fetch --unshallow)"
        )


@pytest.mark.parametrize("plan", PLANS, ids=[p.path + (f" ({p.section})" if p.section else "") for p in PLANS])
def test_every_seed_a_plan_governs_started_after_it_or_is_disclosed(plan):
    _full_clone()
    when = plan_time(plan, ROOT)
    assert when is not None, f"{plan.path} is not committed"
    disclosed = {
        (folder, seed) for d in DEVIATIONS if d.plan == plan.path for folder, seeds in d.early.items() for seed in seeds
    }
    undisclosed = {
        folder: [s for s in seeds if (folder, s) not in disclosed]
        for folder, seeds in early_seeds(plan, ROOT, when).items()
    }
    undisclosed = {f: s for f, s in undisclosed.items() if s}
    assert not undisclosed, (
        f"seeds started before {plan.path} was committed ({when}) and no deviation in maintainers/plans.py "
        f"discloses them: { {f: f'{min(s)}-{max(s)} ({len(s)})' for f, s in undisclosed.items()} }"
    )


def test_each_disclosed_deviation_is_real_and_names_rows_that_exist():
    """A deviation's early seeds did start before its plan (no stale disclosure), and every verdict
    it touches is a forest row."""
    import json

    rows = {f"{r['group']}: {r['label']}" for r in json.loads((ROOT / "results" / "forest.json").read_text())["rows"]}
    for d in DEVIATIONS:
        assert d.plan in {plan.path for plan in PLANS}
        for verdict in d.verdicts:
            assert verdict in rows, verdict
            assert d in deviations_of(verdict)
        if d.early and not shallow():
            plan = next(p for p in PLANS if p.path == d.plan)
            found = early_seeds(plan, ROOT)
            for folder, seeds in d.early.items():
                assert sorted(found.get(folder, [])) == list(seeds), (d.plan, folder)


def test_the_check_spots_a_seed_run_before_its_plan(tmp_path):
    """The rule itself, the product's (``maintainers/plans.early_seeds``), on a throwaway repository: a seed
    that started before the commit adding its plan is found, one after is not, a seed the plan does not
    govern is not read, and a later section governs from its own commit."""
    import json
    import os

    from maintainers.plans import Plan

    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    subprocess.run([*git, "init", "-q"], check=True)

    def commit(message: str, when: str) -> str:
        env = {**os.environ, "GIT_COMMITTER_DATE": when, "GIT_AUTHOR_DATE": when}
        subprocess.run([*git, "add", "-A"], check=True)
        subprocess.run([*git, "commit", "-qm", message], check=True, env=env)
        return subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout[:8]

    for seed, started in ((5, "2026-11-20T10:00:00+00:00"), (6, "2026-11-26T10:00:00+00:00")):
        folder = tmp_path / "results" / "engines" / f"seed_{seed}"
        folder.mkdir(parents=True)
        (folder / "summary.json").write_text(json.dumps({"seed": seed, "provenance": {"started_at": started}}))
    (tmp_path / "plan.md").write_text("the plan\n")
    commit("the plan", "2026-11-25T00:00:00+00:00")
    (tmp_path / "plan.md").write_text("the plan\n\n## a section\n")
    section = commit("a section", "2026-11-27T00:00:00+00:00")
    assert str(plan_time(Plan("plan.md", {}), tmp_path)) == "2026-11-25 00:00:00+00:00"
    assert early_seeds(Plan("plan.md", {"engines": None}), tmp_path) == {"engines": [5]}
    assert early_seeds(Plan("plan.md", {"engines": range(6, 7)}), tmp_path) == {}
    assert early_seeds(Plan("plan.md", {"engines": None}, "a section", section), tmp_path) == {"engines": [5, 6]}
    assert not is_shallow(tmp_path)


def test_each_deviation_is_printed_in_its_reports_and_marks_its_forest_rows():
    """Disclosed where its verdict is printed: each report it names carries its note, and the
    forest's table marks each row it touches with its number and lists it."""
    from maintainers.plans import mark, notes

    readme = (ROOT / "results" / "README.md").read_text()
    for d in DEVIATIONS:
        (note,) = notes([d])
        for report in d.reports:
            assert note in (ROOT / report).read_text(), (report, note)
        assert note in readme  # the forest's block lists it
        for verdict in d.verdicts:
            group, label = verdict.split(": ", 1)
            assert f"| {group} | {label}{mark(verdict)} |" in readme, verdict


def test_a_report_gets_the_section_of_the_deviations_it_touches_and_no_other():
    """``disclosed`` appends the section for a report a deviation names, after one blank line,
    and leaves any other report's text (or a report written outside the checkout) as it is."""
    from maintainers.plans import disclosed, notes, report_path

    (d,) = [d for d in DEVIATIONS if "results/engines/mountaincar/report.md" in d.reports]
    made = disclosed("# A report\n\nits lines\n\n", "results/engines/mountaincar/report.md")
    assert made == "# A report\n\nits lines\n\n## Deviations from the plan\n\n" + notes([d])[0] + "\n"
    assert disclosed("# A report\n", "results/engines/pendulum/report.md") == "# A report\n"
    assert disclosed("# A report\n", None) == "# A report\n"
    assert report_path(ROOT / "results" / "x" / ".." / "README.md") == "results/README.md"
    assert report_path(Path("/tmp/report.md")) is None and report_path(None) is None


@pytest.mark.parametrize("plan", PLANS, ids=[p.path + (f" ({p.section})" if p.section else "") for p in PLANS])
def test_a_planned_set_made_at_several_commits_is_disclosed_with_each(plan):
    """A set the plan governs whose seeds recorded more than one commit: a deviation of that plan
    names every one (†4 named two of the vectorised arm's three, issue 72 item 13)."""
    from maintainers.plans import code_versions

    texts = " ".join(d.text for d in DEVIATIONS if d.plan == plan.path)
    for folder, commits in code_versions(plan, ROOT).items():
        missing = sorted(c for c in commits if c not in texts)
        assert not missing, (
            f"{folder} holds seeds made at {sorted(commits)}; no deviation of {plan.path} names {missing}"
        )


@pytest.mark.parametrize("plan", PLANS, ids=[p.path + (f" ({p.section})" if p.section else "") for p in PLANS])
def test_an_edit_of_a_plan_while_its_runs_ran_is_disclosed(plan):
    """A commit that changed a plan between its first and last governed seed's start (other than the
    ones adding it or a section) is named by a deviation of that plan or in ``PLAN_EDITS`` (the
    tutorial-fix plan's two edits went undisclosed, issue 72 item 14)."""
    from maintainers.plans import PLAN_EDITS, edits_during_runs

    _full_clone()
    named = " ".join(
        [d.text for d in DEVIATIONS if d.plan == plan.path] + [e.commit for e in PLAN_EDITS if e.plan == plan.path]
    )
    missing = [c for c in edits_during_runs(plan, ROOT) if c not in named]
    assert not missing, f"{plan.path} was edited in {missing} while its runs ran, and nothing discloses it"


def test_the_edit_check_finds_an_edit_made_while_runs_ran(tmp_path):
    """The rule itself, on a throwaway repository: a plan edited between two seeds' starts is found;
    its adding commit is not."""
    import json
    import os

    from maintainers.plans import Plan, edits_during_runs

    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    subprocess.run([*git, "init", "-q"], check=True)
    plan_file = tmp_path / "plan.md"

    def commit(message: str, when: str) -> str:
        env = {**os.environ, "GIT_COMMITTER_DATE": when, "GIT_AUTHOR_DATE": when}
        subprocess.run([*git, "add", "-A"], check=True)
        subprocess.run([*git, "commit", "-qm", message], check=True, env=env)
        return subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout[:8]

    plan_file.write_text("the plan\n")
    commit("plan", "2026-11-20T10:00:00+00:00")
    for seed, started in ((0, "2026-11-20T11:00:00+00:00"), (1, "2026-11-20T13:00:00+00:00")):
        folder = tmp_path / "results" / "set" / f"seed_{seed}"
        folder.mkdir(parents=True)
        (folder / "summary.json").write_text(json.dumps({"seed": seed, "provenance": {"started_at": started}}))
    plan_file.write_text("the plan, edited\n")
    edit = commit("edit", "2026-11-20T12:00:00+00:00")
    assert edits_during_runs(Plan("plan.md", {"set": None}), tmp_path) == [edit]
