"""Check the committed evidence by sampling (issue 52, item 6): rerun K randomly drawn seeds of
every committed set with its recorded config and engine, and compare them with the committed
episodes, every column but wall time.

    python -m maintainers audit --per-set 1 --draw-seed 52 --out /tmp/audit [--workers 2] [--sets 'checks/*']
    python -m maintainers audit ... --write       # and results/AUDIT.md (with AUDIT.json), the committed report
    python -m maintainers audit ... --write --again   # every set rerun, the committed report's too
    python -m maintainers audit ... --address ADDR   # the reruns on a Ray cluster

(``python -m maintainers manifest --regenerate SET ... --address ADDR`` reruns whole sets the same way.)

The draw is fixed by ``--draw-seed``: the same seed draws the same seeds of the same sets. A
seed-batched set is drawn by batch (its seeds' bits depend on their batch mates): the whole
batch reruns and its drawn seed is compared. A set made at more than one commit draws a batch
of each, so that every code version is sampled. ``--write`` runs only at a committed tree (its
own report aside), and a committed result rerun at "HEAD + changes", or transcribed from an older
report without its JSON, is rerun. Each rerun goes
through ``manifest.reproduce_command``
(as ``manifest --regenerate``), at HEAD; a set that HEAD no longer makes the same bits for by
design (``AT_RECORDED_COMMIT``: a retired path, a fixed bug) reruns at its seed's recorded commit,
in a temporary ``git worktree`` with that commit's own ``keras_rl``, as ``keras-rl bisect`` does.
``--workers N`` audits N sets at once, each batch one job (on a Ray cluster with ``--address``).
Resumable: a rerun folder under ``--out`` resumes, and ``audit.json`` keeps each set's result as
it lands. With ``--write`` the committed report grows: a set that ``results/AUDIT.json`` holds with
this draw (the same draw seed, K and batches) keeps its result and its "rerun at" commit, and only
the sets added since rerun (``--again`` reruns them all); the report covers every committed set.
A seed that differs is explained where the host explains it (another CPU model or instruction set
than the run recorded, unless ``results/PLATFORMS.json`` lists this CPU as measured to give that
framework's bits: ``replay.why_not_bit_exact``); any other is a mismatch, and the command exits 1.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import shutil
import subprocess
import tempfile
import threading
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from keras_rl.errors import ConfigError
from keras_rl.runs.run_set import RunSet
from maintainers.checkout import ROOT
from maintainers.manifest import RESULTS, committed_sets, compare_seeds, manifest, reproduce_command

AT_RECORDED_COMMIT: dict[str, str] = {}
"""Set -> why HEAD no longer makes its bits by design; such a set reruns at its recorded commit.
Empty until an audit finds one (each entry needs the commit that changed the bits)."""
MADE_UNDER: dict[str, dict[str, str]] = {
    "checks/pendulum/twins/xla-fast-math": {"XLA_FLAGS": "--xla_cpu_enable_fast_math=true"},
}
"""Set -> the arithmetic's environment its queue set (``maintainers/queues/<queue>.tsv``) for a set made
before runs recorded it in their provenance (``provenance.arithmetic_environment``); a rerun sets it."""


def rerun_environment(set_name: str, provenance: dict) -> dict[str, str]:
    """The environment a rerun of a seed needs: the arithmetic's environment it was made under."""
    return {**MADE_UNDER.get(set_name, {}), **provenance.get("environment", {})}


def other_versions(summary: dict) -> str | None:
    """Why a seed cannot rerun here to its bits: the libraries it recorded are not this environment's
    (a set made under another TensorFlow, as a real change the twin check measures); else None."""
    from keras_rl.runs.provenance import library_versions

    here, theirs = library_versions(summary.get("framework", "keras")), summary.get("versions", {})
    differ = [
        f"{k} {theirs[k]} (here {here[k]})"
        for k in ("tensorflow", "keras", "torch")
        if k in theirs and k in here and theirs[k] != here[k]
    ]
    return f"made with {', '.join(differ)}" if differ else None


REPORT = RESULTS / "AUDIT.md"
RECORD = RESULTS / "AUDIT.json"
"""The committed report's results, set by set, as ``audit.json`` keeps them: what ``--write`` extends."""


def uncommitted() -> list[str]:
    """The tracked files that differ from HEAD, other than the report that ``--write`` rewrites as
    it goes (which made every set after the first read "+ changes" in an audit that began clean)."""
    own = [f":(exclude){(RESULTS / name).relative_to(ROOT)}" for name in ("AUDIT.md", "AUDIT.json")]
    subprocess.run(["git", "update-index", "-q", "--refresh"], cwd=ROOT, capture_output=True)  # touched, same bytes
    diff = subprocess.run(
        ["git", "diff-index", "--name-only", "HEAD", "--", ".", *own], cwd=ROOT, capture_output=True, text=True
    )
    if diff.returncode != 0:  # not a clean answer: never read as a clean tree
        raise ConfigError(f"cannot tell whether the tree is committed: git diff-index says {diff.stderr.strip()}")
    return diff.stdout.split()


def head_commit() -> str:
    """Where a rerun at HEAD ran: the commit, and "+ changes" where tracked files differ from it."""
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True)
    return f"HEAD {commit.stdout.strip()[:8]}" + (" + changes" if uncommitted() else "")


def kept(path: Path, draw_seed: int, per_set: int, drawn: dict[str, list[list[int]]]) -> dict[str, dict]:
    """The results in audit log ``path`` (set -> result) that this draw would make again: the same
    draw seed and K, and the same batches (a set that grew draws anew)."""
    import json

    if not path.is_file():
        return {}
    log = json.loads(path.read_text())
    if (log["draw_seed"], log["per_set"]) != (draw_seed, per_set):
        return {}
    return {r["set"]: r for r in log["results"] if drawn.get(r["set"]) == r["batches"]}


def at_committed_tree(results: dict[str, dict]) -> dict[str, dict]:
    """The results whose reruns ran at a committed tree and kept their own record: what the
    committed report keeps. A result rerun at "HEAD + changes", and one transcribed from an older
    report whose JSON was not kept, rerun (issue 72 item 17)."""
    return {name: r for name, r in results.items() if not r["at"].endswith("+ changes") and not r.get("transcribed")}


def draw(entries: list[dict], per_set: int, draw_seed: int) -> dict[str, list[list[int]]]:
    """Set -> the batches drawn from it (``per_set`` of them, or all it has). Each set's draw has a
    generator of its own, seeded by ``draw_seed`` and the set's name, so a set draws the same
    batches whichever other sets an audit takes (``--sets``). A set made at more than one commit
    (``batch_commits``) also draws ``per_set`` batches of each commit the first draw missed, so
    that every code version is sampled (issue 72 item 17)."""
    drawn = {}
    for entry in entries:
        batches = entry["batches"]
        rng = np.random.default_rng([draw_seed, zlib.crc32(entry["set"].encode())])
        picks = {int(p) for p in rng.choice(len(batches), size=min(per_set, len(batches)), replace=False)}
        commits = entry.get("batch_commits") or [None] * len(batches)
        for commit in sorted(set(commits) - {commits[i] for i in picks}):
            mine = [i for i, c in enumerate(commits) if c == commit]
            picks.update(int(p) for p in rng.choice(mine, size=min(per_set, len(mine)), replace=False))
        drawn[entry["set"]] = [batches[i] for i in sorted(picks)]
    return drawn


_GIT = threading.Lock()
"""``git worktree`` edits the repository's worktree list: one at a time across ``--workers`` threads."""


def _at_commit(commit: str, command: list[str], env: dict[str, str] | None = None) -> int:
    """Run ``command`` (a ``python -m keras_rl`` line, its paths absolute) with ``commit``'s own
    keras_rl: from a temporary worktree at that commit (``python -m`` puts the working folder
    first on the path, as ``keras-rl bisect`` relies on), removed afterwards."""
    worktree = Path(tempfile.mkdtemp(prefix="keras-rl-audit-"))
    shutil.rmtree(worktree)
    with _GIT:
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), commit], cwd=ROOT, check=True)
    try:
        env = {**(env if env is not None else os.environ), "PYTHONPATH": str(worktree)}
        return subprocess.run(command, cwd=worktree, env=env).returncode
    finally:
        with _GIT:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, check=False)


def audit_set(
    entry: dict, batches: list[list[int]], out: Path, workers: int, address: str | None = None, where: str = ""
) -> dict:
    """Rerun the drawn batches of one set and compare the drawn seeds (``where``: the tree they rerun
    at, read once when the audit began; ``head_commit()`` where not given)."""
    from maintainers.replay import why_not_bit_exact

    committed = RunSet(RESULTS / entry["set"])
    target = out / entry["set"]
    where = where or head_commit()
    codes = []
    for batch in batches:
        command = reproduce_command(entry, batch, out, workers, address)
        record = committed.run(batch[0]).summary_record()
        env = {**os.environ, **rerun_environment(entry["set"], record.get("provenance", {}))}
        if entry["set"] in AT_RECORDED_COMMIT:
            commit = record["provenance"]["commit"]
            where = f"recorded commit {commit[:8]} ({AT_RECORDED_COMMIT[entry['set']]})"
            codes.append(_at_commit(commit, command, env))
        else:
            codes.append(subprocess.run(command, cwd=ROOT, env=env).returncode)
    seeds = [batch[0] for batch in batches]
    diverged = compare_seeds(committed, target, seeds)
    result: dict = {"set": entry["set"], "seeds": seeds, "batches": batches, "at": where, "exit_codes": codes}
    result["by_seed"] = {}
    for seed, divergence in diverged.items():
        summary = committed.run(seed).summary_record()
        host = why_not_bit_exact(summary.get("provenance", {}), framework=entry["framework"]) or other_versions(summary)
        if divergence is not None and divergence["first_episode"] is None:
            verdict, why = "same bits", None
        elif divergence is None:
            verdict, why = "no rerun", "the rerun left no episodes.csv (see its exit code)"
        elif host is not None:
            verdict, why = "differs: host", f"the run was {host}"
        else:
            verdict, why = "MISMATCH", f"first differs at episode {divergence['first_episode']}"
        result["by_seed"][str(seed)] = {"verdict": verdict, "why": why, "divergence": divergence}
    result["mismatches"] = sum(v["verdict"] in ("MISMATCH", "no rerun") for v in result["by_seed"].values())
    return result


def markdown(results: list[dict], command: str, per_set: int, draw_seed: int, total: int) -> str:
    same = sum(v["verdict"] == "same bits" for r in results for v in r["by_seed"].values())
    host = sum(v["verdict"] == "differs: host" for r in results for v in r["by_seed"].values())
    bad = sum(r["mismatches"] for r in results)
    lines = [
        "# The committed evidence, audited by sampling",
        "",
        f"Generated by `{command}` (`maintainers/audit.py`): {per_set} seed(s) of every committed set drawn "
        f"with random seed {draw_seed}, each rerun with its set's recorded config and engine and compared "
        "with the committed episodes, every column but wall time. Each row names the commit its seed "
        "was rerun at: `--write` reruns only the sets that `results/AUDIT.json` (this report's results) "
        "lacks for this draw, and `--again` reruns them all.",
        "",
        f"{len(results)} of {total} sets audited: {same} seed(s) the same bits, {host} differing where the host "
        f"explains it (another CPU or instruction set than the run recorded), **{bad} mismatch(es)**.",
        "",
        "| set | seeds drawn (batch) | rerun at | verdict |",
        "|---|---|---|---|",
    ]
    for r in results:
        for (seed, v), batch in zip(r["by_seed"].items(), r["batches"]):
            shown = seed if len(batch) == 1 else f"{seed} (batch {batch[0]}-{batch[-1]})"
            verdict = v["verdict"] + (f": {v['why']}" if v["why"] else "")
            lines.append(f"| `{r['set']}` | {shown} | {r['at']} | {verdict} |")
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    from keras_rl.atomic import atomic_write_json, atomic_write_text

    if args.per_set < 1:
        raise ConfigError(f"--per-set must be at least 1, got {args.per_set}")
    if args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if args.out is None:
        raise ConfigError("audit needs --out: a fresh folder, or one to resume")
    if args.again and not args.write:
        raise ConfigError("--again reruns the sets the committed report holds: it needs --write")
    changed = uncommitted()
    if args.write and changed:
        raise ConfigError(
            f"--write reruns the committed report's seeds at a committed tree, and {len(changed)} tracked file(s) "
            f"differ from HEAD ({', '.join(changed[:3])}{', ...' if len(changed) > 3 else ''}): commit them, or "
            "audit from a clean worktree"
        )
    where = head_commit()
    args.out = args.out.resolve()  # the reruns' paths hold from any working folder (a worktree's too)
    if args.out.is_relative_to(RESULTS.resolve()):
        raise ConfigError("--out must not be inside results/: the reruns are compared with it, never written over it")
    if args.sets and not any(  # named at once, before the manifest reads every set
        fnmatch.fnmatch(s.folder.relative_to(RESULTS).as_posix(), p) for s in committed_sets() for p in args.sets
    ):
        raise ConfigError(f"no committed set matches {' '.join(args.sets)} (python -m maintainers manifest)")
    every = manifest()
    entries = [e for e in every if any(fnmatch.fnmatch(e["set"], p) for p in args.sets)] if args.sets else every
    drawn = draw(every, args.per_set, args.draw_seed)
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "audit.json"
    command = (
        f"python -m maintainers audit --per-set {args.per_set} --draw-seed {args.draw_seed} --workers {args.workers}"
        + (" --sets " + " ".join(f"'{p}'" for p in args.sets) if args.sets else "")
        + " --out OUT"
        + (" --write" if args.write else "")
    )
    # what --write extends (the committed report's sets), then what this --out holds already
    committed = (
        at_committed_tree(kept(RECORD, args.draw_seed, args.per_set, drawn)) if args.write and not args.again else {}
    )
    resumed = kept(log, args.draw_seed, args.per_set, drawn)
    finished = {**committed, **(at_committed_tree(resumed) if args.write else resumed)}
    todo = [e for e in entries if e["set"] not in finished]
    covered = every if args.write else entries  # the committed report covers every set
    lock = threading.Lock()

    def one(entry: dict) -> None:
        batches = drawn[entry["set"]]
        # a set's batch is one job: --workers sets at once (on Ray, each job on the cluster)
        result = audit_set(entry, batches, args.out, 1, args.address, where)
        with lock:
            finished[entry["set"]] = result
            report(finished)
            print(f"[{len(finished)}/{len(covered)}] {entry['set']}: seeds {[b[0] for b in batches]}", flush=True)

    def report(finished: dict) -> str:
        """audit.json, audit.md (and with --write results/AUDIT.md and AUDIT.json) as they stand: a
        stopped audit leaves a true report of the sets it did."""
        ordered = [finished[e["set"]] for e in covered if e["set"] in finished]
        record = {"draw_seed": args.draw_seed, "per_set": args.per_set, "results": ordered}
        atomic_write_json(log, record)
        text = markdown(ordered, command, args.per_set, args.draw_seed, len(covered))
        atomic_write_text(args.out / "audit.md", text)
        if args.write:
            atomic_write_json(RECORD, record)
            atomic_write_text(REPORT, text)
        return text

    with ThreadPoolExecutor(max_workers=args.workers) as pool:
        list(pool.map(one, todo))
    results = [finished[e["set"]] for e in covered if e["set"] in finished]
    print(report(finished))
    return 1 if any(r["mismatches"] for r in results) else 0
