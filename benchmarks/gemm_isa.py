"""How fast this CPU multiplies the vectorised engine's matrices, by library and instruction set
(issue 53 item 3: where the 4x per seed stops).

    python benchmarks/gemm_isa.py [--rounds 5]

The engine's four large products a seed-step are 128x128 by 128x128 (``docs/performance.md``);
torch's CPU ``bmm`` runs them through MKL. Each row times a batch of 8 such products, one thread,
best of ``--rounds`` rounds of 200, in a fresh process (the environment variables pick the kernels
at load time): torch's ``bmm`` (MKL, as the engine calls it), then NumPy's ``matmul`` (OpenBLAS)
with the kernels its run-time dispatch picks and with its AVX-512 kernels forced
(``OPENBLAS_CORETYPE=SkylakeX``). One run, one machine: compare the rows with each other.
Below the table: the CPU's vendor, and the class of processors MKL says it dispatched for (its
``MKL_VERBOSE=1`` header; on a CPU it does not take for Intel's it names "Intel(R) Architecture
processors", its generic class, instead of an instruction set).
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
from pathlib import Path

ROWS = (
    ("torch.bmm (MKL), as the engine calls it", "torch", {}),
    ("torch.bmm (MKL), MKL_ENABLE_INSTRUCTIONS=AVX512", "torch", {"MKL_ENABLE_INSTRUCTIONS": "AVX512"}),
    ("numpy matmul (OpenBLAS), its own dispatch", "numpy", {}),
    ("numpy matmul (OpenBLAS), OPENBLAS_CORETYPE=Haswell (AVX2)", "numpy", {"OPENBLAS_CORETYPE": "Haswell"}),
    ("numpy matmul (OpenBLAS), OPENBLAS_CORETYPE=SkylakeX (AVX-512)", "numpy", {"OPENBLAS_CORETYPE": "SkylakeX"}),
)

PROBE = """
import sys, time
lib, rounds = sys.argv[1], int(sys.argv[2])
if lib == "torch":
    import torch
    torch.set_num_threads(1)
    a, b = torch.randn(8, 128, 128), torch.randn(8, 128, 128)
    mul = lambda: torch.bmm(a, b)
else:
    import numpy as np
    a, b = np.random.rand(8, 128, 128).astype(np.float32), np.random.rand(8, 128, 128).astype(np.float32)
    mul = lambda: a @ b
for _ in range(50):
    mul()
best = float("inf")
for _ in range(rounds):
    start = time.perf_counter()
    for _ in range(200):
        mul()
    best = min(best, (time.perf_counter() - start) / 200)
print(best)
"""


def mkl_dispatch() -> str:
    """The processor class MKL names in its verbose header on one ``bmm``, as torch loads it."""
    env = {**os.environ, "MKL_VERBOSE": "1", "MKL_NUM_THREADS": "1"}
    probe = "import torch; a = torch.randn(8, 128, 128); torch.bmm(a, a)"
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    header = next((line for line in out.stdout.splitlines() if line.startswith("MKL_VERBOSE oneMKL")), "")
    for_, _, rest = header.partition(" for ")
    return rest.split(",")[0] if for_ else "(MKL printed no header)"


def cpu_vendor() -> str:
    """``vendor_id`` and ``model name`` from /proc/cpuinfo, where there is one."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return platform.processor() or "unknown"
    fields = {key.strip(): value.strip() for key, _, value in (line.partition(":") for line in lines if ":" in line)}
    return ", ".join(fields.get(k, "") for k in ("vendor_id", "model name")).strip(", ")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    flops = 8 * 2 * 128**3
    print(f"`python benchmarks/gemm_isa.py --rounds {args.rounds}` ({platform.machine()}, one thread):\n")
    print("| library and kernels | ms per 8 products of 128x128x128 | GFLOP/s |\n|---|---:|---:|")
    for label, lib, extra in ROWS:
        env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", **extra}
        out = subprocess.run(
            [sys.executable, "-c", PROBE, lib, str(args.rounds)], env=env, capture_output=True, text=True, check=True
        )
        seconds = float(out.stdout.split()[-1])
        print(f"| {label} | {seconds * 1e3:.3f} | {flops / seconds / 1e9:.0f} |")
    print(f"\nCPU: {cpu_vendor()}. MKL dispatched for: {mkl_dispatch()}.")


if __name__ == "__main__":
    main()
