"""The replay tests' cases, and their references for hosts of another instruction set (issue 52 item 7).

    python -m maintainers replay-references check --emulate EPYC-Rome --episodes 10 [--write]
    python -m maintainers replay-references make --emulate EPYC-Rome [--cases ID ...]
    python -m maintainers replay-references make --reference-set NAME [--cases ID ...]   # natively, here
    python -m maintainers replay-references probe --emulate EPYC-Rome --cases ID --episodes 6 \
        [--env K=V ...] [--native-env K=V ...]
    python -m maintainers replay-references make --reference-set portable-torch   # natively, any host
    python -m maintainers replay-references check --emulate Haswell --reference-set portable-torch \
        --episodes 12 --trace --write

The committed runs were made on AVX-512 hosts. On an AVX2 host TensorFlow's kernels round
differently (oneDNN's blocking, XLA's code), and capping the instruction set does not make the
bits travel (``docs/performance.md``). So a host of another instruction set replays against
references made on such a host: ``tests/replay_references/<set>/<committed seed folder>/episodes.csv``,
the host in ``<set>/host.json`` (``tests/test_committed_runs_replay.py``). PyTorch's bits also
follow the CPU's vendor (MKL's kernels), so an Intel Xeon with the committed AMD EPYC's instruction
set keeps PyTorch references of its own (``intel-xeon-avx512``, made natively: ``make`` without
``--emulate`` reruns each case here and keeps a reference only where the bits differ).

An AVX2 host is not always at hand. QEMU's user-mode emulator (``qemu-x86_64``, Debian's
``qemu-user``) runs a process on this host with the CPUID of another x86 model, and every library
here chooses its kernels from CPUID (oneDNN, MKL, XLA's LLVM, NumPy, PyTorch's ATen): with
``-cpu EPYC-Rome`` (AMD, AVX2 and FMA, no AVX-512) they take their AVX2 paths. ``check`` reruns
the cases whose references were made on a real AVX2 host under the emulator and compares them,
every column but wall time; ``make`` makes the missing references under it and records how in
``host.json``. ``probe`` runs a case both natively (with ``--native-env`` set, a cap say) and
under the emulator (``--env`` is set on both) and compares the two with each other and with the
committed run. The emulator is no test dependency: the tests read the references only.

The emulator computes every instruction as silicon does but the few whose bits the x86 manuals leave
to the chip (``APPROXIMATE``: the approximate reciprocal and reciprocal square root, x87's
transcendentals), which it computes exactly. ``check --trace`` and ``probe --trace`` count those a rerun
executes (``avx2/traced.md``). PyTorch's
float32 square root (MKL's vector math, in Adam's denominator) refines ``rsqrtps``, so no PyTorch
reference is made under the emulator. The PyTorch cases keep one set for every host instead,
``portable-torch``, made natively under PyTorch's portable arithmetic (``KERAS_RL_PORTABLE_TORCH=1``,
``keras_rl.torch.portable_arithmetic``), whose runs execute none of them, and checked under an
emulated Intel and AMD CPU.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from maintainers.checkout import ROOT

REFERENCES = ROOT / "tests" / "replay_references"
DEFAULT_EPISODES = 10
"""``check`` and ``probe``: the episodes of each case rerun and compared, where ``--episodes`` is not given."""
EMULATOR = "qemu-x86_64"
VALIDATED = ("keras",)
"""The frameworks whose runs ``check`` found the emulator to reproduce as a real AVX2 host does.
Under ``-cpu EPYC-Rome`` PyTorch's post 000 parts at episode 5 from a run on an AMD EPYC with its
kernels capped to AVX2 (which gives the committed bits). The cause, traced on an Intel Xeon
(``probe --trace``, ``avx2/traced.md``): torch's float32 ``sqrt`` is MKL's vector math, which refines the approximate
``rsqrtps``; QEMU computes that exactly, and each vendor's silicon its own way. So no PyTorch
reference is made under the emulator; the PyTorch cases replay whole under the portable arithmetic
(``PORTABLE_SET``), and ``make`` without ``--emulate`` on an AMD AVX2 host would make their native ones."""
VALIDATED_WHY = "PyTorch under the emulator is not checked against a real AVX2 host (VALIDATED)"
PORTABLE_SET = "portable-torch"
"""The PyTorch cases' references made under PyTorch's portable arithmetic
(``keras_rl.torch.portable_arithmetic``, ``KERAS_RL_PORTABLE_TORCH=1``): one set for every host
with AVX2, made natively here and checked under the emulator, Intel's and AMD's, with ``--trace``
(``<set>/emulation-<CPU>.md``)."""
APPROXIMATE = re.compile(
    rb"\b(v?rcp(?:14|28)?[ps]s|v?rsqrt(?:14|28)?[ps]s|fsin|fcos|fsincos|fptan|fpatan|f2xm1|fyl2x|fyl2xp1)\b"
)
"""Instructions whose bits the x86 manuals leave to the silicon: the approximate reciprocal and
reciprocal square root, and x87's transcendentals. QEMU computes them exactly (``rsqrtps`` of 2 gives
0.707106769 under it, 0.70690918 on the Intel Xeon of 2026-11-28), so a run that executes one under
the emulator is not what that CPU computes; a run that executes none computes there as silicon does
(every other instruction is IEEE arithmetic, exactly rounded)."""


@dataclass(frozen=True)
class Case:
    """One replay test: a committed run set's seeds rerun in one process, as their command made them."""

    id: str
    folder: str
    """The committed set under ``results/``."""
    experiment: str
    seeds: tuple[int, ...]
    episodes: int | None
    """Episodes to rerun; None: the whole run."""
    kind: str = "seed"
    """``seed`` (one seed, its recorded command), ``batch`` (one ``--seed-batch`` batch) or
    ``compiled`` (the compiled engine's seeds in one process, every seed after the first on the
    first one's kept program)."""
    extra: tuple[str, ...] = ()

    @property
    def framework(self) -> str:
        return self.extra[self.extra.index("--framework") + 1] if "--framework" in self.extra else "keras"

    def seed_folders(self) -> list[str]:
        return [f"{self.folder}/seed_{s}" for s in self.seeds]

    def command(self, out: Path, episodes: int | None = None, prefix: tuple[str, ...] = ()) -> list[str]:
        """The rerun's command (``episodes`` overrides the case's budget), after ``prefix``."""
        budget = self.episodes if episodes is None else episodes
        if self.kind == "seed":
            from maintainers.replay import plan_replay

            replay = plan_replay(ROOT / "results" / self.seed_folders()[0], self.experiment, budget)
            return [*prefix, *replay.command(out, *self.extra)]
        seeds = f"{self.seeds[0]}-{self.seeds[-1]}"
        head = [*prefix, sys.executable, "-m", "keras_rl", "reproduce", self.experiment, "--seeds", seeds]
        tail = ["--no-progress", "--min-success-rate", "0", "--out", str(out)]
        tail = ([] if budget is None else ["--episodes", str(budget)]) + tail
        if self.kind == "batch":
            return [*head, "--seed-batch", str(len(self.seeds)), *tail]
        return [*head, "--engine", "compiled", "--workers", "1", *tail]


CASES = (
    Case("post000-faithful-seed0", "pendulum/faithful", "pendulum", (0,), None),
    Case("post001-faithful-seed0", "mountaincar/faithful", "mountaincar", (0,), None),
    Case(
        "post000-torch-seed0-first12", "pendulum/faithful-torch", "pendulum", (0,), 12, extra=("--framework", "torch")
    ),
    Case("post003-seed0-first60", "cartpole/faithful", "cartpole", (0,), 60),
    # 200 episodes: 12,176 steps, past the tutorial's memory of 10,000, so its eviction is replayed too
    Case(
        "post003-torch-seed0-first200", "cartpole/faithful-torch", "cartpole", (0,), 200, extra=("--framework", "torch")
    ),
    # (posts 000 and 003's batched sets were regenerated on the compiled engine when issue 34
    # retired their stacked learners: their compiled seeds are replayed below)
    Case("post001-batch-of-10-first3", "mountaincar/seed-batch/batch10", "mountaincar", tuple(range(10)), 3, "batch"),
    Case("post000-compiled-seeds0-2", "engines/pendulum/compiled", "pendulum", (0, 1, 2), None, "compiled"),
    Case("post003-compiled-seeds0-1-first120", "engines/cartpole/compiled", "cartpole", (0, 1), 120, "compiled"),
)


def host_file(reference_set: str) -> Path:
    return REFERENCES / reference_set / "host.json"


def reference_rows(reference_set: str, seed_folder: str) -> Path:
    return REFERENCES / reference_set / seed_folder / "episodes.csv"


def emulated(cpu: str) -> tuple[str, ...]:
    """The prefix that runs a command on ``cpu``'s CPUID; a clear error where the emulator is missing."""
    from keras_rl.errors import KerasRLError

    if shutil.which(EMULATOR) is None:
        raise KerasRLError(f"{EMULATOR} is not installed (Debian: apt-get install qemu-user)")
    return (EMULATOR, "-cpu", cpu)


def emulator_version() -> str:
    out = subprocess.run([EMULATOR, "--version"], capture_output=True, text=True, check=True).stdout
    return out.splitlines()[0].strip()


def rerun(
    case: Case,
    prefix: tuple[str, ...],
    episodes: int | None,
    work: Path,
    env: dict[str, str] | None = None,
    approximate: collections.Counter | None = None,
) -> tuple[Path, float]:
    """Run ``case`` under ``prefix`` (and ``env`` added to this one's) into ``work``; its output
    folder and the seconds it took. With ``approximate`` (under the emulator), the instructions of
    ``APPROXIMATE`` in the code the run executed are counted into it, once per block QEMU translated
    (its ``-d in_asm`` log, read through a pipe as it is written)."""
    out = work / case.id
    work.mkdir(parents=True, exist_ok=True)
    reader = None
    if approximate is not None:
        log = work / f"{case.id}.in_asm"
        os.mkfifo(log)
        prefix = (*prefix, "-d", "in_asm", "-D", str(log))
        reader = threading.Thread(target=_count_approximate, args=(log, approximate))
        reader.start()
    start = time.monotonic()
    try:
        proc = subprocess.run(
            case.command(out, episodes, prefix), capture_output=True, text=True, env={**os.environ, **(env or {})}
        )
    finally:
        if reader is not None:
            _release(work / f"{case.id}.in_asm")
            reader.join()
    # 1: a run that fails its criterion, rows whole; a crash also exits 1, with a traceback
    if proc.returncode not in (0, 1) or "Traceback (most recent call last)" in proc.stderr:
        tail = "\n".join(line for line in proc.stderr.splitlines() if "TCG doesn't support" not in line)
        raise RuntimeError(f"{case.id}: exit {proc.returncode}\n{tail[-2000:]}")
    return out, time.monotonic() - start


def _count_approximate(log: Path, counts: collections.Counter) -> None:
    """Count ``APPROXIMATE``'s instructions in QEMU's instruction log at ``log`` (a pipe) until it closes."""
    tail = b""
    with open(log, "rb") as fh:
        while chunk := fh.read(1 << 20):
            text, _, tail = (tail + chunk).rpartition(b"\n")  # an instruction is never split across reads
            counts.update(m.decode() for m in APPROXIMATE.findall(text))
    counts.update(m.decode() for m in APPROXIMATE.findall(tail))


def _release(log: Path) -> None:
    """Let the reader of ``log`` end where the run never opened it (a crash before QEMU's log)."""
    try:
        os.close(os.open(log, os.O_WRONLY | os.O_NONBLOCK))
    except OSError:  # no reader waits: it has read to the end already
        pass


def approximate_shown(counts: collections.Counter) -> str:
    """``counts`` as a report cell: ``none``, or each instruction and its blocks."""
    if not counts:
        return "none"
    return ", ".join(f"`{name}` in {n} block{'s' * (n != 1)}" for name, n in sorted(counts.items()))


def set_env(reference_set: str) -> dict[str, str]:
    """What a rerun of ``reference_set``'s cases sets: PyTorch's portable arithmetic for its set."""
    from keras_rl.torch import PORTABLE_SWITCH

    return {PORTABLE_SWITCH: "1"} if reference_set == PORTABLE_SET else {}


def committed_rows(folder: str, episodes: int) -> list[dict[str, str]]:
    """The first ``episodes`` rows of committed seed ``folder`` (under ``results/``), without wall time."""
    from keras_rl.runs.run_set import RunSet

    return RunSet.seed_at(ROOT / "results" / folder).text_rows()[:episodes]


def _first_difference(expected: list[dict[str, str]], got: list[dict[str, str]]) -> str:
    from maintainers.replay import first_divergence

    d = first_divergence(expected, got)
    if d.identical and len(got) == len(expected):
        return f"the same bits, {len(expected)} episodes"
    if d.identical:
        return f"{len(got)} episodes against {len(expected)}"
    if not d.columns:
        return f"ends before episode {d.first_episode}"
    return f"differs at episode {d.first_episode} ({', '.join(d.columns)})"


def check(args: argparse.Namespace, prefix: tuple[str, ...], work: Path) -> list[str]:
    """Rerun under the emulator every case whose references a real host made; compare."""
    from maintainers.replay import seed_rows

    host = json.loads(host_file(args.reference_set).read_text())
    made_here = set(host.get("emulated", {}).get("references", {}))
    traced = " --trace" if args.trace else ""
    settings = set_env(args.reference_set)
    lines = [
        f"`python -m maintainers replay-references check --emulate {args.emulate} --reference-set "
        f"{args.reference_set} --episodes {args.episodes}{traced}` ({emulator_version()}, `-cpu {args.emulate}`), "
        f"on a host with {', '.join(_isa())}" + (f"; set on every run: {_shown(settings)}" if settings else "") + ":",
        "",
        f"| case | seed | episodes | against the {args.reference_set} reference | against the committed run |"
        + (" approximate instructions executed (`APPROXIMATE`) |" if args.trace else ""),
        "|---|---|---|---|---|" + ("---|" if args.trace else ""),
    ]
    for case in _chosen(args):
        folders = [
            f for f in case.seed_folders() if reference_rows(args.reference_set, f).is_file() and f not in made_here
        ]
        if not folders:
            continue
        counts: collections.Counter | None = collections.Counter() if args.trace else None
        out, seconds = rerun(case, prefix, args.episodes, work, settings, counts)
        print(f"{case.id}: {seconds:.0f} s under the emulator", file=sys.stderr)
        for folder in folders:
            got = seed_rows(out / Path(folder).name / "episodes.csv")
            ours = seed_rows(reference_rows(args.reference_set, folder))[: len(got)]
            committed = committed_rows(folder, len(got))
            lines.append(
                f"| {case.id} | {Path(folder).name} | {len(got)} | {_first_difference(ours, got)} | "
                f"{_first_difference(committed, got)} |"
                + (f" {approximate_shown(counts)} |" if counts is not None else "")
            )
    return lines


def _shown(settings: dict[str, str]) -> str:
    return " ".join(f"{k}={v}" for k, v in settings.items()) or "none"


def make(args: argparse.Namespace, prefix: tuple[str, ...], work: Path) -> list[str]:
    """Make the references the chosen cases lack, under the emulator or natively (no ``--emulate``:
    a set for this host's CPU, made here); record each in host.json."""
    from keras_rl.atomic import atomic_write_json, atomic_write_text
    from maintainers.replay import seed_rows

    path = host_file(args.reference_set)
    portable = args.reference_set == PORTABLE_SET
    host = json.loads(path.read_text()) if path.is_file() else (portable_host() if portable else this_host())
    command = "python -m maintainers replay-references make" + (
        f" --emulate {args.emulate}" if args.emulate else f" --reference-set {args.reference_set}"
    )
    made = {
        "made": f"{time.strftime('%Y-%m-%d')} at {_code()}",  # the code the runs import, read once
        "how": f"{emulator_version()}, -cpu {args.emulate}, on a host with {' '.join(_isa())}"
        if args.emulate
        else f"natively, on {this_host()['cpu_model']} with {' '.join(_isa())}; {_versions()}"
        + (f"; {_shown(set_env(args.reference_set))}" if portable else ""),
        "command": command + (f" --cases {' '.join(args.cases)}" if args.cases else ""),
    }
    where = "under the emulator" if args.emulate else "here"
    lines = ["| case | seed | episodes | against the committed run |", "|---|---|---|---|"]
    for case in _chosen(args):
        missing = [f for f in case.seed_folders() if not reference_rows(args.reference_set, f).is_file()]
        if not missing:
            continue
        if args.emulate and case.framework not in VALIDATED:
            lines.append(f"| {case.id} | - | - | not made: {VALIDATED_WHY} |")
            continue
        if portable and case.framework != "torch":
            continue  # the portable arithmetic is PyTorch's; TensorFlow's runs keep per-host references
        out, seconds = rerun(case, prefix, None, work, set_env(args.reference_set))
        print(f"{case.id}: {seconds:.0f} s {where}", file=sys.stderr)
        for folder in missing:
            ran = out / Path(folder).name
            got = seed_rows(ran / "episodes.csv")
            committed = committed_rows(folder, len(got))
            lines.append(f"| {case.id} | {ran.name} | {len(got)} | {_first_difference(committed, got)} |")
            if not portable and _committed_is_this_hosts(folder, case, native=not args.emulate):
                # the replay test reads the committed run here: a reference would never be read
                same = got == committed and len(got) == len(committed_rows(folder, case.episodes or 10**9))
                lines[-1] = lines[-1][:-2] + (
                    ": none kept, the committed run is this host's |"
                    if same
                    else ": none kept; MISMATCH, this host is expected to give the committed bits |"
                )
                continue
            # recorded before the files land: an interrupted make leaves a listed reference without
            # its rows (the tests fail on it), never rows that pass for a host's own
            kept = (
                host.setdefault("emulated", {}).setdefault("references", {})
                if args.emulate
                else host.setdefault("references", {})
            )
            kept[folder] = made
            atomic_write_json(path, host)
            target = reference_rows(args.reference_set, folder).parent
            target.mkdir(parents=True, exist_ok=True)
            for name in ("config.json", "episodes.csv"):  # the rows last: a seed is missing until they land
                atomic_write_text(target / name, (ran / name).read_text())
    return lines


def _committed_is_this_hosts(folder: str, case: Case, native: bool) -> bool:
    """Whether the replay test compares ``folder`` with its committed run on the host the references
    are made for (``replay.why_not_bit_exact``): only a native make can be that host."""
    from keras_rl.runs.run_set import RunSet
    from maintainers.replay import why_not_bit_exact

    provenance = RunSet.seed_at(ROOT / "results" / folder).summary_record().get("provenance", {})
    return native and why_not_bit_exact(provenance, framework=case.framework) is None


def this_host() -> dict:
    """A new reference set's host.json: this machine's CPU, and the references made on it."""
    from keras_rl.runs.provenance import cpu_model

    return {"cpu_model": cpu_model(), "cpu_isa": _isa(), "references": {}}


def portable_host() -> dict:
    """The portable set's host.json: no CPU of its own, the arithmetic it was made under, its references."""
    from keras_rl.torch import PORTABLE_CAPS, PORTABLE_SWITCH

    return {
        "portable": {"switch": f"{PORTABLE_SWITCH}=1", "sets": PORTABLE_CAPS, "optimizer_step": "fused"},
        "references": {},
    }


def _versions() -> str:
    """The library versions a run records (``provenance.library_versions``), torch's among them."""
    from keras_rl.runs.provenance import library_versions

    try:
        import torch  # noqa: F401  (library_versions names torch once it is imported)
    except ImportError:
        pass
    return ", ".join(f"{name} {version}" for name, version in library_versions("torch").items())


def _settings(pairs: list[str] | None) -> dict[str, str]:
    from keras_rl.errors import KerasRLError

    bad = [p for p in pairs or () if "=" not in p or not p.split("=", 1)[0]]
    if bad:
        raise KerasRLError(f"an environment setting is KEY=VALUE, not {', '.join(map(repr, bad))}")
    return dict(p.split("=", 1) for p in pairs or ())


def probe(args: argparse.Namespace, prefix: tuple[str, ...], work: Path) -> list[str]:
    """Each chosen case natively (``--env`` and ``--native-env``) and emulated (``--env``), compared."""
    from maintainers.replay import seed_rows

    both, native = _settings(args.env), _settings(args.native_env)
    lines = [
        f"Set on both: {_shown(both)}; natively only: {_shown(native)}; `-cpu {args.emulate}` ({emulator_version()}).",
        "",
        "| case | seed | episodes | emulated against native | emulated against committed | native against committed |"
        + (" approximate instructions executed under the emulator |" if args.trace else ""),
        "|---|---|---|---|---|---|" + ("---|" if args.trace else ""),
    ]
    for case in _chosen(args):
        ran, _ = rerun(case, (), args.episodes, work / "native", {**both, **native})
        counts: collections.Counter | None = collections.Counter() if args.trace else None
        emulated_out, seconds = rerun(case, prefix, args.episodes, work / "emulated", both, counts)
        print(f"{case.id}: {seconds:.0f} s under the emulator", file=sys.stderr)
        for folder in case.seed_folders():
            name = Path(folder).name
            here, there = seed_rows(ran / name / "episodes.csv"), seed_rows(emulated_out / name / "episodes.csv")
            committed = committed_rows(folder, len(here))
            lines.append(
                f"| {case.id} | {name} | {len(here)} | {_first_difference(here, there)} | "
                f"{_first_difference(committed, there)} | {_first_difference(committed, here)} |"
                + (f" {approximate_shown(counts)} |" if counts is not None else "")
            )
    return lines


def _isa() -> list[str]:
    from keras_rl.runs.provenance import cpu_isa

    return cpu_isa()


def _code() -> str:
    """The commit and the package's own tree the runs import, marked where it has uncommitted changes."""
    from keras_rl.runs.provenance import git_state

    state = git_state()
    dirty = f"+dirty.{str(state['diff_sha256'])[:12]}" if state["dirty"] else ""
    return f"commit {str(state['commit'])[:8]} (keras_rl tree {str(state['code_tree'])[:12]}{dirty})"


def _chosen(args: argparse.Namespace) -> list[Case]:
    from keras_rl.errors import KerasRLError

    known = {c.id for c in CASES}
    unknown = sorted(set(args.cases or ()) - known)
    if unknown:
        raise KerasRLError(f"no replay case {', '.join(unknown)}; the cases are {', '.join(sorted(known))}")
    return [c for c in CASES if not args.cases or c.id in args.cases]


def run(args: argparse.Namespace) -> int:
    from keras_rl.errors import KerasRLError

    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", args.reference_set):
        raise KerasRLError(f"--reference-set names one folder under {REFERENCES}, not {args.reference_set!r}")
    if args.reference_set == PORTABLE_SET and args.action == "make" and args.emulate:
        raise KerasRLError(f"the {PORTABLE_SET} set is made natively (one set for every host); check it with --emulate")
    if args.trace and (args.action == "make" or args.emulate is None):
        raise KerasRLError("--trace counts the instructions a run executes under the emulator: check's and probe's")
    native = args.action == "make" and args.emulate is None
    if args.emulate is None and not native:
        raise KerasRLError(f"{args.action} compares a run under the emulator: name its CPU with --emulate")
    if not host_file(args.reference_set).is_file() and not native:
        raise KerasRLError(f"no reference set {args.reference_set!r}: {host_file(args.reference_set)} is missing")
    if native and args.reference_set != PORTABLE_SET and host_file(args.reference_set).is_file():
        made_on, here = json.loads(host_file(args.reference_set).read_text()), this_host()
        if (made_on["cpu_model"], made_on["cpu_isa"]) != (here["cpu_model"], here["cpu_isa"]):
            raise KerasRLError(
                f"reference set {args.reference_set!r} is not this host's ({made_on['cpu_model']}; "
                f"{', '.join(made_on['cpu_isa'])}): make it natively in a set of its own (--reference-set NAME), "
                "or under the emulator with --emulate"
            )
    if args.action != "check" and args.write:
        raise KerasRLError(f"--write saves check's report; {args.action} writes none")
    if args.action == "probe" and not args.cases:
        raise KerasRLError("probe runs the cases named by --cases, natively and emulated")
    if args.action == "check" and args.write and args.cases:
        raise KerasRLError("--write saves check's report over every case; leave out --cases")
    if args.action == "make" and args.episodes is not None:
        raise KerasRLError("make reruns each case as long as the case does; --episodes is check's and probe's")
    if args.episodes is None:
        args.episodes = DEFAULT_EPISODES
    if args.episodes < 1:
        raise KerasRLError(f"--episodes must be at least 1, not {args.episodes}")
    if args.action != "probe" and (args.env or args.native_env):
        raise KerasRLError(f"--env and --native-env are probe's; {args.action} runs as the tests do")
    _chosen(args)  # bad input is named before anything runs
    _settings(args.env)
    _settings(args.native_env)
    prefix = emulated(args.emulate) if args.emulate else ()
    with tempfile.TemporaryDirectory(prefix="replay-references-") as work:
        lines = {"check": check, "make": make, "probe": probe}[args.action](args, prefix, Path(work))
    text = "\n".join(lines)
    print(text)
    if args.action == "check" and args.write and not lines[-1].startswith("| "):
        raise KerasRLError(
            f"no case has a reference a real {args.reference_set} host made: "
            f"{REFERENCES / args.reference_set} kept as it is"
        )
    if args.action == "check" and args.write:
        from keras_rl.atomic import atomic_write_text

        report = REFERENCES / args.reference_set / f"emulation-{args.emulate}.md"
        atomic_write_text(
            report, f"# The emulator ({args.emulate}) against the {args.reference_set} references\n\n{text}\n"
        )
        print(f"wrote {report}")
    return 0
