"""Can capping the instruction set make TensorFlow's bits travel between hosts? (issue 52, item 7)

    .venv/bin/python benchmarks/isa_cap.py            # a Markdown table on stdout (a few minutes)

Run on an AVX-512 host: each row reruns the start of two committed seeds under one cap and says
at which episode its rows first differ from the references made on an AVX2 host
(``tests/replay_references/avx2``) and from the committed AVX-512 runs, with the wall time of
the two runs as a ratio to the uncapped ones (one run, one machine: a ratio, not a timing).
A cap that worked would match the AVX2 references at every episode.

The caps: NumPy's runtime dispatch (``NPY_DISABLE_CPU_FEATURES``), oneDNN's kernels
(``ONEDNN_MAX_CPU_ISA``, which TensorFlow's CPU ops call for matrix products), XLA's code
generation (``XLA_FLAGS=--xla_cpu_max_isa``), and all three.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
AVX2 = ROOT / "tests" / "replay_references" / "avx2"
CASES = (("mountaincar", 0, 3), ("cartpole", 0, 10))
"""(experiment, seed, episodes): post 001 differs from episode 1 on AVX2, post 003 at episode 8."""
CAPS: dict[str, dict[str, str]] = {
    "none": {},
    "NumPy": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"},
    "oneDNN": {"ONEDNN_MAX_CPU_ISA": "AVX2"},
    "XLA": {"XLA_FLAGS": "--xla_cpu_max_isa=AVX2"},
    "all three": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "ONEDNN_MAX_CPU_ISA": "AVX2",
        "XLA_FLAGS": "--xla_cpu_max_isa=AVX2",
    },
}


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(fh)]


def first_difference(got: list[dict], want: list[dict]) -> str:
    for have, expected in zip(got, want):
        if have != expected:
            return f"episode {have['episode']}"
    return f"none in {min(len(got), len(want))}"


def committed(experiment: str, seed: int) -> list[dict[str, str]]:
    from keras_rl.runs.run_set import RunSet

    return RunSet.seed_at(ROOT / "results" / experiment / "faithful" / f"seed_{seed}").text_rows()


def main() -> int:
    lines = [
        "| cap | "
        + " | ".join(f"{e} seed {s}: first difference from AVX2 / from AVX-512" for e, s, _ in CASES)
        + " | wall time / uncapped |",
        "|---|" + "---|" * (len(CASES) + 1),
    ]
    uncapped = None
    for name, env in CAPS.items():
        cells, wall = [], 0.0
        for experiment, seed, episodes in CASES:
            with tempfile.TemporaryDirectory() as tmp:
                command = [sys.executable, "-m", "keras_rl", "reproduce", experiment, "--seeds", str(seed)]
                command += ["--episodes", str(episodes), "--no-progress", "--min-success-rate", "0", "--out", tmp]
                start = time.perf_counter()
                done = subprocess.run(command, env={**os.environ, **env}, capture_output=True, text=True, timeout=900)
                wall += time.perf_counter() - start
                if done.returncode not in (0, 1):
                    print(done.stderr, file=sys.stderr)
                    return 1
                got = rows(Path(tmp) / f"seed_{seed}" / "episodes.csv")
            avx2 = rows(AVX2 / experiment / "faithful" / f"seed_{seed}" / "episodes.csv")[:episodes]
            cells.append(f"{first_difference(got, avx2)} / {first_difference(got, committed(experiment, seed))}")
        uncapped = uncapped or wall
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {wall / uncapped:.2f} |")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
