"""SIGTERM at random times, on each engine, and whether the heap survives it (issue 72, item 18).

    python -m maintainers sigterm-stress --out /tmp/stress [--stops 100] [--engines compiled gymnasium vectorised]
    python -m maintainers sigterm-stress --out /tmp/stress --write   # and results/reliability/sigterm-stress.md

A developer's session once saw glibc abort ("corrupted size vs. prev_size while consolidating",
exit -6) in 2 of 19 SIGTERMs of the compiled engine after training began. For each engine this
runs one short seed uninterrupted (the reference), then ``--stops`` times the same command,
stopped with SIGTERM at a random time after training began (its ``episodes.csv`` exists), drawn
uniformly over what the reference run took from there to its exit: mid-episode, while a
checkpoint is written, while the weights and the curve are saved, at exit. Every other stop runs
under glibc's heap checking: ``MALLOC_CHECK_=3``, which since glibc 2.34 acts only with
``libc_malloc_debug.so.0`` preloaded (without it the variable does nothing), so both are set.

Each stop is read as:
- its exit code: 143 (stopped, as ``timeout`` and Slurm expect), 0 (finished before the signal
  came), -15 after its work (the signal came as the interpreter exited, its handlers gone, and its
  files were already complete: "killed after its work"), or anything else, an abort (-6, 134), a
  crash or a hang (killed after ``HANG_SECONDS``);
- whether its stderr holds a heap message (glibc's, or Python's ``Fatal Python error``);
- whether the checkpoint written in that stop is intact: the stopped seed is resumed
  (``--resume``, in a fresh process without heap checking) and its ``episodes.csv`` must equal
  the reference's, every column but wall time. A checkpoint's SHA-256 only shows the file is the
  bytes that were written; a heap damaged before the pickle was made would write damaged bytes
  with a good checksum, and only the resumed run's bits show they are the run's.

Resumable: each stop lands as one line of ``--out``/stops.jsonl and is skipped when run again.
The draw of each stop's delay is seeded by the engine's name and the stop's number.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from keras_rl.errors import ConfigError
from maintainers.checkout import ROOT


@dataclass(frozen=True)
class Case:
    """One engine's short seed: long enough that a random SIGTERM lands in training, and short
    enough that 100 stops and their resumes take minutes."""

    command: tuple[str, ...]


CASES = {
    "compiled": Case(("reproduce", "pendulum", "--engine", "compiled", "--episodes", "60")),
    "gymnasium": Case(("reproduce", "pendulum", "--engine", "gymnasium", "--episodes", "12")),
    "vectorised": Case(("reproduce", "cartpole", "--framework", "torch", "--engine", "vectorised", "--episodes", "40")),
}
"""Engine -> its seed's command (seed 0, a checkpoint every 5 episodes; ``COMMON``)."""
COMMON = ("--seeds", "0", "--checkpoint-every", "5", "--no-progress", "--min-success-rate", "0")
HANG_SECONDS = 180
HEAP_CHECK = {"MALLOC_CHECK_": "3", "LD_PRELOAD": "libc_malloc_debug.so.0"}
HEAP_MESSAGE = re.compile(
    r"corrupted|double free|free\(\)|malloc\(\)|malloc_consolidate|munmap_chunk"
    r"|Fatal Python error|Segmentation fault|Aborted"
)
REPORT = ROOT / "results" / "reliability" / "sigterm-stress.md"
RECORD = REPORT.with_suffix(".json")


def _command(case: Case, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "keras_rl", *case.command, *COMMON, "--out", str(out), *extra]


def _env(heap_check: bool) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in HEAP_CHECK}
    env.update({"PYTHONPATH": str(ROOT), "TF_CPP_MIN_LOG_LEVEL": "3"})
    return {**env, **HEAP_CHECK} if heap_check else env


def _rows(folder: Path) -> list[dict[str, str]] | None:
    from keras_rl.runs.files import seed_rows

    path = folder / "seed_0" / "episodes.csv"
    return seed_rows(path) if path.is_file() else None


def reference(engine: str, out: Path) -> dict:
    """The engine's seed run uninterrupted, and how long it ran after training began."""
    folder = out / engine / "reference"
    record = out / engine / "reference.json"
    if record.is_file():
        return json.loads(record.read_text())
    shutil.rmtree(folder, ignore_errors=True)
    started = time.monotonic()
    log = out / engine / "reference.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("wb") as sink:
        process = subprocess.Popen(_command(CASES[engine], folder), env=_env(False), stdout=sink, stderr=sink)
        began = _wait_for_training(process, folder)
        process.wait(timeout=HANG_SECONDS * 4)
    output = log.read_text(errors="replace")
    ended = time.monotonic()
    if process.returncode != 0 or began is None:
        raise RuntimeError(f"the {engine} reference run failed (exit {process.returncode}):\n{output[-2000:]}")
    result = {"seconds_to_training": round(began - started, 2), "window_seconds": round(ended - began, 2)}
    from keras_rl.atomic import atomic_write_json

    atomic_write_json(record, result)
    return result


def _wait_for_training(process: subprocess.Popen, folder: Path) -> float | None:
    """When the seed's first episode row was written (training began), or None if it exited first."""
    csv = folder / "seed_0" / "episodes.csv"
    deadline = time.monotonic() + HANG_SECONDS
    while process.poll() is None and time.monotonic() < deadline:
        if csv.is_file() and csv.stat().st_size > 0:
            return time.monotonic()
        time.sleep(0.02)
    return None


def stop_once(engine: str, index: int, out: Path, window: float, reference_rows: list) -> dict:
    """One SIGTERM at a random time after training began; the stopped seed resumed and compared."""
    heap_check = index % 2 == 0
    rng = np.random.default_rng([zlib.crc32(engine.encode()), index])
    delay = float(rng.uniform(0.0, window))
    folder = out / engine / f"stop_{index}"
    shutil.rmtree(folder, ignore_errors=True)
    err = out / engine / f"stop_{index}.stderr"  # files, not pipes: nothing blocks on output nobody reads
    with err.open("wb") as sink:
        process = subprocess.Popen(
            _command(CASES[engine], folder), env=_env(heap_check), stdout=subprocess.DEVNULL, stderr=sink
        )
        began = _wait_for_training(process, folder)
        signalled = False
        if began is not None:
            time.sleep(max(0.0, delay - (time.monotonic() - began)))
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                signalled = True
        try:
            process.wait(timeout=HANG_SECONDS)
            hung = False
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            hung = True
    stderr_text = err.read_text(errors="replace")
    err.unlink()
    heap = sorted(set(HEAP_MESSAGE.findall(stderr_text)))
    result = {
        "engine": engine,
        "stop": index,
        "heap_check": heap_check,
        "delay_seconds": round(delay, 3),
        "signalled": signalled,
        "exit": process.returncode,
        "hung": hung,
        "heap_messages": heap,
        "stderr_tail": stderr_text[-600:] if (heap or process.returncode not in (0, 143)) else "",
    }
    if process.returncode == 143:
        resumed = subprocess.run(
            _command(CASES[engine], folder, "--resume"), env=_env(False), capture_output=True, text=True
        )
        result["resume_exit"] = resumed.returncode
        if resumed.returncode != 0:
            result["resume_tail"] = (resumed.stdout + resumed.stderr)[-600:]
    summary = folder / "seed_0" / "summary.json"
    result["summary_status"] = json.loads(summary.read_text()).get("status") if summary.is_file() else None
    result["reference_bits"] = _rows(folder) == reference_rows
    if result["reference_bits"] and not heap and process.returncode in (0, 143):
        shutil.rmtree(folder)  # kept only where something is to be read
    return result


def verdict(r: dict) -> str:
    if r["hung"]:
        return "hung"
    if r["exit"] in (-6, 134) or r["heap_messages"]:
        return "abort"
    if r["exit"] == 143:
        return "stopped"
    if r["exit"] == 0:
        return "finished first"
    if r["exit"] == -signal.SIGTERM and r["reference_bits"] and r.get("summary_status", "completed") == "completed":
        return "killed after its work"  # no handler left (at exit): the default action, files complete
    return f"exit {r['exit']}"


def counts(results: list[dict]) -> list[dict]:
    """Per engine and heap checking: stops, what they read as, and how many resumed to the reference's bits."""
    rows = []
    for engine in CASES:
        for heap_check in (False, True):
            mine = [r for r in results if r["engine"] == engine and r["heap_check"] == heap_check]
            if not mine:
                continue
            seen = [verdict(r) for r in mine]
            rows.append(
                {
                    "engine": engine,
                    "heap_check": heap_check,
                    "stops": len(mine),
                    "stopped": seen.count("stopped"),
                    "finished_first": seen.count("finished first"),
                    "killed_after_work": seen.count("killed after its work"),
                    "aborts": seen.count("abort"),
                    "hung": seen.count("hung"),
                    "other": sum(s.startswith("exit") for s in seen),
                    "reference_bits": sum(r["reference_bits"] for r in mine),
                }
            )
    return rows


def markdown(rows: list[dict], references: dict, command: str) -> str:
    from scipy.stats import beta

    lines = [
        "# SIGTERM at random times, on each engine",
        "",
        f"Generated by `{command}` (`maintainers/sigterm_stress.py`, whose docstring gives the design).",
        "Each stop: one short seed, SIGTERM at a random time after its training began, then `--resume`",
        "and a comparison of its `episodes.csv` with the uninterrupted run's (every column but wall time).",
        "Heap checking is glibc's `MALLOC_CHECK_=3` with `libc_malloc_debug.so.0` preloaded (since glibc",
        '2.34 the variable alone does nothing). "Killed after its work": the signal came after the command\'s',
        "handlers were gone (as the interpreter exits), so SIGTERM's default action ended it (-15, which a",
        "shell reports as 143, as it does the handled stop); its `episodes.csv` was already the reference's.",
        "The last column: stopped seeds resumed (or finished ones as they stood) whose `episodes.csv` equals",
        "the uninterrupted run's.",
        "",
        "| engine | heap checking | stops | exit 143 | finished first | killed after its work | aborts | hung | other "
        "| the reference's bits |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['engine']} | {'yes' if r['heap_check'] else 'no'} | {r['stops']} | {r['stopped']} | "
            f"{r['finished_first']} | {r.get('killed_after_work', 0)} | {r['aborts']} | {r['hung']} | {r['other']} | "
            f"{r['reference_bits']} of {r['stops']} |"
        )
    lines += ["", "Per engine, both settings together, with a one-sided 95% Clopper-Pearson bound on aborts:", ""]
    for engine in CASES:
        mine = [r for r in rows if r["engine"] == engine]
        if not mine:
            continue
        n, aborts = sum(r["stops"] for r in mine), sum(r["aborts"] for r in mine)
        upper = beta.ppf(0.95, aborts + 1, n - aborts) if aborts < n else 1.0
        window = references.get(engine, {})
        lines.append(
            f"- {engine}: {aborts} aborts in {n} stops (at most {upper:.1%} at 95%); SIGTERM drawn over the "
            f"{window.get('window_seconds', '?')} s the reference seed ran after its training began."
        )
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    from keras_rl.atomic import atomic_write_json, atomic_write_text

    if args.stops < 1:
        raise ConfigError(f"--stops must be at least 1, got {args.stops}")
    if args.out is None:
        raise ConfigError("sigterm-stress needs --out: a fresh folder, or one to resume")
    import ctypes.util

    if ctypes.util.find_library("c_malloc_debug") is None:
        raise ConfigError("glibc's libc_malloc_debug.so.0 is not installed: MALLOC_CHECK_=3 would do nothing")
    unknown = [e for e in args.engines if e not in CASES]
    if unknown:
        raise ConfigError(f"unknown engine {unknown[0]!r}; known: {', '.join(CASES)}")
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    log = out / "stops.jsonl"
    lines = log.read_text().splitlines() if log.is_file() else []
    if lines and not lines[-1].rstrip().endswith("}"):  # a stop cut off as it was written reruns
        lines.pop()
        log.write_text("".join(line + "\n" for line in lines))
    results = [json.loads(line) for line in lines]
    done = {(r["engine"], r["stop"]) for r in results}
    references = {}
    for engine in args.engines:
        references[engine] = reference(engine, out)
        reference_rows = _rows(out / engine / "reference")
        if reference_rows is None:
            raise ConfigError(f"{out / engine / 'reference'} lost its episodes.csv: remove {engine}/reference.json")
        for index in range(args.stops):
            if (engine, index) in done:
                continue
            result = stop_once(engine, index, out, references[engine]["window_seconds"], reference_rows)
            results.append(result)
            with log.open("a") as f:
                f.write(json.dumps(result) + "\n")
            print(f"{engine} stop {index}: {verdict(result)}, reference bits {result['reference_bits']}", flush=True)
    for engine in CASES:  # the windows of engines an earlier command of this --out ran
        record = out / engine / "reference.json"
        if engine not in references and record.is_file():
            references[engine] = json.loads(record.read_text())
    command = f"python -m maintainers sigterm-stress --stops {args.stops} --engines {' '.join(args.engines)} --out OUT"
    rows = counts(results)
    command += " --write" if args.write else ""
    text = markdown(rows, references, command)
    print(text)
    if args.write:
        REPORT.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_json(RECORD, {"command": command, "references": references, "counts": rows, "stops": results})
        atomic_write_text(REPORT, text)
    bad = sum(r["aborts"] + r["hung"] + r["other"] + (r["stops"] - r["reference_bits"]) for r in rows)
    return 1 if bad else 0
