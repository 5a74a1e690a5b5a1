"""``keras-rl compare``'s report: the same seeds in Keras and in PyTorch, and what differs.

It reads run folders and trains nothing: ``dispatch/compare_runs.py`` makes or reuses them first.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.atomic import atomic_write_json, atomic_write_text, finite_or_none
from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.experiment import Experiment
from keras_rl.learners.table import compared_frameworks, frameworks
from keras_rl.registry import get_experiment
from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING, Arm, framework_verdict
from keras_rl.report.plots import plt, save_figure
from keras_rl.report.stats import (
    censored_mann_whitney,
    fisher_exact,
    iqm_ci,
    median_difference_ci,
)
from keras_rl.runs.files import run_folder
from keras_rl.runs.summary import RunSummary

FRAMEWORKS = ("keras", "torch")
"""The two arms of every report, in ``learners/table.frameworks`` order
(``dispatch/compare_runs.compared_frameworks`` holds each experiment to it)."""


def load_runs(folder: Path, seeds: list[int]) -> list[dict[str, Any]]:
    """Each seed's summary and rows (from its folder or the packed set); a RunFolderError names a
    seed whose files are missing or corrupt."""
    from keras_rl.runs.run_set import RunSet

    have = {r.seed: r for r in RunSet(folder).runs()}
    runs = []
    for seed in seeds:
        if seed not in have:
            RunSummary.read(folder / f"seed_{seed}")  # names what is missing
        run = have[seed]
        summary = run.summary()
        rows = run.rows(expected_rows=summary.rows_expected)
        if not rows and run.folder is not None and not (run.folder / "episodes.csv").is_file():
            raise RunFolderError(f"seed {seed}: {run.folder / 'episodes.csv'} is missing (the run wrote no episode)")
        runs.append({"seed": seed, "summary": summary, "rows": rows})
    return runs


def analyse(runs: dict[str, list[dict[str, Any]]], budget: int) -> dict[str, Any]:
    """Every number in the report, computed from the run folders' CSVs and summaries.

    Episodes to threshold (median, IQR, each seed's list, the median difference) are by the
    plans' reading (``FIRST_PASSING``), as the Mann-Whitney test and the verdict are; where the
    code's reading before issue 52 (``CONVERGED_AT_END``) differs, its numbers are kept beside
    (``before_issue_52``, ``median_difference_before_issue_52``), not governing."""
    out: dict[str, Any] = {"frameworks": {}}
    old: dict[str, dict[str, Any]] = {}
    for framework, rs in runs.items():
        summaries: list[RunSummary] = [r["summary"] for r in rs]
        stats = Arm.of(summaries).stats(FIRST_PASSING)
        old[framework] = Arm.of(summaries).stats(CONVERGED_AT_END)
        final = [r["rows"][-1]["metric"] for r in rs]
        ms = [s.wall_seconds / max(s.total_steps, 1) * 1e3 for s in summaries]
        out["frameworks"][framework] = {
            "seeds": [r["seed"] for r in rs],
            "successes": stats["successes"],
            "episodes_to_threshold": stats["episodes_to_threshold"],
            # each seed's first passing episode (null: never) and success, what the verdict reads
            "reached_at_episode": [s.reached_at_episode for s in summaries],
            "success": [s.success for s in summaries],
            **{k: (np.nan if stats[k] is None else stats[k]) for k in ("median", "q25", "q75")},
            "final": final,
            "final_iqm": iqm_ci(final, np.random.default_rng(0)),
            "wall_seconds_median": float(np.median([s.wall_seconds for s in summaries])),
            "ms_per_step_median": float(np.median(ms)),
        }
        if old[framework]["episodes_to_threshold"] != stats["episodes_to_threshold"]:
            out["frameworks"][framework]["before_issue_52"] = {
                "reading": CONVERGED_AT_END,
                "episodes_to_threshold": old[framework]["episodes_to_threshold"],
                **{k: (np.nan if old[framework][k] is None else old[framework][k]) for k in ("median", "q25", "q75")},
            }
    a, b = (out["frameworks"][fw]["episodes_to_threshold"] for fw in FRAMEWORKS)
    out["median_difference"] = median_difference_ci(a, b, np.random.default_rng(0)) if a and b else None
    if any("before_issue_52" in out["frameworks"][fw] for fw in FRAMEWORKS):
        a, b = (old[fw]["episodes_to_threshold"] for fw in FRAMEWORKS)
        out["median_difference_before_issue_52"] = (
            median_difference_ci(a, b, np.random.default_rng(0)) if a and b else None
        )
    keras, torch = (arm(out["frameworks"][fw]) for fw in FRAMEWORKS)
    out["mann_whitney"] = censored_mann_whitney(keras.episodes(), torch.episodes(), budget)
    k, t = out["frameworks"]["keras"], out["frameworks"]["torch"]
    out["fisher_p"] = fisher_exact(k["successes"], len(k["seeds"]), t["successes"], len(t["seeds"]))
    out["budget"] = budget
    return out


def _before_issue_52(result: dict[str, Any], fmt) -> list[str]:
    """The report's line on the code's reading before issue 52, where it differs from the plans'
    (none where the two coincide: post 000's and 003's reports are as they were)."""
    if "median_difference_before_issue_52" not in result:
        return []
    cells = []
    for fw in FRAMEWORKS:
        f = result["frameworks"][fw]
        o = f.get("before_issue_52", f)
        cells.append(
            f"{fw} {fmt(o['median'])} (IQR {fmt(o['q25'])}-{fmt(o['q75'])}, {len(o['episodes_to_threshold'])} seeds)"
        )
    return [
        f"- The episodes to threshold above (table, difference, Mann-Whitney) are by the plan's reading (a seed's "
        f"{FIRST_PASSING}). Beside them, not governing, the code's reading before issue 52 ({CONVERGED_AT_END}): "
        f"median {', '.join(cells)}; keras minus torch {result['median_difference_before_issue_52'] or 'n/a'}.",
    ]


def arm(framework: dict[str, Any]) -> Arm:
    """One framework's seeds in ``analyse``'s numbers (or a committed result.json's)."""
    return Arm(framework["reached_at_episode"], framework["success"])


def verdict(result: dict[str, Any], n: int) -> str:
    """The equivalence verdict (``report/equivalence.py``: TOST against the margins set before
    the runs), with the tests of a difference beside it."""
    k, t = result["frameworks"]["keras"], result["frameworks"]["torch"]
    headline, judged = framework_verdict(arm(k), arm(t), result["budget"])
    p = result["mann_whitney"][1]
    tests = f"Fisher p = {result['fisher_p']:.2f}" + (f", Mann-Whitney p = {p:.2f}" if np.isfinite(p) else "")
    rates = f"success {k['successes']}/{len(k['seeds'])} (Keras) vs {t['successes']}/{len(t['seeds'])} (PyTorch)"
    return f"{headline}. {rates}; " + "; ".join(e.sentence() for e in judged) + f". Tests of a difference: {tests}."


def _jsonable(value: Any) -> Any:
    """The analysis as plain JSON (intervals as {estimate, low, high}; NaN as null)."""
    import dataclasses

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return finite_or_none(float(value))
    if isinstance(value, np.integer):
        return int(value)
    return value


def _code_versions(runs: dict[str, list[dict[str, Any]]]) -> dict[str, list[str]]:
    from keras_rl.runs.provenance import code_version_of

    return {
        fw: sorted({code_version_of(r["summary"].provenance, r["summary"].versions.get("keras_rl"))[:12] for r in rs})
        for fw, rs in runs.items()
    }


def write_report(
    out_dir: Path,
    experiment: Experiment,
    variant: str,
    runs: dict[str, list[dict[str, Any]]],
    result: dict[str, Any],
    threshold: float,
    command: str,
    matched_init: bool = False,
    workers: int | None = None,
) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    n = len(runs["keras"])
    fmt = lambda v: "n/a" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:g}"  # noqa: E731
    init = (
        "matched init: each torch run starts from its Keras twin's initial weights, so only the framework differs"
        if matched_init
        else "default init: each framework initialises its networks its own way, as a user of it would get"
    )
    lines = [
        f"# {experiment.name} ({variant}): Keras vs PyTorch, {n} seeds",
        "",
        f"Initialisation: {init}.",
        "",
        f"Seeds: {', '.join(str(r['seed']) for r in runs['keras'])}. "
        f"Success: {runs['keras'][0]['summary'].criterion}. Command: `{command}`",
        "",
        "Made by code version: "
        + "; ".join(f"{fw} {', '.join(versions)}" for fw, versions in _code_versions(runs).items())
        + " (the package's tree hash at the commit each run recorded).",
        "",
        "| framework | success | episodes to threshold: median | IQR | final metric IQM [95% CI] "
        "| wall s per seed (median) | ms/step (median) |",
        "|---|---|---|---|---|---|---|",
    ]
    for fw in FRAMEWORKS:
        f = result["frameworks"][fw]
        lines.append(
            f"| {fw} | {f['successes']}/{n} | {fmt(f['median'])} | {fmt(f['q25'])}-{fmt(f['q75'])} "
            f"| {f['final_iqm']} | {f['wall_seconds_median']:.1f} | {f['ms_per_step_median']:.3f} |"
        )
    u, p = result["mann_whitney"]
    lines += [
        "",
        f"- Success rates, keras vs torch: Fisher exact test (two-sided) p = {fmt(result['fisher_p'])}.",
        f"- Median episodes-to-threshold, keras minus torch: {result['median_difference'] or 'n/a'} "
        "(percentile bootstrap, 10000 resamples, 95%).",
        *_before_issue_52(result, fmt),
        f"- Mann-Whitney U (keras vs torch episodes-to-threshold over every seed, two-sided; a seed that never "
        f"reached the threshold counts as {result['budget'] + 1}, the budget + 1, as in the median ratio): "
        f"U = {fmt(u)}, p = {fmt(p)}.",
        "- Final metric IQM: interquartile mean over seeds with a stratified-bootstrap 95% CI (rliable's method; "
        "one task, so the strata are the one task).",
        "- Wall time and ms/step come from each run's summary, as the runs ran"
        + (f" (this invocation: --workers {workers}; reused folders ran as they were made)" if workers else "")
        + ": often two seeds at a time on two cores, sometimes beside other work, and not always at the "
        "same time for both frameworks. Read them loosely; `benchmarks/step_time.py` measures speed in one process.",
        "",
        f"**Verdict.** {verdict(result, n)}",
        "",
        "![curves](curves.png) ![episodes to threshold](episodes_to_threshold.png)",
        "",
    ]
    atomic_write_text(out_dir / "report.md", "\n".join(lines))
    atomic_write_json(
        out_dir / "result.json",
        _jsonable(
            {
                "experiment": experiment.name,
                "variant": variant,
                "matched_init": matched_init,
                "command": command,
                "verdict": verdict(result, n),
                **result,
            }
        ),
    )

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for fw, color in zip(FRAMEWORKS, ("tab:blue", "tab:orange")):
        length = max(len(r["rows"]) for r in runs[fw])
        curves = np.full((len(runs[fw]), length), np.nan)
        for i, r in enumerate(runs[fw]):
            values = [row["metric"] for row in r["rows"]]
            curves[i, : len(values)] = values
        curves[~np.isfinite(curves)] = np.nan
        episodes = np.arange(1, length + 1)
        q25, q50, q75 = np.nanpercentile(curves, [25, 50, 75], axis=0)
        ax.plot(episodes, q50, color=color, label=f"{fw} median")
        ax.fill_between(episodes, q25, q75, color=color, alpha=0.25, label=f"{fw} IQR")
    ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    ax.set_xlabel("episode")
    ax.set_ylabel(experiment.metric_label(experiment.config_cls.for_variant(variant)))
    lengths = {len(r["rows"]) for rs in runs.values() for r in rs}
    ragged = "\n(seeds stop at the threshold: later points cover fewer seeds)" if len(lengths) > 1 else ""
    ax.set_title(f"{experiment.name} ({variant}): {n} seeds per framework{ragged}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    save_figure(fig, out_dir / "curves.png")

    fig, ax = plt.subplots(figsize=(5, 4))
    rng = np.random.default_rng(0)
    for i, fw in enumerate(FRAMEWORKS):
        hits = result["frameworks"][fw]["episodes_to_threshold"]
        misses = n - len(hits)
        ax.scatter(i + rng.uniform(-0.08, 0.08, len(hits)), hits, alpha=0.8)
        if hits:
            ax.hlines(np.median(hits), i - 0.2, i + 0.2, color="k")
        if misses:
            ax.scatter([i] * misses, [result["budget"] * 1.05] * misses, marker="x", color="tab:red")
    ax.set_xticks(range(len(FRAMEWORKS)), [f"{fw}\n(x: not reached)" for fw in FRAMEWORKS])
    ax.set_ylabel("episodes to threshold")
    ax.set_title("episodes to threshold per seed (line: median)")
    ax.grid(alpha=0.3, axis="y")
    save_figure(fig, out_dir / "episodes_to_threshold.png")


@dataclass(frozen=True)
class CompareResult:
    out_dir: Path
    """Where ``report.md``, ``result.json`` and the plots are."""
    verdict: str
    analysis: dict[str, Any]


def compare(
    name: str,
    seeds: list[int],
    *,
    variant: str = "faithful",
    runs_root: Path = Path("results"),
    out_root: Path = Path("results/compare"),
    matched_init: bool = False,
    episodes: int | None = None,
    command: str = "",
    workers: int | None = None,
) -> CompareResult:
    """Write ``<out_root>/<name>/report.md`` (``<out_root>/<name>/matched-init/`` with
    ``matched_init``: the torch runs start from the Keras runs' initial weights) from the
    run folders of ``seeds`` under ``runs_root``, which ``dispatch/compare_runs.py`` made.
    ``episodes``: the budget the runs had, if not the post's."""
    experiment = get_experiment(name)
    if compared_frameworks(name) != FRAMEWORKS:
        raise ConfigError(f"{name}'s frameworks are {frameworks(name)}; a report compares {FRAMEWORKS}")
    runs = {fw: load_runs(run_folder(runs_root, name, variant, fw, matched_init), seeds) for fw in FRAMEWORKS}
    for fw, rs in runs.items():
        unfinished = [r["seed"] for r in rs if r["summary"].status != "completed"]
        if unfinished:
            raise RunFolderError(f"{fw} runs of seeds {unfinished} did not finish; the comparison needs them all")
    config = experiment.config_cls.for_variant(variant, **({} if episodes is None else {"episodes": episodes}))
    result = analyse(runs, config.episodes)
    out_dir = Path(out_root) / name / ("matched-init" if matched_init else "")
    write_report(out_dir, experiment, variant, runs, result, config.threshold, command, matched_init, workers)
    return CompareResult(out_dir, verdict(result, len(seeds)), result)
