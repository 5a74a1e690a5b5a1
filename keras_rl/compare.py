"""``keras-rl compare``: the same seeds in Keras and in PyTorch, and what differs.

Run folders are reused when they exist for the same config and code version; a folder
made with another config or code version is never silently merged: the command refuses
and says which field differs (``--rerun`` replaces such folders).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.errors import ConfigError, RunFolderError
from keras_rl.experiments import Experiment, get_experiment, metric_label
from keras_rl.results import atomic_write_json, atomic_write_text, plt, read_episodes, save_figure
from keras_rl.stats import fisher_exact, iqm_ci, mann_whitney, median_difference_ci

FRAMEWORKS = ("keras", "torch")
IGNORED_FIELDS = {"seed", "framework"}


def run_folder(runs_root: Path, experiment: str, variant: str, framework: str, matched_init: bool = False) -> Path:
    """``results/<experiment>/<variant>[-torch[-matched-init]]``, as ``keras-rl reproduce`` names them."""
    suffix = "" if framework == "keras" else f"-{framework}" + ("-matched-init" if matched_init else "")
    return Path(runs_root) / experiment / f"{variant}{suffix}"


def framework_overrides(framework: str, matched_init: bool) -> dict[str, Any]:
    return {"framework": framework, "matched_init": matched_init and framework == "torch"}


_MISSING = object()


def _field_defaults(config_dict: dict[str, Any]) -> dict[str, Any]:
    """The defaults of the config class that ``config_dict`` belongs to (as JSON values)."""
    import dataclasses

    from keras_rl.configs import CONFIGS

    cls = CONFIGS.get(config_dict.get("experiment"))
    if cls is None:
        return {}
    return json.loads(json.dumps({f.name: f.default for f in dataclasses.fields(cls)
                                  if f.default is not dataclasses.MISSING}))


def check_reusable(seed_dir: Path, expected: dict[str, Any], code_version: str) -> str | None:
    """None if ``seed_dir`` holds a finished run of ``expected``; else why it cannot be reused.

    Raises RunFolderError for a run of a *different* config or code version.
    """
    if not (seed_dir / "summary.json").is_file():
        return "missing"
    try:
        config = json.loads((seed_dir / "config.json").read_text())
        summary = json.loads((seed_dir / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        raise RunFolderError(f"{seed_dir} is corrupt ({exc}); delete it or pass --rerun") from None
    expected = json.loads(json.dumps(expected))  # compare as config.json stores it (tuples -> lists)
    defaults = _field_defaults(expected)
    # A field added to the config after the run was made is absent from its config.json;
    # the run used that field's default behaviour, so it matches only if the default is wanted.
    differing = sorted(k for k in expected if k not in IGNORED_FIELDS
                       and config.get(k, defaults.get(k, _MISSING)) != expected[k])
    if differing:
        raise RunFolderError(
            f"{seed_dir} was made with a different config ({', '.join(f'{k}={config.get(k)!r} here, {expected[k]!r} wanted' for k in differing[:3])}); "
            "refusing to mix runs: pass --rerun to replace it, or --runs to use another folder")
    theirs = summary.get("versions", {}).get("keras_rl")
    if theirs != code_version:
        raise RunFolderError(f"{seed_dir} was made by keras_rl {theirs}, this is {code_version}; "
                             "refusing to mix code versions: pass --rerun to replace it")
    if summary.get("status") != "completed":
        return f"unfinished ({summary.get('status')})"
    return None


def gather(experiment: Experiment, variant: str, seeds: list[int], runs_root: Path, rerun: bool,
           reuse_only: bool, overrides: dict[str, Any], matched_init: bool = False) -> dict[str, list[int]]:
    """For each framework, the seed folders to use and the jobs still to run."""
    from keras_rl import __version__

    todo: dict[str, list[int]] = {}
    for framework in FRAMEWORKS:
        base = experiment.config_cls.for_variant(variant, **framework_overrides(framework, matched_init), **overrides)
        folder = run_folder(runs_root, experiment.name, variant, framework, matched_init)
        todo[framework] = []
        for seed in seeds:
            expected = base.replace(seed=seed).to_dict()
            seed_dir = folder / f"seed_{seed}"
            reason = "rerun" if rerun else check_reusable(seed_dir, expected, __version__)
            if reason is not None:
                todo[framework].append(seed)
    if reuse_only:
        missing = {fw: s for fw, s in todo.items() if s}
        if missing:
            have = {fw: sorted(set(seeds) - set(s)) for fw, s in todo.items()}
            raise RunFolderError(f"mismatched seed sets: {', '.join(f'{fw} lacks seeds {s}' for fw, s in missing.items())} "
                                 f"(reusable: {have}); run without --reuse-only to make them")
    return todo


def load_runs(folder: Path, seeds: list[int]) -> list[dict[str, Any]]:
    runs = []
    for seed in seeds:
        seed_dir = folder / f"seed_{seed}"
        summary = json.loads((seed_dir / "summary.json").read_text())
        runs.append({"seed": seed, "summary": summary, "rows": read_episodes(seed_dir / "episodes.csv")})
    return runs


def analyse(runs: dict[str, list[dict[str, Any]]], budget: int) -> dict[str, Any]:
    """Every number in the report, computed from the run folders' CSVs and summaries."""
    out: dict[str, Any] = {"frameworks": {}}
    reached = {}
    for framework, rs in runs.items():
        hits = [r["summary"]["reached_at_episode"] for r in rs if r["summary"]["success"]]
        final = [r["rows"][-1]["metric"] for r in rs]
        ms = [r["summary"]["wall_seconds"] / max(r["summary"]["total_steps"], 1) * 1e3 for r in rs]
        reached[framework] = hits
        q25, q50, q75 = (np.percentile(hits, [25, 50, 75]) if hits else (np.nan,) * 3)
        out["frameworks"][framework] = {
            "seeds": [r["seed"] for r in rs], "successes": sum(bool(r["summary"]["success"]) for r in rs),
            "episodes_to_threshold": hits, "median": float(q50), "q25": float(q25), "q75": float(q75),
            "final": final, "final_iqm": iqm_ci(final, np.random.default_rng(0)),
            "wall_seconds_median": float(np.median([r["summary"]["wall_seconds"] for r in rs])),
            "ms_per_step_median": float(np.median(ms)),
        }
    a, b = reached["keras"], reached["torch"]
    out["median_difference"] = (median_difference_ci(a, b, np.random.default_rng(0)) if a and b else None)
    out["mann_whitney"] = mann_whitney(a, b)
    k, t = out["frameworks"]["keras"], out["frameworks"]["torch"]
    out["fisher_p"] = fisher_exact(k["successes"], len(k["seeds"]), t["successes"], len(t["seeds"]))
    out["budget"] = budget
    return out


def verdict(result: dict[str, Any], n: int) -> str:
    diff, (_, p) = result["median_difference"], result["mann_whitney"]
    k, t = result["frameworks"]["keras"], result["frameworks"]["torch"]
    rates = f"success {k['successes']}/{n} (Keras) vs {t['successes']}/{n} (PyTorch), Fisher p = {result['fisher_p']:.2f}"
    if result["fisher_p"] < 0.05:
        more = "Keras" if k["successes"] > t["successes"] else "PyTorch"
        return f"The frameworks differ: {more} succeeds more often ({rates}, {n} seeds each)."
    if diff is None or not np.isfinite(p):
        return (f"No detectable difference in success ({rates}), and too few successes to compare "
                "episodes-to-threshold: no verdict on speed of learning.")
    excludes_zero = diff.low > 0 or diff.high < 0
    if p < 0.05 and excludes_zero:
        faster = "Keras" if diff.estimate < 0 else "PyTorch"
        return (f"The frameworks differ: {faster} reaches the threshold sooner (median difference {diff}, "
                f"Mann-Whitney p = {p:.3f}, {n} seeds each; {rates}).")
    return (f"No detectable difference between the frameworks at {n} seeds: {rates}; the median difference in "
            f"episodes to threshold is {diff} (95% bootstrap CI includes 0) and Mann-Whitney p = {p:.2f}; "
            f"a difference smaller than that interval could still exist.")


def _jsonable(value: Any) -> Any:
    """The analysis as plain JSON (intervals as {estimate, low, high}; NaN as null)."""
    import dataclasses

    if dataclasses.is_dataclass(value):
        return _jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def write_report(out_dir: Path, experiment: Experiment, variant: str, runs: dict[str, list[dict[str, Any]]],
                 result: dict[str, Any], threshold: float, command: str, matched_init: bool = False) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    n = len(runs["keras"])
    fmt = lambda v: "n/a" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:g}"  # noqa: E731
    init = ("matched init: each torch run starts from its Keras twin's initial weights, so only the framework differs"
            if matched_init else "default init: each framework initialises its networks its own way, as a user of it would get")
    lines = [f"# {experiment.name} ({variant}): Keras vs PyTorch, {n} seeds", "", f"Initialisation: {init}.", "",
             f"Seeds: {', '.join(str(r['seed']) for r in runs['keras'])}. "
             f"Success: {runs['keras'][0]['summary']['criterion']}. Command: `{command}`", "",
             "| framework | success | episodes to threshold: median | IQR | final metric IQM [95% CI] | wall s per seed (median) | ms/step (median) |",
             "|---|---|---|---|---|---|---|"]
    for fw in FRAMEWORKS:
        f = result["frameworks"][fw]
        lines.append(f"| {fw} | {f['successes']}/{n} | {fmt(f['median'])} | {fmt(f['q25'])}-{fmt(f['q75'])} "
                     f"| {f['final_iqm']} | {f['wall_seconds_median']:.1f} | {f['ms_per_step_median']:.3f} |")
    u, p = result["mann_whitney"]
    lines += ["", f"- Success rates, keras vs torch: Fisher exact test (two-sided) p = {fmt(result['fisher_p'])}.",
              f"- Median episodes-to-threshold, keras minus torch: {result['median_difference'] or 'n/a'} "
              "(percentile bootstrap, 10000 resamples, 95%).",
              f"- Mann-Whitney U (keras vs torch episodes-to-threshold, two-sided): U = {fmt(u)}, p = {fmt(p)}.",
              "- Final metric IQM: interquartile mean over seeds with a stratified-bootstrap 95% CI (rliable's method; "
              "one task, so the strata are the one task).",
              "- Wall time and ms/step come from each run's summary, as the runs ran: two seeds at a time on two "
              "cores, sometimes beside other work, and not always at the same time for both frameworks. Read them "
              "loosely; `benchmarks/step_time.py` measures speed in one process.",
              "", f"**Verdict.** {verdict(result, n)}", "",
              "![curves](curves.png) ![episodes to threshold](episodes_to_threshold.png)", ""]
    atomic_write_text(out_dir / "report.md", "\n".join(lines))
    atomic_write_json(out_dir / "result.json", _jsonable({
        "experiment": experiment.name, "variant": variant, "matched_init": matched_init, "command": command,
        "verdict": verdict(result, n), **result}))

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for fw, color in zip(FRAMEWORKS, ("tab:blue", "tab:orange")):
        length = max(len(r["rows"]) for r in runs[fw])
        curves = np.full((len(runs[fw]), length), np.nan)
        for i, r in enumerate(runs[fw]):
            values = [row["metric"] for row in r["rows"]]
            curves[i, :len(values)] = values
        curves[~np.isfinite(curves)] = np.nan
        episodes = np.arange(1, length + 1)
        q25, q50, q75 = np.nanpercentile(curves, [25, 50, 75], axis=0)
        ax.plot(episodes, q50, color=color, label=f"{fw} median")
        ax.fill_between(episodes, q25, q75, color=color, alpha=0.25, label=f"{fw} IQR")
    ax.axhline(threshold, color="tab:red", ls="--", lw=1, label=f"threshold {threshold:g}")
    ax.set_xlabel("episode")
    ax.set_ylabel(metric_label(experiment, experiment.config_cls.for_variant(variant)))
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


def compare(name: str, seeds: list[int], variant: str = "faithful", workers: int = 1, runs_root: Path = Path("results"),
            out_root: Path = Path("results/compare"), rerun: bool = False, reuse_only: bool = False,
            episodes: int | None = None, progress: bool = True, command: str = "", matched_init: bool = False) -> Path:
    """Write ``<out_root>/<name>/report.md`` (``<out_root>/<name>/matched-init/`` with
    ``matched_init``: the torch runs start from the Keras runs' initial weights)."""
    from keras_rl.cli import _run_in_processes, _run_one
    from keras_rl.torch import require_torch

    experiment = get_experiment(name)
    if "torch" not in experiment.config_cls.FRAMEWORKS:
        raise ConfigError(f"{name} has no PyTorch version yet, so there is nothing to compare it with "
                          f"(frameworks: {', '.join(experiment.config_cls.FRAMEWORKS)})")
    require_torch()
    overrides = {} if episodes is None else {"episodes": episodes}
    todo = gather(experiment, variant, seeds, runs_root, rerun, reuse_only, overrides, matched_init)
    jobs = []
    for framework, missing in todo.items():
        base = experiment.config_cls.for_variant(variant, **framework_overrides(framework, matched_init), **overrides)
        folder = run_folder(runs_root, name, variant, framework, matched_init)
        jobs += [(name, base.replace(seed=s).to_dict(), str(folder / f"seed_{s}"), progress, i % workers)
                 for i, s in enumerate(missing)]
    if jobs:
        if workers > 1 and len(jobs) > 1:
            interrupted = _run_in_processes(jobs, workers)
        else:
            interrupted = False
            for job in jobs:
                if _run_one(job)["status"] == "interrupted":
                    interrupted = True
                    break
        if interrupted:
            raise KeyboardInterrupt
    runs = {fw: load_runs(run_folder(runs_root, name, variant, fw, matched_init), seeds) for fw in FRAMEWORKS}
    for fw, rs in runs.items():
        unfinished = [r["seed"] for r in rs if r["summary"]["status"] != "completed"]
        if unfinished:
            raise RunFolderError(f"{fw} runs of seeds {unfinished} did not finish; the comparison needs them all")
    config = experiment.config_cls.for_variant(variant, **overrides)
    result = analyse(runs, config.episodes)
    out_dir = Path(out_root) / name / ("matched-init" if matched_init else "")
    write_report(out_dir, experiment, variant, runs, result, config.threshold, command, matched_init)
    return out_dir
