"""Where PyTorch's bits come from the silicon: its float32 square root, and the CPU's ``rsqrtps``.

    python benchmarks/approximate_bits.py [--values N]
    qemu-x86_64 -cpu EPYC-Rome .venv/bin/python benchmarks/approximate_bits.py   # the same under an emulated CPU
    MKL_CBWR=COMPATIBLE python benchmarks/approximate_bits.py                     # any MKL or ATen setting

Prints one table row: the CPU's vendor string as the process sees it (under QEMU, the emulated
one), the kernels ATen chose, the MKL and ATen settings in the environment, how many of ``N``
float32 square roots ``torch.sqrt`` does not round correctly (against float64's, rounded), and what
``rsqrtss`` of 2 gives (run as machine code in this process). The x86 manuals leave
``rsqrtss``'s bits to the chip, within a relative 1.5 * 2^-12; QEMU computes it exactly. torch's
square root is MKL's vector math, which refines that estimate (``maintainers/replay_references.py``
traces it), so its rounding follows the chip (``docs/performance.md``, issue 52 item 7).
"""

from __future__ import annotations

import argparse
import os

RSQRTSS = bytes.fromhex("f30f52c0c3")  # rsqrtss xmm0, xmm0; ret
CPUID_0 = bytes.fromhex("534989f831c00fa2418918418950044189480" + "85bc3")
"""push rbx; mov r8, rdi; xor eax, eax; cpuid; mov [r8], ebx; mov [r8+4], edx; mov [r8+8], ecx; pop rbx; ret"""


def machine_code(code: bytes, restype, *argtypes):
    """``code`` as a C function of this process, so that under QEMU it runs emulated too (a program
    started from here would run natively: qemu-user does not follow ``exec``)."""
    import ctypes
    import mmap

    page = mmap.mmap(-1, mmap.PAGESIZE, prot=mmap.PROT_READ | mmap.PROT_WRITE | mmap.PROT_EXEC)
    page.write(code)
    address = ctypes.addressof(ctypes.c_char.from_buffer(page))
    function = ctypes.CFUNCTYPE(restype, *argtypes)(address)
    function.page = page  # the page lives as long as the function
    return function


def vendor() -> str:
    """CPUID's vendor string (under QEMU, the emulated CPU's; ``/proc/cpuinfo`` keeps the host's)."""
    import ctypes

    out = ctypes.create_string_buffer(12)
    machine_code(CPUID_0, None, ctypes.c_char_p)(out)
    return out.raw.decode()


def rsqrt_of_two() -> str:
    import ctypes

    return f"{machine_code(RSQRTSS, ctypes.c_float, ctypes.c_float)(2.0):.9g}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--values", type=int, default=100_000, help="square roots to check (default 100,000)")
    args = parser.parse_args()
    if args.values < 1:
        parser.error(f"--values must be at least 1, not {args.values}")
    import numpy as np
    import torch

    torch.set_num_threads(1)
    x = torch.rand(args.values, generator=torch.Generator().manual_seed(0)) + 0.5
    exact = np.sqrt(x.numpy().astype(np.float64)).astype(np.float32)
    wrong = int((x.sqrt().numpy() != exact).sum())
    settings = " ".join(f"{k}={os.environ[k]}" for k in ("MKL_CBWR", "ATEN_CPU_CAPABILITY") if k in os.environ)
    print("| vendor | ATen's kernels | settings | torch.sqrt not correctly rounded | rsqrtss(2) |")
    print("|---|---|---|---:|---|")
    print(
        f"| {vendor()} | {torch.backends.cpu.get_cpu_capability()} | {settings or 'none'} | "
        f"{wrong:,} of {args.values:,} | {rsqrt_of_two()} |"
    )


if __name__ == "__main__":
    main()
