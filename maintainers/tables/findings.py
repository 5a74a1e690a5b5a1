"""The findings table of results/README.md, computed from the committed run folders.

    python -m maintainers tables findings            # print the table
    python -m maintainers tables findings --write    # replace it in results/README.md and README.md
    python -m maintainers tables findings --changes  # what seeds 0-9 said against what all the seeds say

and the Keras-vs-PyTorch summary, one row per ``results/compare/**/result.json``, and the
generated part of each per-post section (``post_block``: ``tables/runs.py``'s table of the
post's variants, and what the seeds say about the post's own claim).

One row per post x variant x framework: success rate, episodes to threshold (median and
IQR over the seeds that succeeded; post 001: still converged at the end), the post's own
number, ms per env step (median over seeds of wall seconds / env steps, as the runs ran: two
seeds at a time, often beside
other work) and the command that regenerates the row's folder.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from keras_rl.report.stats import wilson_interval
from keras_rl.runs.run_set import RunSet
from maintainers import plans
from maintainers.checkout import ROOT
from maintainers.markdown import replace_block, seed_span
from maintainers.tables.runs import load, runs_table
from maintainers.tutorial_fix import FRAMEWORKS, PLANNED_SEEDS, TUTORIAL_FIXES

BEGIN, END = "<!-- findings-table:begin -->", "<!-- findings-table:end -->"
COMPARE_BEGIN, COMPARE_END = "<!-- compare-table:begin -->", "<!-- compare-table:end -->"
SHORT_BEGIN, SHORT_END = "<!-- findings-short:begin -->", "<!-- findings-short:end -->"
POSTS = ("post000", "post003", "post001")
"""results/README.md's per-post sections: each has a generated block between these markers."""


def post_markers(post: str) -> tuple[str, str]:
    return f"<!-- {post}:begin -->", f"<!-- {post}:end -->"


REPRODUCE = (
    "keras-rl reproduce {exp} --variant {variant} --framework {fw}{matched} --seeds {seeds} --engine {engine} "
    "--workers 2 --no-progress --min-success-rate 0"
)
"""A row's command, naming the engine its folder's runs recorded: ``--engine auto`` would train a
new Keras study of posts 000, 001 and 003 compiled, and these sets ran on the Gymnasium loop."""

PENDULUM = ("000 Pendulum DDPG", "pendulum")
CARTPOLE = ("003 CartPole DQN", "cartpole")
MOUNTAINCAR = ("001 MountainCar DDPG", "mountaincar")
CARTPOLE_SUCCESS = "100-ep. mean >= 475 in 600"
MOUNTAINCAR_SUCCESS = "last-10 spread <= 2.0"
CARTPOLE_SAID, MOUNTAINCAR_SAID = '"500 within 600" (no number)', '"roughly converged within 100"'

# (post, experiment, variant, framework, matched init, success criterion, the post's own number)
ROWS = [
    (*PENDULUM, "faithful", "keras", False, "EMA > -300", "153 (one run)"),
    (*PENDULUM, "faithful", "torch", False, "EMA > -300", "153 (one run)"),
    (*PENDULUM, "faithful", "torch", True, "EMA > -300", "153 (one run)"),
    (*PENDULUM, "fixed", "keras", False, "EMA > -300", "-"),
    (*CARTPOLE, "faithful", "keras", False, CARTPOLE_SUCCESS, CARTPOLE_SAID),
    (*CARTPOLE, "faithful", "torch", False, CARTPOLE_SUCCESS, CARTPOLE_SAID),
    (*CARTPOLE, "faithful", "torch", True, CARTPOLE_SUCCESS, CARTPOLE_SAID),
    (*MOUNTAINCAR, "faithful", "keras", False, MOUNTAINCAR_SUCCESS, MOUNTAINCAR_SAID),
    (*MOUNTAINCAR, "faithful", "torch", False, MOUNTAINCAR_SUCCESS, MOUNTAINCAR_SAID),
    (*MOUNTAINCAR, "faithful", "torch", True, MOUNTAINCAR_SUCCESS, MOUNTAINCAR_SAID),
    (*MOUNTAINCAR, "faithful-intended", "keras", False, MOUNTAINCAR_SUCCESS, "-"),
    (*MOUNTAINCAR, "fixed", "keras", False, "goal in >= 50% of last 50", "-"),
    *((*CARTPOLE, fix.variant, fw, False, CARTPOLE_SUCCESS, fix.said) for fix in TUTORIAL_FIXES for fw in FRAMEWORKS),
]

ELSEWHERE = {("cartpole", fix.variant): fix for fix in TUTORIAL_FIXES}
"""(experiment, variant) -> the tutorial's community fix whose folders and commands its rows take
(``maintainers/tutorial_fix.py``), for rows not in ``run_folder``'s default place."""


def queued(folder: Path) -> bool:
    """Whether a committed queue of long runs (``maintainers/queues/*.tsv``) makes this run set: a
    row of it is pending until it lands (the forest lists its reading as pending), not "not run"."""
    from maintainers.plans import queued_sets

    return folder.relative_to(ROOT / "results").as_posix() in queued_sets()


def arm_name(fw: str, matched: bool) -> str:
    """A row's framework as the tables print it: ``vectorised`` is PyTorch on the vectorised engine."""
    return ("torch, vectorised engine" if fw == "vectorised" else fw) + (" (matched init)" if matched else "")


def row_folder(exp: str, variant: str, fw: str, matched: bool) -> Path:
    from keras_rl.runs.files import run_folder

    if (exp, variant) in ELSEWHERE:
        return ROOT / "results" / ELSEWHERE[(exp, variant)].folder(fw)
    return run_folder(ROOT / "results", exp, variant, fw, matched)


def row_command(exp: str, variant: str, fw: str, matched: bool, seeds: str, engine: str = "gymnasium") -> str:
    if (exp, variant) in ELSEWHERE:
        return ELSEWHERE[(exp, variant)].command(fw, seeds)
    matched_text = " --matched-init" if matched else ""
    return REPRODUCE.format(exp=exp, variant=variant, fw=fw, matched=matched_text, seeds=seeds, engine=engine)


def row_numbers(folder: Path, seeds: set[int] | None = None) -> dict | None:
    """A folder's numbers over its seeds (only ``seeds``, when given)."""
    summaries = RunSet(folder).summary_records()
    summaries = [s for s in summaries if seeds is None or s["seed"] in seeds]
    if not summaries:
        return None
    hits = [s["reached_at_episode"] for s in summaries if s["success"]]
    ms = [s["wall_seconds"] / s["total_steps"] * 1e3 for s in summaries if s["total_steps"]]
    q25, q50, q75 = np.percentile(hits, [25, 50, 75]) if hits else (np.nan,) * 3
    return {
        "seeds": sorted(s["seed"] for s in summaries),
        "successes": len(hits),
        "n": len(summaries),
        "median": q50,
        "q25": q25,
        "q75": q75,
        "ms": float(np.median(ms)) if ms else np.nan,
        "unfinished": sum(s["status"] != "completed" for s in summaries),
    }


def _listed(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _seeds(summaries: list[dict]) -> str:
    return ("seed " if len(summaries) == 1 else "seeds ") + _listed([str(s["seed"]) for s in summaries])


def post_block(post: str) -> str:
    """The generated part of a per-post section of results/README.md: the variants against each
    other (``tables/runs.py``'s table, with its command), and what the seeds say about the
    post's own claim."""
    results = ROOT / "results"
    if post == "post000":
        folders = [results / "pendulum" / "faithful", results / "pendulum" / "fixed"]
        faithful = load(folders[0])
        hits = [s["reached_at_episode"] for s in faithful if s["success"]]
        lo, hi, median = min(hits), max(hits), float(np.median(hits))
        said = (
            f"On seeds {seed_span([s['seed'] for s in faithful])} the faithful variant reaches EMA > -300 in "
            f"{len(hits)}/{len(faithful)}, after a median of {median:g} episodes, "
            f"{abs(153 - median):g} {'fewer' if median < 153 else 'more'} than the post's single run (153); "
            f"153 lies {'inside' if lo <= 153 <= hi else 'outside'} the range {lo}-{hi}."
        )
    elif post == "post003":
        folders = [results / "cartpole" / "faithful", results / "cartpole" / "faithful-torch"]
        parts = []

        def final(runs: list[dict]) -> str:
            return ("final mean " if len(runs) == 1 else "final means ") + _listed(
                [f"{s['final_metric']:.1f}" for s in runs]
            )

        for folder, name in zip(folders, ("Keras", "PyTorch")):
            runs = load(folder)
            hits = [s for s in runs if s["success"]]
            never = [s for s in runs if not s["success"]]
            fell = [s for s in hits if s["final_metric"] < 475]
            text = (
                f"In {name} ({len(hits)}/{len(runs)} on seeds {seed_span([s['seed'] for s in runs])}) the 100-episode "
                f"mean passes 475 between episodes {min(s['reached_at_episode'] for s in hits)} and "
                f"{max(s['reached_at_episode'] for s in hits)}"
            )
            if never:
                text += f"; {_seeds(never)} never got there ({final(never)})"
            if fell:
                text += f"; {_seeds(fell)} got there and fell back ({final(fell)})"
            parts.append(text + ".")
        said = " ".join(parts)
    elif post == "post001":
        folders = [results / "mountaincar" / "faithful", results / "mountaincar" / "faithful-intended"]
        fixed = results / "mountaincar" / "fixed"
        evaluated = [(r.seed, json.loads(r.file_text("evaluation.json"))) for r in RunSet(fixed).runs()]
        rows = []
        for start in range(0, len(evaluated), 10):
            chunk = evaluated[start : start + 10]
            rows += [
                "| seed | " + " | ".join(str(seed) for seed, _ in chunk) + " |",
                "|---|" + "---|" * len(chunk),
                "| mean return (100 greedy episodes) | "
                + " | ".join(f"**{e['mean']:.2f}**" if e["mean"] >= 90 else f"{e['mean']:.2f}" for _, e in chunk)
                + " |",
                "",
            ]
        met = [seed for seed, e in evaluated if e["mean"] >= 90]
        close = [f"{seed} ({e['mean']:.2f})" for seed, e in evaluated if 89 <= e["mean"] < 90]
        said = (
            "Each fixed seed's policy after 100 training episodes, played greedily by `keras-rl evaluate "
            "results/mountaincar/fixed/seed_N --episodes 100` (its `evaluation.json`):\n\n"
            + "\n".join(rows)
            + f"\n{len(met)}/{len(evaluated)} seeds meet Gymnasium's bar of 90 (bold)"
            + (f"; within 1 of it: {_listed(close)}" if close else "")
            + "."
        )
    else:
        raise ValueError(post)
    command = "python -m maintainers tables runs " + " ".join(str(f.relative_to(ROOT)) for f in folders)
    return f"{runs_table(folders)}\n\n(`{command}`)\n\n{said}"


def table() -> str:
    lines = [
        "| post | variant | framework | success | criterion | episodes to threshold: median (IQR) | the post | ms/step "
        "| command |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for post, exp, variant, fw, matched, criterion, theirs in ROWS:
        folder = row_folder(exp, variant, fw, matched)
        numbers = row_numbers(folder)
        if numbers is None and queued(folder):
            continue
        framework = arm_name(fw, matched)
        planned = PLANNED_SEEDS[fw] if (exp, variant) in ELSEWHERE else 10  # what a row not yet run asks for
        span = f"0-{planned - 1}" if numbers is None else seed_span(numbers["seeds"])
        from keras_rl.runs.lifecycle import set_engine

        command = row_command(exp, variant, fw, matched, span, set_engine(folder) or "gymnasium")
        if numbers is None:
            lines.append(
                f"| {post} | {variant} | {framework} | not run | {criterion} | - | {theirs} | - | `{command}` |"
            )
            continue
        g = lambda v: "-" if not np.isfinite(v) else f"{v:g}"  # noqa: E731
        success = f"{numbers['successes']}/{numbers['n']}" + (
            f" ({numbers['unfinished']} unfinished)" if numbers["unfinished"] else ""
        )
        lines.append(
            f"| {post} | {variant} | {framework} | {success} | {criterion} | "
            f"{g(numbers['median'])} ({g(numbers['q25'])}-{g(numbers['q75'])}) | {theirs} | "
            f"{numbers['ms']:.2f} | `{command}` |"
        )
    return "\n".join(lines)


def short_table() -> str:
    """The README's version: success and median episodes to threshold per row, with the seeds (a
    row whose queue is still running is left out, as in ``table``)."""

    lines = [
        "| post | variant | framework | seeds | success (95% Wilson interval) "
        "| median episodes to threshold, over the seeds that succeeded | the post |",
        "|---|---|---|---|---|---|---|",
    ]
    for post, exp, variant, fw, matched, _criterion, theirs in ROWS:
        folder = row_folder(exp, variant, fw, matched)
        numbers = row_numbers(folder)
        framework = arm_name(fw, matched)
        if numbers is None:
            if not queued(folder):
                lines.append(f"| {post} | {variant} | {framework} | - | not run | - | {theirs} |")
            continue
        seeds = numbers["seeds"]
        span = seed_span(seeds) if seeds == list(range(seeds[0], seeds[-1] + 1)) else f"{len(seeds)} seeds"
        median = "-" if not np.isfinite(numbers["median"]) else f"{numbers['median']:g}"
        low, high = wilson_interval(numbers["successes"], numbers["n"])
        lines.append(
            f"| {post} | {variant} | {framework} | {span} | {numbers['successes']}/{numbers['n']} "
            f"({low:.2f}-{high:.2f}) | {median} | {theirs} |"
        )
    return "\n".join(lines)


def compare_table() -> str:
    """One row per committed ``results/compare/**/result.json``."""
    from keras_rl.report.compare import arm
    from keras_rl.report.equivalence import framework_verdict

    lines = [
        "| experiment | torch init | success keras / torch (Fisher p) | episodes to threshold, median keras / torch "
        "| keras - torch [95% CI] | Mann-Whitney p | equivalence, success ±0.15 / median ±10% (TOST) | report "
        "| at the planned seeds (`results/compare/seed_plan.md`) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    from maintainers.certified import certifications, reading

    planned = {(c.post, c.matched_init): c for c in certifications()}
    g = lambda v: "-" if v is None else f"{v:.2g}"  # noqa: E731  (p-values)
    m = lambda v: "-" if v is None else f"{v:g}"  # noqa: E731  (medians, exact)
    for path in sorted((ROOT / "results" / "compare").glob("**/result.json")):
        r = json.loads(path.read_text())
        k, t = r["frameworks"]["keras"], r["frameworks"]["torch"]
        d = r["median_difference"]
        diff = "-" if d is None else f"{d['estimate']:g} [{d['low']:g}, {d['high']:g}]"
        medians = f"{m(k['median'])} / {m(t['median'])}"
        if "median_difference_before_issue_52" in r:  # the code's reading before issue 52, beside
            ko, to = (f.get("before_issue_52", f) for f in (k, t))
            medians += f"; before issue 52: {m(ko['median'])} / {m(to['median'])}"
            d = r["median_difference_before_issue_52"]
            diff += "; before issue 52: " + ("-" if d is None else f"{d['estimate']:g} [{d['low']:g}, {d['high']:g}]")
        link = path.parent.relative_to(ROOT / "results") / "report.md"
        _, judged = framework_verdict(arm(k), arm(t), r["budget"])
        readings = _readings(judged)
        lines.append(
            f"| {r['experiment']} ({r['variant']}) | {'matched to Keras' if r['matched_init'] else 'torch default'} "
            f"| {k['successes']}/{len(k['seeds'])} / {t['successes']}/{len(t['seeds'])} ({g(r['fisher_p'])}) "
            f"| {medians} | {diff} | {g(r['mann_whitney'][1])} | {readings} "
            f"| [{link}]({link}) | {_planned_cell(reading(c := planned[(r['experiment'], r['matched_init'])]))}"
            f"{plans.mark(f'Keras vs PyTorch, the planned seeds: {c.label} ({c.planned} planned)')} |"
        )
    disclosed = plans.disclosure("results/README.md")
    return "\n".join(lines) + (f"\n\n{disclosed.rstrip()}" if disclosed else "")


def _planned_cell(read: dict) -> str:
    """A comparison at its planned seeds: the two readings, or how many seeds each arm holds."""
    if read["pending"]:
        keras, torch = read["held"]
        return f"pending: Keras {keras}, PyTorch {torch} of {read['planned']} seeds"
    return f"{_readings(read['judged'])} ({read['planned']} seeds each)"


def _readings(judged: list) -> str:
    """ "success / median ratio", and the median ratio by the code's reading before issue 52 where
    it differs from the plans' (``report.equivalence.CONVERGED_AT_END``)."""
    from keras_rl.report.equivalence import CONVERGED_AT_END

    said = " / ".join(e.reading.replace(" within the margin", "") for e in judged)
    beside = judged[1].beside
    if beside is None:
        return said
    return f"{said} (the code's reading, {CONVERGED_AT_END}: {beside.reading.replace(' within the margin', '')})"


FIRST_TEN = set(range(10))


def changes_table() -> str:
    """Every findings row and Keras-vs-PyTorch verdict on seeds 0-9 (what the findings said
    before issue #20) beside all of its seeds, and whether the reading changed: a success
    rate whose all-seeds estimate falls outside the 10-seed Wilson interval, or that moves
    between "every seed", "some seeds" and "no seed"; a comparison whose TOST reading moves."""
    from keras_rl.report.equivalence import framework_verdict
    from keras_rl.runs.files import run_folder

    def kind(successes: int, n: int) -> str:
        return "every seed" if successes == n else "no seed" if successes == 0 else "some seeds"

    lines = [
        "| row | seeds 0-9: success (95% Wilson) | median | all seeds: success (95% Wilson) | median | changed |",
        "|---|---|---|---|---|---|",
    ]
    for post, exp, variant, fw, matched, _criterion, _theirs in ROWS:
        folder = row_folder(exp, variant, fw, matched)
        ten, every = row_numbers(folder, FIRST_TEN), row_numbers(folder)
        if every is None and queued(folder):
            continue
        name = f"{post}, {variant}, {arm_name(fw, matched)}"
        if ten is None or every is None or every["n"] <= 10:
            lines.append(f"| {name} | - | - | {every['n'] if every else 0} seeds | - | not yet on more seeds |")
            continue
        low, high = wilson_interval(ten["successes"], ten["n"])
        rate = every["successes"] / every["n"]
        why = []
        if not low <= rate <= high:
            why.append(f"{rate:.2f} is outside {low:.2f}-{high:.2f}")
        if kind(ten["successes"], ten["n"]) != kind(every["successes"], every["n"]):
            why.append(f"{kind(ten['successes'], ten['n'])} -> {kind(every['successes'], every['n'])}")
        g = lambda v: "-" if not np.isfinite(v) else f"{v:g}"  # noqa: E731
        lo2, hi2 = wilson_interval(every["successes"], every["n"])
        lines.append(
            f"| {name} | {ten['successes']}/{ten['n']} ({low:.2f}-{high:.2f}) | {g(ten['median'])} "
            f"| {every['successes']}/{every['n']} ({lo2:.2f}-{hi2:.2f}) | {g(every['median'])} "
            f"| {'yes: ' + '; '.join(why) if why else 'no'} |"
        )
    lines += [
        "",
        "| comparison | seeds 0-9: success / median (TOST) | all seeds | changed |",
        "|---|---|---|---|",
    ]
    for path in sorted((ROOT / "results" / "compare").glob("**/result.json")):
        r = json.loads(path.read_text())
        folders = {
            fw: run_folder(ROOT / "results", r["experiment"], r["variant"], fw, r["matched_init"])
            for fw in ("keras", "torch")
        }
        readings = {}
        for label, seeds in (("ten", FIRST_TEN), ("all", set(r["frameworks"]["keras"]["seeds"]))):
            arms = [_arm(folders[fw], seeds) for fw in ("keras", "torch")]
            _, judged = framework_verdict(arms[0], arms[1], r["budget"])
            readings[label] = (" / ".join(e.reading for e in judged), arms[0].seeds)
        name = f"{r['experiment']} ({r['variant']}), {'matched init' if r['matched_init'] else 'torch default init'}"
        changed = (
            "not yet on more seeds"
            if readings["all"][1] <= 10
            else "no"
            if readings["ten"][0] == readings["all"][0]
            else "yes"
        )
        lines.append(
            f"| {name} | {readings['ten'][0]} | {readings['all'][0]} ({readings['all'][1]} seeds) | {changed} |"
        )
    return "\n".join(lines)


def _arm(folder: Path, seeds: set[int]):
    """A run folder's ``seeds`` as one arm of a verdict."""
    from keras_rl.report.equivalence import Arm

    return Arm.of(s for s in RunSet(folder).summary_records() if s["seed"] in seeds)


def run(args: argparse.Namespace) -> int:
    if args.changes:
        print(changes_table())
        return 0
    text, compared = table(), compare_table()
    if not args.write:
        print(text, compared, *(post_block(post) for post in POSTS), sep="\n\n")
        return 0
    from keras_rl.atomic import atomic_write_text

    readme = ROOT / "results" / "README.md"
    content = replace_block(readme.read_text(), BEGIN, END, text)
    content = replace_block(content, COMPARE_BEGIN, COMPARE_END, compared)
    for post in POSTS:
        content = replace_block(content, *post_markers(post), post_block(post))
    atomic_write_text(readme, content)
    main_readme = ROOT / "README.md"
    atomic_write_text(main_readme, replace_block(main_readme.read_text(), SHORT_BEGIN, SHORT_END, short_table()))
    print(f"updated {readme} and {main_readme}")
    return 0
