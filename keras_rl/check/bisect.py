"""``keras-rl bisect GOOD BAD [EXPERIMENT ...]``: the first commit whose learner the check calls
changed, found by ``git bisect`` with the sequential ``keras-rl check --sequential`` as its test
(``--fixed-n``: the fixed rule instead).

- The repository is never touched: bisect runs in a temporary ``git worktree`` at each commit,
  and the commit's own ``keras-rl check`` runs there (``python -m keras_rl`` from the worktree).
- The baseline stays outside the tree bisect rewrites: ``--against`` (default: this checkout's
  ``results/checks``) is copied to ``<out>/baseline`` before the first step.
- The error is controlled over all the steps: a bisect of n commits tests at most
  ceil(log2 n) of them, plus BAD itself, which is checked first (is there anything to find?).
  Each step tests at ``alpha / steps`` (Bonferroni), so the chance that any step of the whole
  bisect raises a false alarm is at most alpha. Within a step, the sequential check splits its
  share over the posts and each post's looks (``check --sequential --alpha``: seeds in looks of
  5, a clear regression stops at the first look, so a step costs few seeds where bisect needs
  it); the fixed rule adjusts the posts by Holm.
- Each step's evidence (commit, subject, each post's p and adjusted p, the verdict) goes to
  ``<out>/bisect.json`` and ``bisect.md``; the step's own check report to ``<out>/step_<k>``.
- A step whose check gives no verdict (a crash, exit 3, or a commit whose check cannot run) is
  skipped (``git bisect skip``); it spends no alpha, since it cannot raise an alarm. Where skips
  leave git unable to choose, or the decided checks reach their budget, the report lists the
  commits the first changed one may be.

Exit codes: 0 the first changed commit was found; 1 BAD is consistent with the baseline (there
is nothing to bisect); 2 usage; 3 no verdict (skips left bisect without an answer).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

from keras_rl.atomic import atomic_write_json, atomic_write_text
from keras_rl.check.statistics import holm_adjusted
from keras_rl.errors import ConfigError, argument
from keras_rl.runs.signals import stop_signals_deferred


@dataclass
class Step:
    commit: str
    subject: str
    verdict: str  # "changed", "consistent" or "no verdict"
    p: dict[str, float] = field(default_factory=dict)
    """Each post's p: the fixed rule's, or the sequential check's at its last look."""
    adjusted_p: dict[str, float] = field(default_factory=dict)
    """Holm-adjusted (the fixed rule only)."""
    seeds: dict[str, int] = field(default_factory=dict)
    """Fresh seeds each post used (the sequential check stops early)."""
    note: str = ""


@dataclass
class BisectResult:
    good: str
    bad: str
    commits: int
    alpha: float
    alpha_per_step: float
    steps: list[Step]
    first_changed: str | None
    outcome: str  # "found", "bad is consistent", "no verdict"
    sequential: bool = True
    candidates: list[str] = field(default_factory=list)
    """Where skipped commits leave git unable to choose: the first changed commit is one of these."""


def git(repo: Path, *args: str, check: bool = True) -> str:
    done = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True)
    if check and done.returncode != 0:
        raise ConfigError(f"git {' '.join(args)} failed in {repo}: {done.stderr.strip()}")
    return done.stdout.strip()


def resolve(repo: Path, good: str, bad: str) -> tuple[str, str, int]:
    """Both commits, checked: GOOD an ancestor of BAD, with commits between them."""
    if git(repo, "rev-parse", "--is-inside-work-tree", check=False) != "true":
        raise ConfigError(f"{repo} is not a git repository")
    shas = []
    for name, ref in (("GOOD", good), ("BAD", bad)):
        sha = git(repo, "rev-parse", "--verify", "--quiet", f"{ref}^{{commit}}", check=False)
        if not sha:
            raise ConfigError(f"{name} {ref!r} is not a commit of {repo}")
        shas.append(sha)
    good_sha, bad_sha = shas
    ancestor = subprocess.run(["git", "merge-base", "--is-ancestor", good_sha, bad_sha], cwd=repo).returncode == 0
    if not ancestor:
        raise ConfigError(f"GOOD {good} is not an ancestor of BAD {bad}")
    commits = int(git(repo, "rev-list", "--count", f"{good_sha}..{bad_sha}"))
    if commits == 0:
        raise ConfigError(f"GOOD {good} and BAD {bad} are the same commit: nothing to bisect")
    return good_sha, bad_sha, commits


def step_budget(commits: int) -> int:
    """Checks a bisect of ``commits`` commits may make: BAD first, then ceil(log2 n)."""
    return 1 + max(1, math.ceil(math.log2(commits)))


def check_commit(worktree: Path, experiments: list[str], tier: str, against: Path, out: Path, extra: list[str]):
    """Run the worktree's own ``keras-rl check``; its report's posts, or None (no verdict) and why."""
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "keras_rl", "check", *experiments, "--tier", tier, "--against", str(against)]
    done = subprocess.run(
        [*command, "--out", str(out), *extra], cwd=worktree, capture_output=True, text=True, env=_env(worktree)
    )
    report = out / "check.json"
    if done.returncode not in (0, 1) or not report.is_file():
        return None, f"check exited {done.returncode}: {done.stderr.strip().splitlines()[-1:] or ''}"
    return json.loads(report.read_text())["experiments"], ""


def _env(worktree: Path) -> dict[str, str]:
    import os

    return {**os.environ, "PYTHONPATH": str(worktree)}  # the commit's own keras_rl, not the installed one


def judge(p: dict[str, float], alpha: float) -> tuple[str, dict[str, float]]:
    names = list(p)
    adjusted = dict(zip(names, holm_adjusted([p[n] for n in names])))
    return ("changed" if min(adjusted.values()) < alpha else "consistent"), adjusted


def bisect(
    repo: Path,
    good: str,
    bad: str,
    experiments: list[str],
    tier: str,
    against: Path,
    out: Path,
    alpha: float = 0.01,
    extra: list[str] | None = None,
    log=print,
    sequential: bool = True,
) -> BisectResult:
    good_sha, bad_sha, commits = resolve(repo, good, bad)
    if not (against / experiments[0] / "baseline").is_dir():
        raise ConfigError(f"{argument('against', against)} holds no {experiments[0]}/baseline")
    out.mkdir(parents=True, exist_ok=True)
    baseline = out / "baseline"
    if baseline.exists():
        shutil.rmtree(baseline)
    shutil.copytree(against, baseline)  # outside the tree bisect rewrites
    per_step = alpha / step_budget(commits)
    result = BisectResult(good_sha, bad_sha, commits, alpha, per_step, [], None, "no verdict", sequential=sequential)
    if sequential:  # each step's check spends exactly its share: the union bound over posts and looks
        extra = ["--sequential", "--alpha", repr(per_step), *(extra or [])]
    worktree = Path(tempfile.mkdtemp(prefix="keras-rl-bisect-"))
    shutil.rmtree(worktree)
    try:
        with stop_signals_deferred():  # a signal during the add lands after it, inside this try
            git(repo, "worktree", "add", "--detach", str(worktree), bad_sha)
        log(f"bisect: {commits} commits, at most {step_budget(commits)} checks, each at alpha {per_step:.3g}")
        verdict = _step(result, worktree, experiments, tier, baseline, out, extra or [], log)
        if verdict != "changed":
            result.outcome = "bad is consistent" if verdict == "consistent" else "no verdict"
            return result
        text = git(worktree, "bisect", "start", bad_sha, good_sha)
        while "is the first bad commit" not in text:
            if sum(s.verdict != "no verdict" for s in result.steps) >= step_budget(commits):
                result.outcome = "no verdict"  # more decided checks would spend more than alpha
                result.candidates = git(worktree, "bisect", "visualize", "--format=%H", check=False).split()
                return result
            verdict = _step(result, worktree, experiments, tier, baseline, out, extra or [], log)
            mark = {"changed": "bad", "consistent": "good"}.get(verdict, "skip")
            text = git(worktree, "bisect", mark, check=False)
            if "only 'skip'ped commits left" in text or "cannot bisect" in text.lower():
                result.outcome = "no verdict"
                result.candidates = [
                    w for w in text.split() if len(w) == 40 and all(c in "0123456789abcdef" for c in w)
                ]
                return result
        result.first_changed = text.split()[0]
        result.outcome = "found"
        return result
    finally:
        with stop_signals_deferred(reraise=False):  # a second signal does not cut the clean-up short
            remove_worktree(repo, worktree)
            write_report(out, result)


def remove_worktree(repo: Path, worktree: Path) -> None:
    """The temporary worktree, gone from the disk and from ``git worktree list``, whatever
    state a stop left it in (added or half-added)."""
    if worktree.exists():
        git(worktree, "bisect", "reset", check=False)
    git(repo, "worktree", "remove", "--force", str(worktree), check=False)
    shutil.rmtree(worktree, ignore_errors=True)
    git(repo, "worktree", "prune", check=False)


def _step(result: BisectResult, worktree: Path, experiments, tier, baseline, out, extra, log) -> str:
    commit = git(worktree, "rev-parse", "HEAD")
    subject = git(worktree, "log", "-1", "--format=%s")
    k = len(result.steps) + 1
    posts, why = check_commit(worktree, experiments, tier, baseline, out / f"step_{k}", extra)
    if posts is None:
        step = Step(commit, subject, "no verdict", note=why)
    else:
        p = {e["experiment"]: float(e["decision"]["p"]) for e in posts}
        seeds = {e["experiment"]: len(e["new"]) for e in posts}
        if result.sequential:  # the check's own verdict: its levels already carry this step's share
            verdict = "changed" if any(e["decision"]["changed"] for e in posts) else "consistent"
            step = Step(commit, subject, verdict, p, seeds=seeds)
        else:
            verdict, adjusted = judge(p, result.alpha_per_step)
            step = Step(commit, subject, verdict, p, adjusted, seeds)
    result.steps.append(step)
    write_report(out, result)
    shown = evidence(step)
    log(f"step {k}: {commit[:10]} {subject[:50]!r}: {step.verdict} ({shown})")
    return step.verdict


def evidence(step: Step) -> str:
    """One step's evidence by post: the Holm-adjusted p (fixed rule), or the last look's p and
    the seeds it took (sequential); or why the step gave no verdict."""
    if step.adjusted_p:
        return ", ".join(f"{n} {v:.3g}" for n, v in step.adjusted_p.items())
    if step.p:
        return ", ".join(f"{n} {v:.3g} ({step.seeds.get(n, '?')} seeds)" for n, v in step.p.items())
    return step.note


def write_report(out: Path, result: BisectResult) -> None:
    atomic_write_json(out / "bisect.json", asdict(result))
    lines = [
        "# keras-rl bisect",
        "",
        f"GOOD {result.good[:10]}, BAD {result.bad[:10]}: {result.commits} commits. Overall alpha "
        f"{result.alpha}, each check at {result.alpha_per_step:.3g} (alpha over the {step_budget(result.commits)} "
        "checks a bisect may make, Bonferroni); "
        + (
            "each check sequential (`check --sequential --alpha`: its share split over the posts and each "
            "post's looks of 5 seeds).",
            "the posts within a check adjusted by Holm.",
        )[not result.sequential],
        "",
        "| step | commit | subject | "
        + ("p at the last look (seeds)", "Holm-adjusted p by post")[not result.sequential]
        + " | verdict |",
        "|---|---|---|---|---|",
    ]
    for k, s in enumerate(result.steps, 1):
        lines.append(f"| {k} | `{s.commit[:10]}` | {s.subject} | {evidence(s)} | {s.verdict} |")
    found = f"the first changed commit is `{result.first_changed}`" if result.first_changed else result.outcome
    if result.candidates:
        found += "; the first changed commit is one of " + ", ".join(f"`{c[:10]}`" for c in result.candidates)
    lines += ["", f"Outcome: **{found}**.", ""]
    atomic_write_text(out / "bisect.md", "\n".join(lines))
