"""One cell of the version matrix, run inside that cell's virtualenv (``noxfile.py`` calls it).

    python matrix/compat_cell.py --cell NAME --spec '{"tensorflow": "2.20.0"}' \
        --reference-python .nox/cell-reference/bin/python [--out results/compat/NAME] [--redo STEP] [--only STEP]

Steps, each written to ``<out>/<step>.json`` as it finishes (a killed cell resumes at the first
step without its file; ``--redo STEP`` reruns one, ``--only STEP`` runs just the steps named, so a
cell's verdict can come before its slower steps):

- ``versions``: the library versions this interpreter imports, and ``pip freeze`` (``pip-freeze.txt``);
- ``tests``: the fast suite (``pytest -m "not slow"``), its counts and the names of failures;
- ``envs``: env parity, ``tests/test_tf_envs.py`` whole (the compiled engine's TensorFlow envs
  against this cell's Gymnasium: one step from 1,000 random states per env, bit for bit on
  TensorFlow's kernels and within stated ulps under XLA, and 200-step trajectories within 1e-6),
  so a Gymnasium release that changes the dynamics shows here;
- ``replay``: committed seed 0 of each post (Keras) rerun whole: bit for bit, or the first
  differing episode and its columns;
- ``probe``: ``matrix/compat_probe.py`` here and under ``--reference-python``: each
  post's initial weights, first action and one update on a fixed batch, compared (the largest
  absolute difference of each: 0 for the same bits, ~1e-7 for float32 rounding);
- ``check``: ``keras-rl check pendulum cartpole mountaincar --tier sensitive --workers 2``, the twin
  check, against the committed baselines (its ``check.json`` and ``check.md`` copied here as
  ``check-report.*``), then ``keras-rl check cartpole --framework torch --tier smoke``, PyTorch's
  one rule (``check-torch-report.*``). Cells run before the twin check hold the smoke tier's
  verdicts instead, a ``changed`` post rerun at the full tier (``check-full-report.*``);
- ``speed``: ``benchmarks/step_time.py --keras-only`` here and under ``--reference-python``
  (the reference cell's interpreter), alternated five times in this one session; the cell's ms
  over the reference's ms per post, median of the runs.

``cell.json`` gathers them; ``maintainers/tables/compat.py --write`` makes the table.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cells import STEPS  # noqa: E402 beside this script

from keras_rl.atomic import atomic_write_json, atomic_write_text  # noqa: E402

# Tests of the repository's committed state, not of the libraries: the matrix table is made from
# the cell folders, which a running cell is still writing.
DESELECTED = ("tests/test_results_docs.py::test_the_version_matrix_table_is_generated_from_the_committed_cells",)
POSTS = ("pendulum", "cartpole", "mountaincar")
REPLAYS = {  # post -> its committed seed 0 (Keras, the faithful variant), rerun whole
    "pendulum": "results/pendulum/faithful/seed_0",
    "cartpole": "results/cartpole/faithful/seed_0",
    "mountaincar": "results/mountaincar/faithful/seed_0",
}
SPEED_ROUNDS = 5  # reference and cell alternate: ref, cell, ref, ... (each round one of each)


def run(command: list[str], log: Path, timeout: float) -> tuple[int, float]:
    """Run a command with its output to ``log``; its exit code and wall seconds."""
    start = time.perf_counter()
    with open(log, "w") as fh:
        try:
            code = subprocess.run(command, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT, timeout=timeout).returncode
        except subprocess.TimeoutExpired:
            fh.write(f"\n[compat_cell] timed out after {timeout:.0f} s\n")
            code = -9
    return code, time.perf_counter() - start


def step_versions(out: Path, work: Path) -> dict:
    from keras_rl.runs.provenance import git_state, library_versions

    freeze = subprocess.run([sys.executable, "-m", "pip", "freeze"], capture_output=True, text=True, check=True)
    lines = [line for line in freeze.stdout.splitlines() if not line.startswith("-e ") and "keras-rl-repro" not in line]
    atomic_write_text(out / "pip-freeze.txt", "\n".join(lines) + "\n")
    import torch  # in every cell: the CPU wheel 2.13.0, or the PyTorch cell's release

    code = {k: v for k, v in git_state().items() if k in ("commit", "dirty")}
    return {"versions": {**library_versions(), "torch": torch.__version__}, "packages": len(lines), "code": code}


def _pytest(out: Path, work: Path, name: str, selection: list[str]) -> dict:
    """Run pytest on ``selection`` here; its counts and the names of failures (``name``.log kept
    beside the cell's results when it fails)."""
    junit = work / f"{name}.xml"
    code, seconds = run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            *selection,
            "-p",
            "no:cacheprovider",
            *[f"--deselect={test}" for test in DESELECTED],
            f"--junitxml={junit}",
        ],
        work / f"{name}.log",
        timeout=1800,
    )
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    failed: list[str] = []
    if junit.exists():
        root = ET.parse(junit).getroot()
        for suite in root.iter("testsuite"):
            for key in counts:
                counts[key] += int(suite.get(key, 0))
        for case in root.iter("testcase"):
            if case.find("failure") is not None or case.find("error") is not None:
                failed.append(f"{case.get('classname')}::{case.get('name')}")
    if code != 0:  # keep the log of a failing suite beside the cell's results
        shutil.copy(work / f"{name}.log", out / f"{name}.log")
    passed = counts["tests"] - counts["failures"] - counts["errors"] - counts["skipped"]
    return {
        "exit_code": code,
        "seconds": round(seconds, 1),
        **counts,
        "passed": passed,
        "failed": failed,
        "deselected": list(DESELECTED),
    }


def step_tests(out: Path, work: Path) -> dict:
    return _pytest(out, work, "tests", ["-m", "not slow", "-n", "2"])


def step_envs(out: Path, work: Path) -> dict:
    import gymnasium

    return {"gymnasium": gymnasium.__version__, **_pytest(out, work, "envs", ["tests/test_tf_envs.py"])}


def step_replay(out: Path, work: Path) -> dict:
    from maintainers.replay import plan_replay

    posts = {}
    for post, folder in REPLAYS.items():
        replay = plan_replay(ROOT / folder, post)
        run_dir = work / f"replay-{post}"
        shutil.rmtree(run_dir, ignore_errors=True)
        code, seconds = run(replay.command(run_dir), work / f"replay-{post}.log", timeout=1800)
        try:
            divergence = replay.divergence(run_dir).as_dict()
        except FileNotFoundError:
            divergence = None
            shutil.copy(work / f"replay-{post}.log", out / f"replay-{post}.log")
        posts[post] = {
            "folder": folder,
            "episodes": replay.budget,
            "exit_code": code,
            "seconds": round(seconds, 1),
            "bit_exact": divergence is not None and divergence["first_episode"] is None,
            "divergence": divergence,
        }
    return {"posts": posts}


def step_probe(out: Path, work: Path, reference_python: str) -> dict:
    script = str(ROOT / "matrix" / "compat_probe.py")
    dumps = {}
    for side, python in (("reference", reference_python), ("cell", sys.executable)):
        dumps[side] = work / f"probe-{side}.npz"
        code, _ = run([python, script, "dump", str(dumps[side])], work / f"probe-{side}.log", 900)
        if code != 0:
            shutil.copy(work / f"probe-{side}.log", out / f"probe-{side}.log")
            return {"error": f"compat_probe.py dump failed under {python} (probe-{side}.log)"}
    sys.path.insert(0, str(ROOT / "matrix"))
    from compat_probe import compare

    return {"max_abs_difference": compare(dumps["reference"], dumps["cell"])}


def _check(out: Path, work: Path, posts: list[str], tier: str, name: str, *options: str) -> dict:
    check_dir = work / name
    shutil.rmtree(check_dir, ignore_errors=True)
    command = [
        sys.executable,
        "-m",
        "keras_rl",
        "check",
        *posts,
        "--tier",
        tier,
        *options,
        "--no-progress",
        "--out",
        str(check_dir),
    ]
    code, seconds = run(command, work / f"{name}.log", timeout=7200)
    report = check_dir / "check.json"
    if not report.exists():
        shutil.copy(work / f"{name}.log", out / f"{name}.log")
        return {"tier": tier, "exit_code": code, "seconds": round(seconds, 1), "posts": {}}
    shutil.copy(report, out / f"{name}-report.json")  # not <step>.json, which is this step's own record
    shutil.copy(check_dir / "check.md", out / f"{name}-report.md")
    payload = json.loads(report.read_text())
    # each post-cell test on its own, at its rule's alpha (the check itself adjusts over the posts)
    verdicts = {}
    for e in payload["experiments"]:
        twins = e.get("twins") or {}
        p = e["decision"]["p"]  # 1.0 where every twin kept its baseline seed's bits
        verdicts[e["experiment"]] = {
            "verdict": "changed" if p < e["rule"]["alpha"] else "consistent",
            "p": p,
            "alpha": e["rule"]["alpha"],
            "statistic": e["rule"]["statistic"],
            "check_verdict": e["verdict"],
            "same_bits": twins.get("same_bits"),
            "twins": twins.get("compared"),
            "identical": twins.get("identical"),
            "environment": e.get("environment"),
        }
    return {"tier": tier, "exit_code": code, "seconds": round(seconds, 1), "posts": verdicts}


def step_check(out: Path, work: Path) -> dict:
    keras = _check(out, work, list(POSTS), "sensitive", "check", "--workers", "2")
    torch = _check(out, work, ["cartpole"], "smoke", "check-torch", "--framework", "torch", "--workers", "2")
    return {"sensitive": keras, "torch": torch}


def step_speed(out: Path, work: Path, reference_python: str) -> dict:
    script = str(ROOT / "benchmarks" / "step_time.py")
    ms: dict[str, dict[str, list[float]]] = {"cell": {}, "reference": {}}
    for round_ in range(SPEED_ROUNDS):
        for side, python in (("reference", reference_python), ("cell", sys.executable)):
            target = work / f"speed-{side}-{round_}.json"
            code, _ = run([python, script, "--keras-only", "--json", str(target)], work / f"speed-{side}.log", 900)
            if code != 0:
                raise SystemExit(f"benchmarks/step_time.py failed under {python}: see {work / f'speed-{side}.log'}")
            for row in json.loads(target.read_text())["rows"]:
                ms[side].setdefault(row["experiment"], []).append(row["keras_ms"])
    ratios = {
        experiment: round(
            statistics.median(c / r for c, r in zip(ms["cell"][experiment], ms["reference"][experiment])), 3
        )
        for experiment in ms["cell"]
    }
    return {"rounds": SPEED_ROUNDS, "reference_python": reference_python, "ms": ms, "cell_over_reference": ratios}


def _commit() -> str:
    from keras_rl.runs.provenance import git_state

    state = git_state()
    return f"{state['commit']}{'+dirty' if state['dirty'] else ''}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cell", required=True)
    parser.add_argument("--spec", required=True, help="the versions this cell asks for, as JSON")
    parser.add_argument("--reference-python", required=True, help="the reference cell's interpreter (speed ratios)")
    parser.add_argument("--out", type=Path, default=None, help="default results/compat/<cell>")
    parser.add_argument("--redo", action="append", choices=STEPS, default=[], help="rerun this step (repeatable)")
    parser.add_argument(
        "--only",
        action="append",
        choices=STEPS,
        default=[],
        help="run just this step (repeatable), the others left for a later run; no cell.json until all are done",
    )
    args = parser.parse_args()
    if not Path(args.reference_python).exists():
        print(
            f"error: --reference-python {args.reference_python} does not exist: run the reference cell first",
            file=sys.stderr,
        )
        raise SystemExit(2)
    out = args.out or ROOT / "results" / "compat" / args.cell
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"compat-{args.cell}-"))
    spec = json.loads(args.spec)
    for step in STEPS:
        target = out / f"{step}.json"
        if args.only and step not in args.only:
            continue
        if target.exists() and step not in args.redo:
            print(f"[{args.cell}] {step}: done before ({target.name}), skipped", flush=True)
            continue
        print(f"[{args.cell}] {step} ...", flush=True)
        start = time.perf_counter()
        if step in ("speed", "probe"):
            result = globals()[f"step_{step}"](out, work, args.reference_python)
        else:
            result = globals()[f"step_{step}"](out, work)
        result["step_seconds"] = round(time.perf_counter() - start, 1)
        result["commit"] = _commit()
        atomic_write_json(target, result)
        print(f"[{args.cell}] {step}: {result['step_seconds']:.0f} s", flush=True)
    missing = [step for step in STEPS if not (out / f"{step}.json").exists()]
    if missing:
        shutil.rmtree(work, ignore_errors=True)
        print(f"[{args.cell}] left for a later run: {', '.join(missing)} (no cell.json yet)", flush=True)
        return
    steps = {step: json.loads((out / f"{step}.json").read_text()) for step in STEPS}
    install = json.loads((out / "install.json").read_text()) if (out / "install.json").exists() else None
    cell = {"cell": args.cell, "spec": spec, "install": install, **steps}
    cell["seconds"] = round(sum(s["step_seconds"] for s in steps.values()) + (install or {}).get("seconds", 0), 1)
    atomic_write_json(out / "cell.json", cell)
    shutil.rmtree(work, ignore_errors=True)
    print(f"[{args.cell}] wrote {out / 'cell.json'}", flush=True)


if __name__ == "__main__":
    main()
