"""Each quirk switch's measured effect, for ``reproductions/FIDELITY.md``, from the committed
ablation runs.

    python -m maintainers tables ablations            # print the three tables
    python -m maintainers tables ablations --changes  # each switch's reading on seeds 0-9 and on all
    python -m maintainers tables ablations --write    # replace them in reproductions/FIDELITY.md,
                                                      # and rewrite each sweep folder's sweep.md

Per post: the faithful runs, and for every quirk switch of its config (``QUIRKS``) the runs
with that switch flipped alone, seeds 0-9 at the post's budget. Every number comes from
``keras_rl.report.sweep.analyse_sweep``, the same code that writes a sweep's ``sweep.md``:

- the success rate under the post's own criterion, its difference from faithful with
  Newcombe's hybrid score 95% interval, and Fisher's exact p;
- episodes to threshold by the plans' reading (each seed's first passing episode; median and
  IQR), the difference of medians with a percentile-bootstrap 95% interval, and the two-sided
  Mann-Whitney p, with the code's reading before issue 52 (counted only if converged at the end)
  beside them where the two differ (post 001).

The reading is mechanical: "changes the success rate" when that interval excludes 0; else
"faster"/"slower" when both the Mann-Whitney test (p < 0.05) and the interval of the median
difference say so, with a caveat when only one does. Else no effect was shown, and the
equivalence tests against the margins set before the 30-seed runs (``report/equivalence.py``:
success rate within ±0.15, median episodes to threshold within ±10%, TOST) say whether that
means "equivalent within the margins" or only "inconclusive at n seeds": an interval that
includes 0 is no evidence of no effect.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

from keras_rl.errors import ConfigError
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT
from maintainers.markdown import replace_block
from maintainers.tables.runs import runs_table

FIDELITY = ROOT / "reproductions" / "FIDELITY.md"
SWEEP = "keras-rl sweep {exp} --ablate --seeds 0-9 --workers 2{batch} --no-progress --out results/{exp}/ablations"
MORE = (
    "`keras-rl sweep {exp} --ablate --seeds 10-29 --seed-batch auto --workers 2 --no-progress --out DIR` "
    "(seeds 10-29, run into a fresh folder at 662a149, its seed folders merged in)"
)
SOURCES: dict[str, dict[str, Any]] = {
    # post 000's ablations run on the compiled engine since issue 34 retired its stacked learner
    # (the Gymnasium loop's sets, seeds 10-29 of them batched, were regenerated there);
    "pendulum": {
        "base": "results/pendulum/ablations-compiled/base",
        "points": "results/pendulum/ablations-compiled",
        "also": {"fixed (all four off)": "results/pendulum/ablations-compiled/fixed"},
        "command": "`keras-rl reproduce pendulum --engine compiled --seeds 0-29 --set SWITCH=false --workers 1 "
        "--resume --no-progress --min-success-rate 0 --out results/pendulum/ablations-compiled/SWITCH=false` "
        "(base: no --set, into base/; fixed: --variant fixed, into fixed/)",
    },
    # post 003's likewise (its Gymnasium-loop sets had been batched, seeds 0-9 by 10, 10-29 auto)
    "cartpole": {
        "base": "results/cartpole/ablations-compiled/base",
        "points": "results/cartpole/ablations-compiled",
        "also": {},
        "command": "`keras-rl reproduce cartpole --engine compiled --seeds 0-29 --set SWITCH=VALUE --workers 1 "
        "--resume --no-progress --min-success-rate 0 --out results/cartpole/ablations-compiled/SWITCH=VALUE` "
        "(base: no --set; its seeds are results/engines/cartpole/compiled's seeds 0-29, made by that command, copied)",
    },
    "mountaincar": {
        "base": "results/mountaincar/ablations/base",
        "points": "results/mountaincar/ablations",
        "also": {},
        "command": f"`{SWEEP.format(exp='mountaincar', batch='')}`, then "
        + MORE.format(exp="mountaincar")
        + " and, since no stacked learner covers it, the learning-phase point alone: `keras-rl sweep mountaincar "
        "--grid learning_phase_training=true --seeds 10-29 --workers 1 --no-progress --out DIR`",
    },
}


def commands(folder: Path) -> str:
    """The distinct commands that made a folder's seeds, in seed order (a set extended by a later
    command names both)."""
    seen: list[str] = []
    for summary in _summaries(folder):
        if summary.command and summary.command not in seen:
            seen.append(summary.command)
    return "; ".join(f"`{c}`" for c in seen)


def sweep_report(experiment: str) -> Path | None:
    """Rewrite ``results/<experiment>/ablations/sweep.md`` (and each point's summary.md and
    curves.png) from every committed seed of every grid point (``grid.json``), with the commands
    that made them; None where the ablations are not one sweep folder (post 000's)."""
    import json

    from keras_rl.registry import get_experiment
    from keras_rl.report.sweep import write_sweep_report

    folder = ROOT / SOURCES[experiment]["points"]
    if not (folder / "grid.json").is_file():
        return None
    points = [entry["name"] for entry in json.loads((folder / "grid.json").read_text())]
    summaries = {name: _summaries(folder / name) for name in points}
    made = commands(folder / points[0])
    spec = get_experiment(experiment)
    write_sweep_report(folder, spec, spec.config_cls.for_variant("faithful"), summaries, points[0], made.strip("`"))
    return folder / "sweep.md"


def markers(experiment: str) -> tuple[str, str]:
    return f"<!-- ablations:{experiment}:begin -->", f"<!-- ablations:{experiment}:end -->"


def _summaries(folder: Path) -> list:

    return RunSet(folder).summaries()


def _reading(row: dict, summaries: list, faithful: list, budget: int) -> str:
    """A switch's reading against the faithful base, from both arms' seeds (``summaries``)."""
    if row["unfinished"] and len(row["unfinished"]) == row["seeds"]:
        return "every seed stopped early: " + ", ".join(sorted({s.status for s in summaries}))
    rate, diff = row["success_difference"], row.get("median_difference")
    if rate["low"] > 0 or rate["high"] < 0:
        return "changes the success rate"
    tested = row.get("mann_whitney_p") is not None and row["mann_whitney_p"] < 0.05
    excluded = diff is not None and (diff["low"] > 0 or diff["high"] < 0)
    if diff is not None and (tested or excluded):
        direction = "slower" if diff["estimate"] > 0 else "faster"
        return (
            direction
            if tested and excluded
            else (
                f"{direction} by Mann-Whitney (p < 0.05), but the median's interval includes 0"
                if tested
                else f"{direction} by the median's interval, but Mann-Whitney p >= 0.05"
            )
        )
    from keras_rl.report.equivalence import Arm, framework_verdict

    _, judged = framework_verdict(Arm.of(summaries), Arm.of(faithful), budget)
    if all(e.reading == "equivalent within the margin" for e in judged):
        return "no effect: equivalent within the margins (TOST)"
    return f"no effect shown; inconclusive at {row['seeds']} seeds (TOST)"


def table(experiment: str, only: set[int] | None = None) -> str:
    from keras_rl.config import point_name
    from keras_rl.registry import get_experiment
    from keras_rl.report.sweep import analyse_sweep

    source = SOURCES[experiment]
    config_cls: Any = get_experiment(experiment).config_cls
    defaults = config_cls()
    rows = [("-", "faithful", ROOT / source["base"])]
    for field, (ledger_id, off) in config_cls.QUIRKS.items():
        flipped = point_name({field: off})
        rows.append(
            (
                ledger_id,
                f"`{field}`: `{point_name({field: getattr(defaults, field)}).split('=', 1)[1]}` -> "
                f"`{flipped.split('=', 1)[1]}`",
                ROOT / source["points"] / flipped,
            )
        )
    rows += [("-", name, ROOT / folder) for name, folder in source["also"].items()]

    lines = [
        f"Regenerate the runs with {source['command']} and this table with "
        "`python -m maintainers tables ablations --write`.",
        "",
        "| id | runs (seeds 0-9) | success | minus faithful [95% CI] | Fisher p | episodes to threshold: "
        "median (IQR) | minus faithful [95% CI] | Mann-Whitney p | reading |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    summaries = {label: _summaries(folder) for _, label, folder in rows if folder.is_dir()}
    if "faithful" not in summaries:
        return "\n".join(lines[:2] + ["Not run yet: no faithful runs in " + source["base"] + "."])
    # Every arm on the seeds they all have: the faithful set may hold more (issue #20's
    # 30-seed runs) than the switches' sets, and a comparison is made on the same seeds.
    common = set.intersection(*({s.seed for s in arm} for arm in summaries.values()))
    if only is not None:
        common &= only
    summaries = {label: [s for s in arm if s.seed in common] for label, arm in summaries.items()}
    span = f"{min(common)}-{max(common)}" if common == set(range(min(common), max(common) + 1)) else str(sorted(common))
    lines[2] = lines[2].replace("runs (seeds 0-9)", f"runs (seeds {span})")
    result = {r["point"]: r for r in analyse_sweep(summaries, "faithful")["points"]}
    budget = summaries["faithful"][0].budget_episodes
    g = lambda v: "n/a" if v is None else f"{v:g}"  # noqa: E731
    p = lambda v: "n/a" if v is None or v != v else f"{v:.2g}"  # noqa: E731
    for ledger_id, label, _folder in rows:
        if label not in result:
            lines.append(f"| {ledger_id} | {label} | not run yet | | | | | | |")
            continue
        r = result[label]
        stopped = f" ({len(r['unfinished'])} stopped early)" if r["unfinished"] else ""
        spread = "n/a" if r["median"] is None else f"{g(r['median'])} ({g(r['q25'])}-{g(r['q75'])})"
        was = r.get("before_issue_52")  # the code's reading before issue 52, beside, where it differs
        if was is not None:
            spread += "; before issue 52: " + (
                "n/a" if was["median"] is None else f"{g(was['median'])} ({g(was['q25'])}-{g(was['q75'])})"
            )
        if label == "faithful":
            lines.append(
                f"| {ledger_id} | {label} | {r['successes']}/{r['seeds']}{stopped} | - | - | {spread} | - | - | - |"
            )
            continue
        rate, diff = r["success_difference"], r.get("median_difference")
        diff_text = "n/a" if diff is None else f"{diff['estimate']:+g} [{diff['low']:+g}, {diff['high']:+g}]"
        if was is not None:
            d = was["median_difference"]
            diff_text += "; before issue 52: " + (
                "n/a" if d is None else f"{d['estimate']:+g} [{d['low']:+g}, {d['high']:+g}]"
            )
        lines.append(
            f"| {ledger_id} | {label} | {r['successes']}/{r['seeds']}{stopped} "
            f"| {rate['estimate']:+.2f} [{rate['low']:+.2f}, {rate['high']:+.2f}] | {p(r['fisher_p'])} "
            f"| {spread} | {diff_text} | {p(r.get('mann_whitney_p'))} "
            f"| {_reading(r, summaries[label], summaries['faithful'], budget)}{planned_reading(experiment, label)} |"
        )
    return "\n".join(lines)


def planned_reading(experiment: str, label: str) -> str:
    """Where the forest reads this ablation at the seeds its plan set (``results/ablation_plan.md``
    and its second look), that reading, after the pilot's: the quirk's effect as settled."""
    import json

    switch = label.replace("`", "").replace(": ", "=").split(" -> ")
    if len(switch) != 2:
        return ""
    name = f"{switch[0].split('=')[0]}={switch[1]}"
    forest = ROOT / "results" / "forest.json"
    rows = json.loads(forest.read_text())["rows"] if forest.is_file() else []
    group = f"{experiment} ablation vs faithful, the planned seeds"
    for row in rows:
        if row["group"] == group and row["label"].startswith(f"{name} ("):
            if row["pending"]:
                return f"; at its planned seeds ({row['label'].split('(', 1)[1].rstrip(')')}): pending"
            readings = f"{row['success']['reading']} on success, {row['speed']['reading']} on the median ratio"
            return f"; at its planned seeds ({row['seeds']}, the forest): {readings}"
    return ""


def changes(experiment: str) -> list[tuple[str, str, str]]:
    """(switch, reading on seeds 0-9, reading on every seed all arms have) per row."""

    def readings(text: str) -> dict[str, str]:
        rows = [line.split("|") for line in text.splitlines() if line.startswith("| ") and "---" not in line]
        return {f"{r[1].strip()} {r[2].strip()}": r[-2].strip() for r in rows[1:]}

    ten, every = readings(table(experiment, only=set(range(10)))), readings(table(experiment))
    return [(name, ten[name], every[name]) for name in every if every[name] != "-"]


READINGS = ("results/mountaincar/faithful", "results/mountaincar/faithful-intended")
READINGS_MARKERS = ("<!-- p001-readings:begin -->", "<!-- p001-readings:end -->")


def readings_table() -> str:
    """Post 001's two readings of the actor step on every committed seed (``report/tables/runs.py``)."""
    command = "python -m maintainers tables runs " + " ".join(READINGS)
    return f"{runs_table([ROOT / f for f in READINGS])}\n\n(`{command}`)"


def run(args: argparse.Namespace) -> int:
    experiments = args.experiments or list(SOURCES)
    unknown = sorted(set(experiments) - set(SOURCES))
    if unknown:
        raise ConfigError(f"unknown experiment(s) {', '.join(unknown)}; choose from {', '.join(SOURCES)}")
    if args.changes:
        print("| post | switch | seeds 0-9 | all seeds | changed |\n|---|---|---|---|---|")
        for name in experiments:
            for switch, ten, every in changes(name):
                same = re.sub(r"at \d+ seeds", "", ten) == re.sub(r"at \d+ seeds", "", every)
                print(f"| {name} | {switch} | {ten} | {every} | {'no' if same else 'yes'} |")
        return 0
    tables = {name: table(name) for name in experiments}
    if not args.write:
        print("\n\n".join([*tables.values(), readings_table()]))
        return 0
    from keras_rl.atomic import atomic_write_text

    content = FIDELITY.read_text()
    for name, text in tables.items():
        content = replace_block(content, *markers(name), text)
    content = replace_block(content, *READINGS_MARKERS, readings_table())
    atomic_write_text(FIDELITY, content)
    print(f"updated {FIDELITY}")
    for name in experiments:
        report = sweep_report(name)
        if report is not None:
            print(f"updated {report}")
    return 0
