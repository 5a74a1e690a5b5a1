"""Every committed run set under ``results/``, with what made it and what it cost; and one
resumable command that reruns them (all, or those named) into a fresh folder and says, set by
set, whether the rerun agrees with what is committed.

    python -m maintainers manifest                      # print the manifest
    python -m maintainers manifest --write              # results/MANIFEST.md and MANIFEST.json
    python -m maintainers manifest --regenerate 'pendulum/faithful' 'checks/*/baseline' --out /tmp/rerun [--workers 2]

A set is a folder of ``seed_<n>/`` run folders. Its cost is in process-minutes: a seed run
alone costs its wall time, a seed batch (``--seed-batch``) the wall time of the batch, once.

``--regenerate`` reruns each set with ``keras-rl reproduce --config <seed>/config.json`` (the exact
config, whichever command made it, on the engine the set recorded; on a Ray cluster with
``--address``), batch by batch as the set was made (the batch's seeds are
in each summary, or else in its command's ``--seeds``/``--seed-batch``), with ``--resume``: a
rerun stopped midway continues where it was. Then, per set: where the CPU model and the library
versions match the committed runs, every seed must be bit for bit the same (``episodes.csv``
but for wall time; the first differing episode otherwise); where they do not, the two sets are
compared as distributions (two-sided Mann-Whitney on each seed's final metric). The verdicts go
to ``<out>/rerun.md`` and ``rerun.json``.
"""

from __future__ import annotations

import argparse
import fnmatch
import functools
import json
import shlex
import subprocess
import sys
from pathlib import Path

from keras_rl.errors import ConfigError
from keras_rl.runs.run_set import RunSet, SeedRun
from maintainers.checkout import ROOT

RESULTS = ROOT / "results"


def tracked_folders(results: Path = RESULTS) -> set[Path]:
    """Every folder under ``results`` that holds a file git tracks: the committed evidence. A run
    someone left there (live seed folders of their own) is not evidence, and is never read as it."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--", "."], cwd=results, capture_output=True, text=True, check=False
    )
    if listed.returncode != 0:
        raise ConfigError(
            f"{results} is not in a git checkout ({listed.stderr.strip()}): committed sets are what git tracks"
        )
    return {(results / name).parent for name in listed.stdout.split("\0") if name}


def committed_sets(results: Path = RESULTS) -> list[RunSet]:
    """The run sets under ``results`` that git tracks (packed, or seed folders committed as such)."""
    folders = tracked_folders(results)
    return [
        run_set
        for run_set in RunSet.find(results)
        if run_set.folder in folders or any(seed in folders for seed in run_set.seed_dirs())
    ]


def find_sets(results: Path = RESULTS) -> dict[str, list[SeedRun]]:
    """Set (its path under results/) -> its seeds, in seed order: the sets git tracks."""
    sets = {run_set.folder.relative_to(results).as_posix(): run_set.runs() for run_set in committed_sets(results)}
    return dict(sorted(sets.items()))


@functools.lru_cache(maxsize=4096)
def _argv(command: str) -> tuple[str, ...]:
    """``command`` split as a shell would (once per command: a set's seeds mostly share one)."""
    return tuple(shlex.split(command))


def _flag(argv: tuple[str, ...], name: str) -> str | None:
    return argv[argv.index(name) + 1] if name in argv and argv.index(name) + 1 < len(argv) else None


def batch_of(summary: dict) -> list[int]:
    """The seeds a seed was trained with (itself alone, unless seed-batched)."""
    recorded = summary.get("provenance", {}).get("seed_batch")
    if recorded:
        return [int(s) for s in recorded]
    argv = _argv(summary.get("command", ""))
    size = int(_flag(argv, "--seed-batch") or 1)
    seeds_text = _flag(argv, "--seeds")
    from keras_rl.learners.table import RETIRED, STACKED

    batched = {*STACKED, *RETIRED}  # a set made before its stacked learner was retired batched too
    if size <= 1 or seeds_text is None or (summary["experiment"], summary.get("framework", "keras")) not in batched:
        return [int(summary["seed"])]
    from keras_rl.cli import parse_seeds

    seeds = parse_seeds(seeds_text)
    for i in range(0, len(seeds), size):
        if int(summary["seed"]) in seeds[i : i + size]:
            return seeds[i : i + size]
    return [int(summary["seed"])]


def describe(name: str, runs: list[SeedRun]) -> dict:
    summaries = [r.summary_record() for r in runs]
    batches: dict[tuple[int, ...], float] = {}
    made_at: dict[tuple[int, ...], str] = {}
    for s in summaries:
        key = tuple(batch_of(s))
        batches[key] = max(batches.get(key, 0.0), float(s.get("wall_seconds") or 0.0))
        made_at[key] = str(s.get("provenance", {}).get("commit"))[:8]
    first = summaries[0]
    versions = {"batch_commits": [made_at[b] for b in batches]} if len(set(made_at.values())) > 1 else {}
    return {
        "set": name,
        "experiment": first["experiment"],
        "variant": first["variant"],
        "framework": first.get("framework", "keras"),
        "engine": first.get("provenance", {}).get("engine", "gymnasium"),
        "seeds": [int(s["seed"]) for s in summaries],
        "batches": [list(b) for b in batches],
        "commands": sorted({s.get("command", "") for s in summaries}),
        "commits": sorted({str(s.get("provenance", {}).get("commit")) for s in summaries}),
        "cpu_models": sorted({str(s.get("provenance", {}).get("cpu_model")) for s in summaries}),
        "versions": first.get("versions", {}),
        "status": dict(
            sorted({st: sum(s["status"] == st for s in summaries) for st in {s["status"] for s in summaries}}.items())
        ),
        "episodes": sum(int(s.get("episodes_run") or 0) for s in summaries),
        "process_minutes": round(sum(batches.values()) / 60, 1),
        "longest_job_minutes": round(max(batches.values()) / 60, 1),
        **versions,  # a set made at more than one commit: each batch's
    }


def run_head(run: SeedRun) -> str:
    """What two seed runs must share to be the same run, short of their episodes: the config
    (the seed in it) and the seeds it was batched with."""
    return json.dumps([run.config(), batch_of(run.summary_record())], sort_keys=True)


def run_key(run: SeedRun) -> str:
    """What makes two seed runs the same run: ``run_head`` and every column of every episode
    but wall time (``episodes.csv``). The episodes go in as their typed values' ``repr`` (exact
    for a float, as ``episodes.csv``'s text is), column by column."""
    import hashlib

    from keras_rl.runs.files import TIMING_COLUMNS

    columns = [(c, values) for c, values in run.columns().items() if c not in TIMING_COLUMNS]
    return hashlib.sha256((run_head(run) + repr(columns)).encode()).hexdigest()


_MANIFESTS: dict[tuple, list[dict]] = {}
"""``manifest``'s entries by ``results``' fingerprint: reading every set takes about 5 s of CPU (34 s
before ``run_head``), and one process (a test worker, an audit) asks several times of files that
did not change."""


def _fingerprint(results: Path) -> tuple:
    """What ``manifest`` reads: the tracked folders and every run file's path, size and modification time."""
    names = ("runs.parquet", "summary.json", "episodes.csv", "config.json")
    files = sorted(p for p in Path(results).rglob("*") if p.name in names and p.is_file())
    stats = tuple((str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in files)
    return str(Path(results).resolve()), stats, tuple(sorted(map(str, tracked_folders(results))))


def manifest(results: Path = RESULTS) -> list[dict]:
    """Every set, each with its ``copies``: the seeds that are the same run as a seed of a set
    listed before it (``run_key``; a set extended by copying, say), counted once in the cost.
    Read once per state of the files (``_fingerprint``); each call gets its own copy."""
    import copy

    key = _fingerprint(results)
    if key not in _MANIFESTS:
        _MANIFESTS.clear()
        _MANIFESTS[key] = _read_manifest(results)
    return copy.deepcopy(_MANIFESTS[key])


def _read_manifest(results: Path) -> list[dict]:
    """``manifest``'s entries. A seed's episodes are read for ``run_key`` only where an earlier
    seed has its ``run_head``: most seeds have none (the cost is under ``_MANIFESTS``)."""
    entries: list[dict] = []
    heads: dict[str, list[list]] = {}  # run_head -> [first run, its set, its run_key once read] per distinct run
    for name, runs in find_sets(results).items():
        entry = describe(name, runs)
        copies: dict[str, list[int]] = {}
        for run in runs:
            earlier = heads.setdefault(run_head(run), [])
            key = run_key(run) if earlier else None
            for first in earlier:
                if first[2] is None:
                    first[2] = run_key(first[0])
                if first[2] == key:
                    copies.setdefault(first[1], []).append(run.seed)
                    break
            else:
                earlier.append([run, name, key])
        entry["copies"] = copies
        entries.append(entry)
    return entries


def cost(entry: dict) -> float:
    """A set's process-minutes less those of its seeds that copy an earlier set's (each copied
    seed costs its share of its set's minutes)."""
    copied = sum(len(seeds) for seeds in entry.get("copies", {}).values())
    return entry["process_minutes"] * (1 - copied / len(entry["seeds"]))


def by_kind(entries: list[dict]) -> dict[str, float]:
    """Process-minutes counted once (``cost``), by how the runs ran: PyTorch, Keras on the
    compiled engine (the engine the set recorded: since ``--engine auto`` its command need not
    name it), Keras on the Gymnasium loop; the largest first."""
    out: dict[str, float] = {}
    for e in entries:
        if e["framework"] == "torch":
            kind = "PyTorch"
        elif e["engine"] == "compiled":
            kind = "Keras on the compiled engine"
        else:
            kind = "Keras on the Gymnasium loop"
        out[kind] = out.get(kind, 0.0) + cost(e)
    return dict(sorted(out.items(), key=lambda item: -item[1]))


PRICED_CORES = (2, 16, 64, 256)
"""Core counts a full regeneration is priced at (issue 52 item 6: the 3-hour target on this
2-core machine is withdrawn; what a maintainer needs is the price where there are cores)."""


def regeneration_hours(entries: list[dict]) -> tuple[float, dict[int, float], float]:
    """A full regeneration's price: the sets counted once, in process-hours; the wall time on each
    of ``PRICED_CORES``, at least the larger of those hours over N and the longest single job (a
    seed, or a seed batch, runs on one core from start to end); and that job's minutes."""
    unique = sum(cost(e) for e in entries)
    longest = max(e["longest_job_minutes"] for e in entries)
    return unique / 60, {n: max(unique / n, longest) / 60 for n in PRICED_CORES}, longest


def regeneration_line(entries: list[dict]) -> str:
    """A full regeneration's price, as ``MANIFEST.md`` states it (``regeneration_hours``)."""
    hours, walls_h, longest = regeneration_hours(entries)
    walls = "; ".join(f"{n} cores {h:.1f} h" for n, h in walls_h.items())
    return (
        f"A full regeneration (`python -m maintainers manifest --regenerate '*' --out DIR --workers N`, or "
        f"`--address` on a Ray cluster) costs {hours:.1f} process-hours; in wall time at least: {walls} "
        f"(the longest single job, {longest:.0f} minutes, bounds it from below)."
    )


def markdown(entries: list[dict]) -> str:
    total = sum(e["process_minutes"] for e in entries)
    unique = sum(cost(e) for e in entries)
    copied = sum(len(seeds) for e in entries for seeds in e.get("copies", {}).values())
    lines = [
        "# Every committed run set",
        "",
        "Generated by `python -m maintainers manifest --write` from the run folders; a test fails when",
        "it is stale. Rerun sets into a fresh folder, and compare them with these, with",
        "`python -m maintainers manifest --regenerate SET ... --out DIR` (see its docstring).",
        "",
        f"{len(entries)} sets, {sum(len(e['seeds']) for e in entries)} seed runs, {total:.0f} process-minutes "
        f"({total / 60:.1f} process-hours; with `--workers 2` on this 2-core machine, about half that in wall time).",
        f"{copied} of those seed runs are the same runs as seeds of a set listed before them (same config, batch "
        f'and episodes but for wall time; the "copies" column): counted once, the sets cost {unique:.0f} '
        f"process-minutes ({unique / 60:.1f} process-hours, about {unique / 120:.1f} hours of wall time on two "
        "workers). The minutes are the runs' recorded wall times, most measured beside other work.",
        "Counted once, by how they ran: "
        + "; ".join(f"{kind} {minutes / 60:.1f} process-hours" for kind, minutes in by_kind(entries).items())
        + ". "
        + regeneration_line(entries),
        "",
        "| set | experiment / variant / framework | seeds | batches | process-min | copies | made by |",
        "|---|---|---|---|---|---|---|",
    ]
    for e in entries:
        seeds = f"{min(e['seeds'])}-{max(e['seeds'])}" if len(e["seeds"]) > 1 else str(e["seeds"][0])
        batch = "solo" if all(len(b) == 1 for b in e["batches"]) else f"{len(e['batches'])} of {len(e['batches'][0])}"
        commands = "; ".join(f"`{c}`" for c in e["commands"])
        lines.append(
            f"| `{e['set']}` | {e['experiment']} / {e['variant']} / {e['framework']} | {seeds} ({len(e['seeds'])}) "
            f"| {batch} | {e['process_minutes']:g} | {_copies(e)} | {commands} |"
        )
    return "\n".join(lines) + "\n"


def _copies(entry: dict) -> str:
    copies = entry.get("copies", {})
    return "; ".join(f"{len(seeds)} of `{name}`" for name, seeds in copies.items()) or "-"


# -- rerun --------------------------------------------------------------------------------------


def reproduce_command(
    entry: dict, batch: list[int], out: Path, workers: int, address: str | None = None, python: str | None = None
) -> list[str]:
    """The ``keras-rl reproduce`` that reruns one batch of a committed set into ``out / set``: the
    exact config (``--config``, whichever command made it), the batch's seeds together, on the
    engine the set recorded, with ``--resume``; on a Ray cluster with ``address``."""
    committed = RunSet(RESULTS / entry["set"])
    config = committed.run(batch[0]).config_path(out / ".configs" / entry["set"])
    seeds = ",".join(str(s) for s in batch)
    command = [
        python or sys.executable, "-m", "keras_rl", "reproduce", entry["experiment"], "--config", str(config),
        "--seeds", seeds, "--seed-batch", str(len(batch)), "--engine", entry["engine"], "--workers", str(workers),
        "--no-progress", "--min-success-rate", "0", "--resume", "--out", str(out / entry["set"]),
    ]  # fmt: skip
    return command + (["--address", address] if address else [])


def compare_seeds(committed: RunSet, target: Path, seeds: list[int]) -> dict[int, dict | None]:
    """Each seed's first divergence from its committed run (every column but wall time); None
    where the rerun left no ``episodes.csv``."""
    from maintainers.replay import first_divergence, seed_rows

    by_seed: dict[int, dict | None] = {}
    for seed in seeds:
        ours = target / f"seed_{seed}" / "episodes.csv"
        theirs = committed.run(seed).text_rows()
        by_seed[seed] = first_divergence(theirs, seed_rows(ours)).as_dict() if ours.is_file() else None
    return by_seed


def rerun_set(entry: dict, out: Path, workers: int, address: str | None = None) -> dict:
    """Rerun one set batch by batch with ``--resume``, then compare it with the committed one."""
    committed = RunSet(RESULTS / entry["set"])
    target = out / entry["set"]
    codes = [
        subprocess.run(reproduce_command(entry, batch, out, workers, address), cwd=ROOT).returncode
        for batch in entry["batches"]
    ]
    from keras_rl.runs.provenance import library_versions
    from maintainers.replay import why_not_bit_exact

    same_machine = bool(entry["cpu_models"]) and all(
        why_not_bit_exact({"cpu_model": m}, framework=entry["framework"]) is None for m in entry["cpu_models"]
    )
    mine = library_versions(entry["framework"])
    same_versions = all(mine.get(k) == v for k, v in entry["versions"].items() if k not in ("keras_rl", "torch"))
    by_seed = compare_seeds(committed, target, entry["seeds"])
    exact = sum(d is not None and d["first_episode"] is None for d in by_seed.values())
    result = {
        "set": entry["set"],
        "exit_codes": codes,
        "same_cpu_and_versions": same_machine and same_versions,
        "bit_exact": exact,
        "seeds": len(entry["seeds"]),
        "divergences": {str(k): v for k, v in by_seed.items() if v is None or v["first_episode"] is not None},
    }
    result["distribution_p"] = _distribution_p(committed, target, entry["seeds"])
    if result["same_cpu_and_versions"]:
        result["agrees"] = exact == len(entry["seeds"])
        result["how"] = "bit for bit"
    else:
        result["agrees"] = result["distribution_p"] is not None and result["distribution_p"] >= 0.05
        result["how"] = "as distributions (Mann-Whitney on final metric, p >= 0.05)"
    return result


def _distribution_p(committed: RunSet, target: Path, seeds: list[int]) -> float | None:
    from keras_rl.report.stats import mann_whitney

    def finals(run_set: RunSet) -> list[float]:
        records = {r.seed: r.summary_record() for r in run_set.runs()}
        return [float(records[s]["final_metric"]) for s in seeds if records.get(s, {}).get("final_metric") is not None]

    a, b = finals(committed), finals(RunSet(target))
    if len(a) < 2 or len(b) < 2:
        return None
    if a == b:
        return 1.0
    return mann_whitney(a, b)[1]


def rerun(patterns: list[str], out: Path, workers: int, address: str | None = None) -> list[dict]:
    from keras_rl.atomic import atomic_write_json, atomic_write_text

    names = [n for n in find_sets() if any(fnmatch.fnmatch(n, p) for p in patterns)]
    if not names:  # named at once, before the manifest reads every set
        raise ConfigError(f"no committed set matches {' '.join(patterns)} (python -m maintainers manifest lists them)")
    entries = [e for e in manifest() if e["set"] in names]
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for entry in entries:
        cost = f"{len(entry['seeds'])} seeds, committed cost {entry['process_minutes']} process-min"
        print(f"rerunning {entry['set']} ({cost})", flush=True)
        results.append(rerun_set(entry, out, workers, address))
        atomic_write_json(out / "rerun.json", results)
        lines = ["| set | seeds | compared | agrees | bit-exact seeds | final-metric p |", "|---|---|---|---|---|---|"]
        for r in results:
            p = "-" if r["distribution_p"] is None else f"{r['distribution_p']:.3g}"
            agrees = "yes" if r["agrees"] else "**no**"
            lines.append(f"| `{r['set']}` | {r['seeds']} | {r['how']} | {agrees} | {r['bit_exact']} | {p} |")
        atomic_write_text(out / "rerun.md", "# Rerun against the committed sets\n\n" + "\n".join(lines) + "\n")
    return results


SIZE_BEGIN, SIZE_END = "<!-- results-size:begin -->", "<!-- results-size:end -->"
SIZE_PAGE = ROOT / "docs" / "runs.md"


def size_text(entries: list[dict], results: Path = RESULTS) -> str:
    """How much ``results/`` commits: its sets, seeds, episodes and packed MiB (``docs/runs.md``'s block)."""
    seeds = sum(len(e["seeds"]) for e in entries)
    episodes = sum(e["episodes"] for e in entries)
    mib = sum((results / e["set"] / "runs.parquet").stat().st_size for e in entries) / 2**20
    return f"{len(entries)} sets, {seeds:,} seeds and {episodes:,} episodes in {mib:.0f} MiB of `runs.parquet`"


def run(args: argparse.Namespace) -> int:
    if args.regenerate:
        if args.out is None:
            raise ConfigError("--regenerate needs --out: a fresh folder, or one to resume")
        if args.out.resolve().is_relative_to(RESULTS.resolve()):
            raise ConfigError("--out must not be inside results/: the rerun is compared with it, never written over it")
        results = rerun(args.regenerate, args.out, args.workers, args.address)
        return 0 if all(r["agrees"] for r in results) else 1
    entries = manifest()
    if not args.write:
        print(markdown(entries))
        return 0
    from keras_rl.atomic import atomic_write_json, atomic_write_text
    from maintainers.markdown import replace_block

    atomic_write_json(RESULTS / "MANIFEST.json", entries)
    atomic_write_text(RESULTS / "MANIFEST.md", markdown(entries))
    atomic_write_text(SIZE_PAGE, replace_block(SIZE_PAGE.read_text(), SIZE_BEGIN, SIZE_END, size_text(entries)))
    print(f"updated {RESULTS / 'MANIFEST.md'}, MANIFEST.json and {SIZE_PAGE}")
    return 0
