"""Every verdict drawn: one forest plot of every two-arm comparison the project commits.

    python -m maintainers tables forest            # print the table
    python -m maintainers tables forest --write    # results/forest.png (and docs/forest.png), results/forest.json,
                                      # and the blocks of results/README.md and docs/findings.md

Each row is a comparison of two arms on the seeds both hold, judged on the two margins set on
2026-11-23 before the runs (``report/equivalence.framework_verdict``, the function ``compare``
and ``reproductions/seed_batch_compare.py`` call): the difference of success rates (first arm
minus second) within ±0.15, and the ratio of median episodes to threshold (first over second;
a seed that never reached the threshold counts as the budget + 1) within 0.9 to 1.1. Each
shows its estimate, its 90% interval (TOST), the margin band, and its reading: equivalent
within the margin, different, or inconclusive at its number of seeds.

The rows: Keras against PyTorch, default and matched init (the committed ``compare`` results,
``results/compare/<post>/[matched-init/]result.json``, 30 seeds) and again at the seeds the plan
asked for (``maintainers.certified``: pending until both arms hold them); the compiled engine against the
Gymnasium loop; the vectorised PyTorch engine against the tutorial's own code; the tutorial's
community fix (pytorch/tutorials #3080) against the tutorial as published; seed-batched against solo
runs; and each post's ablations, every quirk switched off alone against the faithful base. A
comparison whose plan sets a number of seeds before its reading (``COMPARISONS``'
``seeds_before_reading``) is listed as pending, and not drawn, until both arms hold that many.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING
from maintainers import plans
from maintainers.checkout import ROOT

RESULTS = ROOT / "results"
ENGINE_GROUP = "compiled engine vs Gymnasium loop"
FIGURE = RESULTS / "forest.png"
DOCS_FIGURE = ROOT / "docs" / "forest.png"
"""The same figure beside ``docs/findings.md`` (the docs site takes no link out of ``docs/``)."""
DATA = RESULTS / "forest.json"
COMMAND = "python -m maintainers tables forest --write"
PAGES = (RESULTS / "README.md", ROOT / "docs" / "findings.md")
BEGIN, END = "<!-- forest:begin -->", "<!-- forest:end -->"


@dataclass(frozen=True)
class Comparison:
    group: str
    label: str
    first: str | tuple[str, ...] = ""
    """The first arm's run-set folder (under ``results/``), or its folders where it grew in steps
    (``maintainers.certified.arm``); or ``compare``'s result.json below."""
    second: str | tuple[str, ...] = ""
    result: str | None = None
    """A committed ``compare`` result (``results/compare/...``), which holds both arms."""
    seeds_before_reading: int = 0
    first_seeds_only: bool = False
    """Read on seeds 0 to ``seeds_before_reading`` - 1 of both arms and on no other (a planned
    reading at that many seeds, where an arm holds more), pending until both hold all of them."""
    certified: Any = None
    """A Keras-against-PyTorch comparison at its planned seeds (``maintainers.certified``)."""


def _comparisons() -> list[Comparison]:
    from maintainers.certified import TORCH_ARMS, certifications
    from maintainers.tutorial_fix import FRAMEWORKS, PUBLISHED, TUTORIAL_FIXES

    out = []
    for post in ("pendulum", "cartpole", "mountaincar"):
        out.append(Comparison("Keras vs PyTorch", post, result=f"compare/{post}/result.json"))
        out.append(
            Comparison("Keras vs PyTorch, matched init", post, result=f"compare/{post}/matched-init/result.json")
        )
    for c in certifications():
        out.append(Comparison("Keras vs PyTorch, the planned seeds", f"{c.label} ({c.planned} planned)", certified=c))
    for post, seeds in (("pendulum", 100), ("cartpole", 100)):
        out.append(
            Comparison(
                ENGINE_GROUP,
                post,
                f"engines/{post}/compiled",
                f"engines/{post}/gymnasium",
                seeds_before_reading=seeds,
            )
        )
    # results/engines/mountaincar/plan.md planned a reading at 100 seeds and another at 200; by the plan's
    # reading (episodes to threshold since issue 52) the engines were equivalent at 100 already, and the
    # row reads the 200 as planned
    out.append(
        Comparison(
            ENGINE_GROUP,
            "mountaincar",
            "engines/mountaincar/compiled",
            ("checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199"),
            seeds_before_reading=200,
        )
    )
    out.append(  # results/cartpole/vectorised-torch/plan.md (issue 53): independent arms, read at 200 seeds
        Comparison(
            "vectorised PyTorch engine vs the tutorial's own code",
            "cartpole",
            "cartpole/vectorised-torch/seeds-0-199",
            TORCH_ARMS[("cartpole", False)],  # the tutorial's own code, seeds 0-199
            seeds_before_reading=200,
        )
    )
    # results/cartpole/tutorial-fix/plan.md's last addendum: the engine on a config it was not certified on,
    # PR #3384's values, against the same values in the tutorial's own code, seeds 0-99 of both
    pr = next(fix for fix in TUTORIAL_FIXES if fix.variant == "pr-3384")
    out.append(
        Comparison(
            "vectorised PyTorch engine vs the tutorial's own code",
            f"cartpole, {pr.upstream}",
            pr.folder("vectorised"),
            pr.folder("torch"),
            seeds_before_reading=100,
            first_seeds_only=True,
        )
    )
    for fix in TUTORIAL_FIXES:  # results/cartpole/tutorial-fix/plan.md (and its addenda)
        for fw in FRAMEWORKS:
            for seeds in fix.readings(fw):
                out.append(
                    Comparison(
                        "the tutorial's community fix vs as published",
                        fix.label(fw, seeds),
                        fix.folder(fw),
                        PUBLISHED[fw],
                        seeds_before_reading=seeds,
                        first_seeds_only=True,
                    )
                )
    for label, batched, solo in (
        ("pendulum (PyTorch), batch of 10", "pendulum/seed-batch-torch/batch10", "pendulum/faithful-torch"),
        ("mountaincar, batch of 10", "mountaincar/seed-batch/batch10", "mountaincar/faithful"),
    ):
        out.append(Comparison("seed-batched vs solo", label, batched, solo))
    from maintainers.tables.ablations import SOURCES

    planned = planned_ablations()
    grown = {folder for *_, first, second in planned for folder in first + second}
    for post, source in SOURCES.items():
        points, base = source["points"].removeprefix("results/"), source["base"].removeprefix("results/")
        for point in sorted(p.name for p in (RESULTS / points).iterdir() if p.is_dir() and p.name != "base"):
            if f"{points}/{point}" in grown and point.rpartition("-seeds-")[1]:
                continue  # a set the ablation plan grew an arm by: read in the planned row below
            out.append(Comparison(f"{post} ablation vs faithful", point, f"{points}/{point}", base))
    for post, switch, planned_text, n, first, second in planned:
        out.append(
            Comparison(
                f"{post} ablation vs faithful, the planned seeds",
                f"{switch} ({planned_text})",
                first,
                second,
                seeds_before_reading=n,
                first_seeds_only=True,
            )
        )
    return out


def planned_ablations() -> list[tuple[str, str, str, int, tuple[str, ...], tuple[str, ...]]]:
    """Each quirk ablation ``results/ablation_plan.json`` runs: (post, switch, the planned seeds in
    words, seeds per arm, the ablation arm's sets, the faithful arm's sets), the arms grown by the
    sets of its queue
    (``maintainers/queues/ablations.tsv``, named ``<switch>-seeds-A-B`` and ``base-seeds-A-B``
    beside the pilot on the plan's engine). Read at the planned seeds, pending until both arms
    hold them all."""
    import json

    from maintainers.plans import queued_sets

    path = RESULTS / "ablation_plan.json"
    queued = queued_sets("ablations.tsv")
    out = []
    for entry in json.loads(path.read_text()) if path.is_file() else []:
        post, switch, n, engine = entry["post"], entry["switch"], entry["seeds_per_arm"], entry["engine"]
        grown = [q for q in queued if q.startswith(f"{post}/ablations-{engine}/")]
        pilot = (entry["pilot"],) if entry["pilot_engine"] == engine else ()
        first, second = plans.ablation_arms(switch, pilot, tuple(entry["base"].split(",")), grown)
        if first == pilot:
            continue  # the plan runs nothing for it: it stays as the plan says
        out.append((post, switch, int(n), first, second))
    return [second_look(*planned) for planned in out]


def second_look(post: str, switch: str, n: int, first: tuple[str, ...], second: tuple[str, ...]):
    """A planned ablation as ``results/ablation_plan_second.json`` plans its second look, where it
    plans one: read at the second look's seeds, each arm grown by the sets of its queue
    (``maintainers/queues/ablations-second.tsv``), the label saying so; else as it was."""
    import json

    path = RESULTS / "ablation_plan_second.json"
    for entry in json.loads(path.read_text()) if path.is_file() else []:
        if (entry["post"], entry["switch"]) == (post, switch) and entry["runs"]:
            sets = [line.split("\t")[0].removeprefix("results/") for line in entry["runs"]]
            label = f"{entry['seeds_per_arm']} planned, a second look after {n}"
            return post, switch, label, int(entry["seeds_per_arm"]), *plans.ablation_arms(switch, first, second, sets)
    return post, switch, f"{n} planned", n, first, second


def _arm(folders: str | tuple[str, ...]) -> dict[int, dict[str, Any]]:
    """Seed -> its summary, for the run set(s) under ``results/``."""
    from maintainers.certified import arm

    return arm((folders,) if isinstance(folders, str) else folders, RESULTS)


def row(c: Comparison) -> dict[str, Any]:
    """One comparison's numbers and readings (or why it is pending)."""
    from keras_rl.report.compare import arm
    from keras_rl.report.equivalence import Arm, framework_verdict
    from maintainers.certified import reading

    if c.certified is not None:
        read = reading(c.certified)
        held = read["held"]
        if read["pending"]:
            return {
                "group": c.group,
                "label": c.label,
                "source": ", ".join(c.certified.keras + c.certified.torch),
                "seeds": f"Keras {held[0]}, PyTorch {held[1]} of {read['planned']}",
                "pending": True,
            }
        return _judged(c, ", ".join(c.certified.keras + c.certified.torch), read["planned"], read["judged"])
    if c.result is not None:
        result = json.loads((RESULTS / c.result).read_text())
        arms = [arm(result["frameworks"][fw]) for fw in ("keras", "torch")]
        budget = int(result["budget"])
        source = c.result
    else:
        first, second = _arm(c.first), _arm(c.second)
        common = sorted(set(first) & set(second))
        if c.first_seeds_only:
            common = [s for s in common if s < c.seeds_before_reading]
        n = len(common)
        source = " and ".join(x if isinstance(x, str) else " + ".join(x) for x in (c.first, c.second))
        if n < max(c.seeds_before_reading, 1):
            return {"group": c.group, "label": c.label, "source": source, "seeds": n, "pending": True}
        arms = [Arm.of(first[s] for s in common), Arm.of(second[s] for s in common)]
        budget = int(second[common[0]]["budget_episodes"])
    _, judged = framework_verdict(arms[0], arms[1], budget)
    seeds = [a.seeds for a in arms]
    return _judged(c, source, seeds[0] if seeds[0] == seeds[1] else seeds, judged)


def _judged(c: Comparison, source: str, seeds: Any, judged: list) -> dict[str, Any]:
    success, speed = judged
    return {
        "group": c.group,
        "label": c.label,
        "source": source,
        "seeds": seeds,
        "pending": False,
        **{name: _point(e) for name, e in (("success", success), ("speed", speed))},
        # the code's reading before issue 52 (report.equivalence.CONVERGED_AT_END), where it differs
        **({"speed_converged_at_end": _point(speed.beside)} if speed.beside is not None else {}),
    }


def _point(e) -> dict[str, Any]:
    return {
        "estimate": _num(e.estimate),
        "low": _num(e.tost.low),
        "high": _num(e.tost.high),
        "margin": list(e.margin),
        "reading": e.reading,
    }


def _num(x: float) -> float | None:
    return round(float(x), 4) if np.isfinite(x) else None


def rows() -> list[dict[str, Any]]:
    return [row(c) for c in _comparisons()]


READ = {"equivalent within the margin": "equivalent", "different": "**different**", "inconclusive": "inconclusive"}


DEGENERATE = (
    "; no width: both medians are whole episodes and tie in most resamples, so the interval cannot show "
    "the ratio's step, one episode in a median of m (x1/m: x0.067 at post 001's median of about 15)"
)
"""What a ratio's interval of no width says (issue 72 item 11): not a precision the data have."""


def _cell(v: dict[str, Any]) -> str:
    if v["estimate"] is None:
        return f"no estimate: {READ[v['reading']]}"
    width = DEGENERATE if v["low"] == v["high"] else ""
    return f"{v['estimate']:.3g} ({v['low']:.3g} to {v['high']:.3g}{width}): {READ[v['reading']]}"


def table(data: list[dict[str, Any]]) -> str:
    lines = [
        "![every verdict: estimates and 90% intervals against the margins](forest.png)",
        "",
        "Every two-arm comparison the project commits, drawn above and tabled here "
        f"(`{COMMAND}`; margins set before the runs: success difference within ±0.15, median-episodes "
        "ratio within 0.9 to 1.1; each cell: estimate (90% interval): reading; a test fails when this "
        f"block is stale). A seed's episodes to threshold is its {FIRST_PASSING}, as the plans define it, "
        "a seed that never passed counting as the budget + 1; where the code's reading before issue 52 "
        f"({CONVERGED_AT_END}) differs (post 001), it follows the ratio in parentheses, and does not "
        'govern. A 30-seed ablation row whose quirk has a row under "the planned seeds" is that row\'s '
        "pilot: its seed plan (`results/ablation_plan.md`, and `results/ablation_plan_second.md` for a second "
        "look) was sized from it, so an inconclusive pilot stays so and the planned row is the verdict.",
        "",
        "| comparison | first against second | seeds | success difference | median-episodes ratio |",
        "|---|---|---|---|---|",
    ]
    for r in data:
        label = r["label"] + plans.mark(f"{r['group']}: {r['label']}")
        if r["pending"]:
            lines.append(
                f"| {r['group']} | {label} | {r['seeds']} so far | pending: no reading before "
                "its planned seeds | pending |"
            )
            continue
        speed = _cell(r["speed"])
        if "speed_converged_at_end" in r:
            speed += f" (the code's reading, {CONVERGED_AT_END}: {_cell(r['speed_converged_at_end'])})"
        lines.append(f"| {r['group']} | {label} | {r['seeds']} | {_cell(r['success'])} | {speed} |")
    marked = [d for d in plans.DEVIATIONS if any(d in plans.deviations_of(f"{r['group']}: {r['label']}") for r in data)]
    if marked:
        lines += ["", "Deviations from the plans (`maintainers/plans.py`), marked † on their rows:", ""]
        lines += plans.notes(marked)
    return "\n".join(lines)


RATIO_AXIS = (0.5, 2.0)
COLOURS = {"equivalent within the margin": "tab:green", "different": "tab:red", "inconclusive": "tab:gray"}


def _heading(group: str) -> str:
    """A group's heading, saying which arm is first: ``Keras vs PyTorch`` -> first Keras, second PyTorch."""
    first, vs, rest = group.partition(" vs ")
    if not vs:
        return group
    second, comma, detail = rest.partition(", ")
    return (
        f"{group}: first = {first}, second = {second}"
        if not comma
        else (f"{first} vs {second} ({detail}): first = {first}, second = {second}")
    )


def draw(data: list[dict[str, Any]], path: Path) -> None:
    """Two panels (success difference, median ratio), the comparisons grouped under headings that
    say which arm is first: each estimate and its 90% interval coloured by reading, the margin band
    shaded, an interval cut at the axis marked with an arrow, a row without an estimate saying so."""
    from keras_rl.report.plots import plt, save_figure

    shown = [r for r in data if not r["pending"]]
    entries: list[tuple[str, dict[str, Any] | None]] = []  # (label, row), a heading's row None
    for group in dict.fromkeys(r["group"] for r in shown):  # each group once, in the order of its first row
        entries.append((_heading(group), None))
        entries += [
            (f"{r['label']} ({r['seeds']} seeds){plans.mark(group + ': ' + r['label'])}", r)
            for r in shown
            if r["group"] == group
        ]
    height = 0.22 * len(entries) + 1.3
    fig, axes = plt.subplots(1, 2, figsize=(16, height), sharey=True)
    y = np.arange(len(entries))[::-1]
    for ax, key, title in (
        (axes[0], "success", "success rate: first minus second"),
        (axes[1], "speed", "median episodes to threshold: first over second"),
    ):
        margin = shown[0][key]["margin"] if shown else [0, 1]
        ax.axvspan(margin[0], margin[1], color="tab:green", alpha=0.08, lw=0)
        ax.axvline(0.0 if key == "success" else 1.0, color="k", lw=0.7)
        centre = 0.0 if key == "success" else 1.0
        for yi, (_, row) in zip(y, entries):
            if row is None:
                ax.axhline(yi, color="0.85", lw=0.6)
                continue
            v = row[key]
            if v["estimate"] is None:
                ax.text(centre, yi, "no estimate", ha="center", va="center", fontsize=6.5, color="0.35")
                continue
            colour = COLOURS[v["reading"]]
            low, high = v["low"], v["high"]
            lo_axis, hi_axis = RATIO_AXIS if key == "speed" else (-1.0, 1.0)
            if low < lo_axis:
                ax.plot([lo_axis], [yi], "<", color=colour, ms=5, clip_on=False)
            if high > hi_axis:
                ax.plot([hi_axis], [yi], ">", color=colour, ms=5, clip_on=False)
            low, high = max(low, lo_axis), min(high, hi_axis)
            ax.plot([low, high], [yi, yi], color=colour, lw=2)
            ax.plot([v["estimate"]], [yi], "o", color=colour, ms=4)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="x", alpha=0.3, which="both")
        if key == "speed":  # a ratio: symmetric on a log axis; what lies beyond the axis is cut, with an arrow
            ax.set_xscale("log")
            ax.set_xlim(*RATIO_AXIS)
            ax.set_xticks([0.5, 0.67, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0])
            ax.set_xticklabels(["0.5", "0.67", "0.8", "0.9", "1", "1.1", "1.25", "1.5", "2"], fontsize=8)
            ax.minorticks_off()
        else:
            ax.set_xlim(-1.0, 1.0)
    axes[0].set_ylim(-0.8, len(entries) - 0.2)
    axes[0].set_yticks(y)
    axes[0].set_yticklabels([label for label, _ in entries], fontsize=7)
    for tick, (_, row) in zip(axes[0].get_yticklabels(), entries):
        if row is None:
            tick.set_fontweight("bold")
    handles = [plt.Line2D([], [], color=c, marker="o", lw=2, label=k) for k, c in COLOURS.items()]
    handles.append(plt.Line2D([], [], color="0.3", marker=">", lw=0, label="interval continues past the axis"))
    handles.append(plt.Rectangle((0, 0), 1, 1, color="tab:green", alpha=0.15, label="margin set before the runs"))
    handles.append(plt.Line2D([], [], lw=0, label="†N: a deviation from its plan (the table below)"))
    top = 1 - 0.95 / height  # about an inch above the panels: the title, then the legend
    fig.subplots_adjust(left=0.36, right=0.99, bottom=0.5 / height, top=top, wspace=0.06)
    fig.legend(handles=handles, fontsize=8, loc="lower center", ncol=5, bbox_to_anchor=(0.675, top + 0.25 / height))
    fig.suptitle(
        f"Every verdict, 90% intervals against the margins set before the runs (`{COMMAND}`)",
        fontsize=10,
        x=0.675,
        y=1 - 0.12 / height,
    )
    save_figure(fig, path)


CERTIFIED = ROOT / "keras_rl" / "train" / "certified.json"
"""The compiled engine's certification, package data that ``train/compiled_scope.CERTIFIED`` reads."""


def certified(data: list[dict]) -> dict[str, str]:
    """Each post whose "compiled engine vs Gymnasium loop" row reads equivalent on both readings,
    with what says so: the compiled engine is its default engine (``study.choose_engine``)."""
    return {
        f"{r['label']}/keras": "equivalent to the Gymnasium loop on success and median episodes over "
        f"{r['seeds']} seeds per engine"
        + (", read as its plan defines them" if "speed_converged_at_end" in r else "")
        + f" (results/engines/{r['label']}/report.md)"
        for r in data
        if r["group"] == ENGINE_GROUP
        and not r["pending"]
        and r["success"]["reading"].startswith("equivalent")
        and r["speed"]["reading"].startswith("equivalent")
    }


def run(args) -> int:
    from keras_rl.atomic import atomic_write_bytes, atomic_write_json, atomic_write_text
    from maintainers.markdown import replace_block

    data = rows()
    text = table(data)
    if not args.write:
        print(text)
        return 0
    atomic_write_json(DATA, {"command": COMMAND, "rows": data})
    atomic_write_json(CERTIFIED, certified(data))
    draw(data, FIGURE)
    atomic_write_bytes(DOCS_FIGURE, FIGURE.read_bytes())
    for page in PAGES:
        atomic_write_text(page, replace_block(page.read_text(), BEGIN, END, text))
    print(f"wrote {FIGURE}, {DATA}, {CERTIFIED} and the blocks of {', '.join(str(p) for p in PAGES)}")
    return 0
