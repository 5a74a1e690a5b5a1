"""A new user's pass over a fresh clone: the commands two rounds of new users reported, run again.

    python reproductions/new_user_pass.py [--write]

Clones this repository (its committed HEAD) into a temporary folder, and runs each scenario
there with this interpreter and the clone's own code (``PYTHONPATH``). Every scenario states
what a user must see: the exit code, a message that names the problem, no Python traceback,
and no file of theirs lost. ``--write`` puts the table in ``results/new-user-pass.md``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Outcome:
    item: str
    command: str
    ok: bool
    seen: str


class Pass:
    def __init__(self, clone: Path, work: Path):
        self.clone, self.work, self.outcomes = clone, work, []
        self.env = {**os.environ, "PYTHONPATH": str(clone), "PYTHONUNBUFFERED": "1", "TF_CPP_MIN_LOG_LEVEL": "3"}

    def cli(self, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "keras_rl", *args],
            cwd=self.work,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    def expect(self, item: str, args: list[str], code: int, message: str, keep: list[Path] = (), timeout=600):
        before = {p: p.read_bytes() for p in keep if p.is_file()}
        done = self.cli(*args, timeout=timeout)
        out = done.stdout + done.stderr
        lost = [str(p) for p, data in before.items() if not p.is_file() or p.read_bytes() != data]
        ok = done.returncode == code and message in out and "Traceback" not in out and not lost
        noise = ("I0000", "W0000", "WARNING: All log messages")  # TensorFlow's start-up lines
        lines = [
            line for line in (done.stderr + done.stdout).splitlines() if line.strip() and not line.startswith(noise)
        ]
        last = next((line for line in lines if line.startswith("error")), lines[-1] if lines else "")
        seen = f"exit {done.returncode}; {last[:160]}" + (f"; LOST {lost}" if lost else "")
        self.outcomes.append(Outcome(item, "keras-rl " + " ".join(args), ok, seen))
        return done

    def run_set(self, folder: str, seeds: str = "0-1", episodes: int = 3) -> Path:
        out = self.work / folder
        done = self.cli(
            "reproduce",
            "pendulum",
            "--seeds",
            seeds,
            "--episodes",
            str(episodes),
            "--no-progress",
            "--min-success-rate",
            "0",
            "--out",
            str(out),
        )
        assert done.returncode == 0, done.stderr
        return out


def scenarios(p: Pass) -> None:
    w = p.work
    # 1. a seed folder without summary.json is never deleted by compare
    runs = w / "X" / "pendulum" / "faithful"
    p.run_set("X/pendulum/faithful")
    (runs / "seed_0" / "summary.json").unlink()
    (runs / "seed_0" / "NOTES.txt").write_text("n\n")
    p.expect(
        "1 compare keeps a folder it did not make",
        [
            "compare",
            "pendulum",
            "--seeds",
            "0-1",
            "--episodes",
            "3",
            "--runs",
            str(w / "X"),
            "--out",
            str(w / "R"),
            "--no-progress",
        ],
        2,
        "NOTES",
        [runs / "seed_0" / "NOTES.txt"],
    )
    # 2. duplicate grid values are one grid point, or refused
    p.expect(
        "2 duplicate grid values",
        [
            "sweep",
            "pendulum",
            "--grid",
            "tau=0.1,0.10,1e-1",
            "--seeds",
            "0",
            "--episodes",
            "2",
            "--out",
            str(w / "S"),
            "--no-progress",
        ],
        2,
        "tau",
    )
    # 4. a longer evaluation is not replaced by a shorter one
    one = p.run_set("E", seeds="0")
    p.cli("evaluate", str(one / "seed_0"), "--episodes", "2")
    p.expect(
        "4 evaluate keeps a longer evaluation",
        ["evaluate", str(one / "seed_0"), "--episodes", "1"],
        2,
        "holds an evaluation of 2 episodes",
        [one / "seed_0" / "evaluation.json"],
    )
    # 6, 7. damaged and truncated episodes.csv
    damaged = p.run_set("D")
    csv = damaged / "seed_1" / "episodes.csv"
    rows = csv.read_text()
    csv.write_text("garbage\n")
    p.expect("6 garbage episodes.csv", ["aggregate", str(damaged)], 2, "seed_1", [csv])
    csv.write_text(rows.rsplit("\n", 2)[0] + "\n")  # one row short of what summary.json counts
    p.expect("7 truncated episodes.csv", ["aggregate", str(damaged)], 2, "seed_1", [csv])
    csv.write_text(rows)
    # 9. misleading messages
    p.expect(
        "9 --rerun with --reuse-only",
        ["compare", "pendulum", "--seeds", "0-1", "--rerun", "--reuse-only", "--out", str(w / "R2")],
        2,
        "--rerun",
    )
    cartpole = ROOT / "results" / "checks"
    p.expect(
        "9 check against another post's baseline",
        ["check", "pendulum", "--against", str(w / "wrong"), "--out", str(w / "C")],
        2,
        "baseline",
    )
    (w / "wrong" / "pendulum").mkdir(parents=True)
    shutil.copytree(cartpole / "cartpole" / "baseline", w / "wrong" / "pendulum" / "baseline")
    p.expect(
        "9 check against another post's baseline",
        ["check", "pendulum", "--against", str(w / "wrong"), "--out", str(w / "C"), "--no-progress"],
        2,
        "is a baseline of cartpole",
    )
    # 10. conventions
    p.expect("10 check names an unknown experiment", ["check", "pendulumm"], 2, "unknown experiment")
    p.expect("10 evaluate --gif x.mp4", ["evaluate", str(one / "seed_0"), "--gif", str(w / "x.mp4")], 2, ".gif")
    # 12. extend a finished run
    p.expect(
        "12 --resume --episodes N extends",
        [
            "reproduce",
            "pendulum",
            "--seeds",
            "0",
            "--episodes",
            "5",
            "--no-progress",
            "--min-success-rate",
            "0",
            "--resume",
            "--out",
            str(one),
        ],
        0,
        "completed",
    )
    # 14. evaluation during training
    p.expect(
        "14 --eval-every",
        [
            "reproduce",
            "pendulum",
            "--seeds",
            "0",
            "--episodes",
            "4",
            "--eval-every",
            "2",
            "--eval-episodes",
            "1",
            "--no-progress",
            "--min-success-rate",
            "0",
            "--out",
            str(w / "EV"),
        ],
        0,
        "completed",
    )
    ok = (w / "EV" / "seed_0" / "evaluations.csv").is_file() and (w / "EV" / "seed_0" / "best" / "best.json").is_file()
    p.outcomes.append(Outcome("14 evaluations.csv and best/ written", "(files)", ok, "present" if ok else "missing"))
    # 10. SIGTERM exits 143 and the run resumes
    command = [
        sys.executable,
        "-m",
        "keras_rl",
        "reproduce",
        "pendulum",
        "--seeds",
        "0-1",
        "--seed-batch",
        "2",
        "--episodes",
        "40",
        "--no-progress",
        "--out",
        str(w / "T"),
    ]
    proc = subprocess.Popen(command, cwd=w, env=p.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not (w / "T" / "seed_0" / "episodes.csv").is_file():
        time.sleep(0.2)
    time.sleep(3)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=300)
    ok = proc.returncode == 143 and "Traceback" not in out + err and "--resume" in out + err
    p.outcomes.append(
        Outcome(
            "3, 10 SIGTERM on a seed batch: exit 143, --resume advised",
            " ".join(command[2:]),
            ok,
            f"exit {proc.returncode}",
        )
    )
    p.expect(
        "3 the advised --resume continues the batch",
        [
            "reproduce",
            "pendulum",
            "--seeds",
            "0-1",
            "--seed-batch",
            "2",
            "--episodes",
            "40",
            "--no-progress",
            "--min-success-rate",
            "0",
            "--resume",
            "--out",
            str(w / "T"),
        ],
        0,
        "completed",
    )


def round_two(p: Pass) -> None:
    """The second round's bad inputs: each refused with exit 2 before anything is trained."""
    w = p.work
    out = ["--out", str(w / "R2")]
    p.expect(
        "r2.1 a huge seed range", ["reproduce", "pendulum", "--seeds", "0-4294967295", "--dry-run", *out], 2, "10000"
    )
    p.expect("r2.2 NaN threshold", ["reproduce", "pendulum", "--set", "threshold=nan", "--dry-run", *out], 2, "finite")
    p.expect("r2.2 inf threshold", ["reproduce", "pendulum", "--set", "threshold=inf", "--dry-run", *out], 2, "finite")
    ro = "/proc/no-such-dir/out"
    p.expect("r2.3 compare --out read-only", ["compare", "pendulum", "--seeds", "0", "--out", ro], 2, "writable")
    bad = w / "latin1.json"
    bad.write_bytes(b"\xff\xfe{")
    p.expect(
        "r2.5 --config not UTF-8", ["reproduce", "pendulum", "--config", str(bad), "--dry-run", *out], 2, "not JSON"
    )
    config = (p.clone / "results" / "pendulum" / "faithful" / "seed_0" / "config.json").read_text()
    nosuch = w / "nosuch.json"
    nosuch.write_text(config.replace('"variant": "faithful"', '"variant": "nosuch"'))
    p.expect(
        "r2.6 --config variant nosuch", ["reproduce", "pendulum", "--config", str(nosuch), "--dry-run"], 2, "nosuch"
    )
    p.expect("r2.7 check --out read-only", ["check", "pendulum", "--out", ro], 2, "writable")
    p.expect("r2.7 bisect --out read-only", ["bisect", "HEAD", "HEAD", "pendulum", "--out", ro], 2, "writable")
    grid = ["sweep", "pendulum", "--grid", "tau=0.001,0.01", "--set", "tau=0.005", "--out", str(w / "S2")]
    p.expect("r2.10 --grid and --set one field", grid, 2, "given both")
    p.expect("r2.15 --eval-episodes alone", ["reproduce", "pendulum", "--eval-episodes", "3", *out], 2, "--eval-every")
    p.expect("r2.15 seeds 1,,2", ["reproduce", "pendulum", "--seeds", "1,,2", "--dry-run", *out], 2, "empty item")
    p.expect("r2.15 seeds 1,1", ["reproduce", "pendulum", "--seeds", "1,1", "--dry-run", *out], 2, "twice")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", action="store_true", help="write results/new-user-pass.md")
    args = parser.parse_args()
    base = Path(tempfile.mkdtemp(prefix="new-user-"))
    clone, work = base / "clone", base / "work"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    work.mkdir()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, capture_output=True, text=True).stdout
    p = Pass(clone, work)
    try:
        scenarios(p)
        round_two(p)
    finally:
        lines = [
            "# A new user's pass over a fresh clone",
            "",
            f"`python reproductions/new_user_pass.py --write` on a fresh clone of commit `{commit.strip()}`: the",
            "commands two rounds of new users reported, each with what a user must see (the exit code, a",
            "message naming the problem, no traceback, none of their files lost).",
            "",
            "| item | command | as it should be | seen |",
            "|---|---|---|---|",
        ]
        lines += [f"| {o.item} | `{o.command[:90]}` | {'yes' if o.ok else '**no**'} | {o.seen} |" for o in p.outcomes]
        text = "\n".join(lines) + "\n"
        print(text)
        if args.write:
            (ROOT / "results" / "new-user-pass.md").write_text(text)
        shutil.rmtree(base, ignore_errors=True)
    raise SystemExit(0 if all(o.ok for o in p.outcomes) else 1)


if __name__ == "__main__":
    main()
