"""The quirk ablations' seed plans (issue 52 item 5): the second look's rule, and what the forest
reads from the committed plans."""

from __future__ import annotations

import json
from importlib import import_module
from pathlib import Path

import pytest
from clitools import reproduction

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


def reading(text: str) -> dict:
    return {"estimate": 1.0, "low": 0.9, "high": 1.1, "reading": text}


@pytest.mark.parametrize(
    "success, speed, unsettled",
    [
        ("equivalent within the margin", "inconclusive", True),
        ("inconclusive", "inconclusive", True),
        ("equivalent within the margin", "equivalent within the margin", False),
        ("different", "inconclusive", False),
        ("inconclusive", "different", False),
    ],
)
def test_a_second_look_is_planned_only_where_the_first_settled_nothing(success, speed, unsettled):
    plan = reproduction("ablation_plan")
    row = {"pending": False, "success": reading(success), "speed": reading(speed)}
    assert plan.unsettled(row) is unsettled
    assert plan.unsettled({**row, "pending": True}) is False and plan.unsettled(None) is False


def test_the_second_look_runs_what_its_plan_says_under_a_registered_plan():
    """Its queue holds exactly the runs its JSON plans, each set governed by the committed plan
    (so the plan-order test compares their seeds' start with its commit), and the forest reads the
    ablation at the second look's seeds, its arms grown by those sets."""
    from maintainers.plans import PLANS

    second = json.loads((RESULTS / "ablation_plan_second.json").read_text())
    queue = (ROOT / "maintainers" / "queues" / "ablations-second.tsv").read_text().splitlines()
    runs = [line for line in queue if line and not line.startswith("#")]
    assert runs == [r for entry in second for r in entry["runs"]]
    governed = next(p.governs for p in PLANS if p.path == "results/ablation_plan_second.md")
    assert set(governed) == {r.split("\t")[0].removeprefix("results/") for r in runs}
    forest = import_module("maintainers.tables.forest")
    planned = {(post, switch): rest for post, switch, *rest in forest.planned_ablations()}
    for entry in second:
        first = json.loads((RESULTS / "ablation_plan.json").read_text())
        n = next(e["seeds_per_arm"] for e in first if (e["post"], e["switch"]) == (entry["post"], entry["switch"]))
        assert entry["first_seeds"] == n and entry["first_reading"]["speed"]["reading"] == "inconclusive"
        text, seeds, ablation_sets, faithful_sets = planned[(entry["post"], entry["switch"])]
        if entry["runs"]:
            assert (text, seeds) == (
                f"{entry['seeds_per_arm']} planned, a second look after {n}",
                entry["seeds_per_arm"],
            )
            grown = {r.split("\t")[0].removeprefix("results/") for r in entry["runs"]}
            assert grown <= set(ablation_sets) | set(faithful_sets)
            assert set(entry["ablation_sets"]) <= set(ablation_sets)


def merged(runs: list[str]) -> list[str]:
    """A queue's runs with each set that runs in parts (``<name>-seeds-A-B`` beside
    ``<name>-seeds-(B+1)-C``, the same arguments but ``--seeds``) joined back into one."""
    out: list[tuple[str, int, int, str]] = []
    for run in runs:
        folder, args = run.split("\t")
        name, _, span = folder.rpartition("-seeds-")
        first, last = (int(x) for x in span.split("-"))
        assert f"--seeds {first}-{last} " in args, run
        rest = args.replace(f"--seeds {first}-{last} ", "--seeds {} ")
        if out and out[-1][0] == name and out[-1][3] == rest and out[-1][2] + 1 == first:
            first = out.pop()[1]
        out.append((name, first, last, rest))
    return [f"{name}-seeds-{a}-{b}\t{rest.format(f'{a}-{b}')}" for name, a, b, rest in out]


def test_the_first_plans_queue_runs_its_sets_whole_or_in_parts_along_their_seeds():
    """The queue holds the runs the committed plan lists (its ``commands_of``), where a long set
    may run as consecutive sets of its seeds with the same arguments, each landing on its own."""
    plan = reproduction("ablation_plan")
    first = json.loads((RESULTS / "ablation_plan.json").read_text())
    queue = (ROOT / "maintainers" / "queues" / "ablations.tsv").read_text().splitlines()
    runs = [line for line in queue if line and not line.startswith("#")]
    assert merged(runs) == [c for entry in first for c in plan.commands_of(entry)]
    assert len(runs) > len(merged(runs))  # popping_buffer=false's 600 seeds run in parts
    assert merged(["f/x-seeds-0-9\treproduce p --seeds 0-9 --a", "f/x-seeds-11-19\treproduce p --seeds 11-19 --a"]) == [
        "f/x-seeds-0-9\treproduce p --seeds 0-9 --a",
        "f/x-seeds-11-19\treproduce p --seeds 11-19 --a",
    ]  # a gap is not joined


def test_a_committed_plan_is_never_rewritten_by_accident(monkeypatch, tmp_path):
    """Drawn again after its runs a plan reads other data (the second look now finds nothing
    unsettled), so ``--write`` refuses a plan that exists, and writes one that does not."""
    from keras_rl.errors import ConfigError

    plan = reproduction("ablation_plan")
    (tmp_path / "results").mkdir()
    (tmp_path / "maintainers" / "queues").mkdir(parents=True)
    monkeypatch.setattr(plan, "RESULTS", tmp_path / "results")
    monkeypatch.setattr(plan, "ROOT", tmp_path)
    plan.write("p", [{"n": 1}], "text\n", "q.tsv", "heading", ["a\tb"])
    assert (tmp_path / "maintainers" / "queues" / "q.tsv").read_text() == "# heading\na\tb\n"
    with pytest.raises(ConfigError, match="a plan is written once"):
        plan.write("p", [{"n": 2}], "other\n", "q.tsv", "heading", [])
    assert json.loads((tmp_path / "results" / "p.json").read_text()) == [{"n": 1}]
