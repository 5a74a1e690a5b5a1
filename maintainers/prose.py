"""The numbers in the docs' prose, written from the data between markers (issue 71 item 7).

    python -m maintainers tables prose           # the pages whose prose is stale, and what changes
    python -m maintainers tables prose --write   # write every claim's block

Each claim is a page, a sentence fragment with ``{}`` slots, and a function that computes the
slots from the committed runs (``RunSet``, ``maintainers.certified.arm``) or from a generated file
(``results/forest.json``, a report's per-seed table). The formatted fragment is the page's text
between ``<!-- prose:ID -->`` and ``<!-- /prose -->``, an HTML comment pair that neither GitHub
nor the docs site shows; ``ID`` is the fragment's first words. The whole block is written here, so
a number typed into a page by hand, or data that moved under it, makes the page differ from what
this module writes (``tests/test_generated.py`` regenerates and compares).
"""

from __future__ import annotations

import argparse
import gzip
import json
import re
from collections.abc import Callable
from functools import cache
from pathlib import Path

import numpy as np

from keras_rl.atomic import atomic_write_text
from keras_rl.errors import ConfigError
from keras_rl.report.equivalence import CONVERGED_AT_END, FIRST_PASSING, Arm
from keras_rl.report.stats import fisher_exact
from keras_rl.runs.run_set import RunSet
from maintainers.certified import arm, certifications, reading

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


def page(name: str) -> str:
    return re.sub(r"\s+", " ", (ROOT / name).read_text())


@cache
def forest(group: str, label: str) -> dict:
    rows = json.loads((RESULTS / "forest.json").read_text())
    return next(
        r for r in (rows["rows"] if isinstance(rows, dict) else rows) if (r["group"], r["label"]) == (group, label)
    )


def interval(point: dict) -> tuple[str, str, str]:
    return tuple(f"{point[k]:.3g}" for k in ("estimate", "low", "high"))  # type: ignore[return-value]


def compiled_001() -> dict:
    return forest("compiled engine vs Gymnasium loop", "mountaincar")


def table_pairs(report: str) -> list[tuple[str, str]]:
    """The per-seed table of a ``seed_batch_compare`` report: each seed's two "reached at" cells."""
    rows = [
        line.split("|")[1:-1] for line in (RESULTS / report).read_text().splitlines() if re.match(r"\| \d+ \|", line)
    ]
    return [(r[3].strip(), r[4].strip()) for r in rows]


def same_in_table(report: str) -> tuple[int, int]:
    pairs = table_pairs(report)
    return sum(a == b for a, b in pairs), len(pairs)


def paired(keras: dict, torch: dict, seeds) -> dict[str, int]:
    """Seeds on which two arms' first passing episodes agree; and agree with success too; and
    agree by the code's old reading (the episode kept only for a seed converged at the end)."""
    old = lambda r: r["reached_at_episode"] if r["success"] else None  # noqa: E731
    return {
        "first": sum(keras[s]["reached_at_episode"] == torch[s]["reached_at_episode"] for s in seeds),
        "and_success": sum(
            (keras[s]["reached_at_episode"], keras[s]["success"])
            == (torch[s]["reached_at_episode"], torch[s]["success"])
            for s in seeds
        ),
        "old": sum(old(keras[s]) == old(torch[s]) for s in seeds),
        "success": sum(keras[s]["success"] == torch[s]["success"] for s in seeds),
    }


@cache
def planned_001(matched: bool) -> dict:
    """Post 001's Keras-against-PyTorch reading at its planned seeds, with the medians by both readings."""
    c = next(c for c in certifications() if c.post == "mountaincar" and c.matched_init == matched)
    read = reading(c)
    keras, torch = arm(c.keras), arm(c.torch)
    budget = int(next(iter(keras.values()))["budget_episodes"])

    def median(a: Arm, how: str) -> str:
        return f"{np.median([budget + 1 if e is None else e for e in a.episodes(how)]):g}"

    return {
        "read": read,
        "medians": {how: [median(a, how) for a in read["arms"]] for how in (FIRST_PASSING, CONVERGED_AT_END)},
        "paired": paired(keras, torch, range(c.planned)),
        "n": c.planned,
    }


def shared_median(how: str) -> str:
    """Post 001's matched-init median at its planned seeds by one reading, where both arms share it."""
    medians = planned_001(True)["medians"][how]
    return medians[0] if len(set(medians)) == 1 else "differs"


def engines_001() -> dict:
    gym = arm(("checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199"))
    compiled = arm(("engines/mountaincar/compiled",))
    return paired(gym, compiled, sorted(gym))


def engines_001_successes() -> tuple[int, int]:
    """Post 001's seeds that end converged, of 200: the compiled engine's and the Gymnasium loop's."""
    return tuple(  # type: ignore[return-value]
        sum(r["success"] for r in arm(sets).values())
        for sets in (
            ("engines/mountaincar/compiled",),
            ("checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199"),
        )
    )


def cartpole_first_ten() -> tuple:
    from scipy.stats import mannwhitneyu

    arms = [
        [r for r in RunSet(RESULTS / "cartpole" / folder).summary_records() if r["seed"] < 10]
        for folder in ("faithful", "faithful-torch")
    ]
    k, t = (sum(bool(r["success"]) for r in a) for a in arms)
    hits = [[r["reached_at_episode"] for r in a if r["success"]] for a in arms]
    return k, len(arms[0]), t, len(arms[1]), fisher_exact(k, 10, t, 10), mannwhitneyu(*hits).pvalue


def cartpole_engines() -> tuple:
    arms = [Arm.of(RunSet(RESULTS / "engines" / "cartpole" / e).summary_records()) for e in ("compiled", "gymnasium")]
    budget = 600
    over_hits = [np.median(a.hits(CONVERGED_AT_END)) for a in arms]
    over_all = [np.median([budget + 1 if e is None else e for e in a.episodes()]) for a in arms]
    return (*over_hits, budget + 1, *over_all, over_all[0] / over_all[1])


def fits(table: str) -> dict[str, str]:
    """``seed_plan.py``'s table: seeds per arm -> P(median-ratio interval fits), as printed."""
    rows = [
        line.split("|")[1:-1] for line in (RESULTS / table).read_text().splitlines() if re.match(r"\| \d+ \|", line)
    ]
    return {r[0].strip(): r[2].strip() for r in rows}


def ablation(point: str) -> dict:
    rows = json.loads((RESULTS / "mountaincar" / "ablations" / "sweep.json").read_text())["points"]
    return next(r for r in rows if r["point"] == point)


def audit_counts() -> tuple[int, int, int, int]:
    """results/AUDIT.json: sets audited; committed sets (``results/MANIFEST.json``, which
    ``python -m maintainers manifest`` writes from every set and its test holds to them); seeds rerun
    to the same bits; mismatches."""
    results = json.loads((RESULTS / "AUDIT.json").read_text())["results"]
    same = sum(v["verdict"] == "same bits" for r in results for v in r["by_seed"].values())
    sets = len(json.loads((RESULTS / "MANIFEST.json").read_text()))
    return len(results), sets, same, sum(r["mismatches"] for r in results)


POP_600 = "mountaincar ablation vs faithful, the planned seeds"
POP_ARMS = (
    tuple(f"mountaincar/ablations-gymnasium/popping_buffer=false-seeds-{a}-{a + 49}" for a in range(0, 600, 50)),
    ("checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199", "mountaincar/faithful-seeds-200-599"),
)


def popping_600() -> tuple[int, int]:
    """Seeds that end converged of 0-599, the ablation's arm and the faithful one."""
    return tuple(sum(r["success"] for s, r in arm(sets).items() if s < 600) for sets in POP_ARMS)  # type: ignore[return-value]


def popping_600_medians() -> tuple[float, float]:
    """Each arm's median first passing episode over seeds 0-599 (101 for a seed that never passed)."""
    return tuple(  # type: ignore[return-value]
        float(
            np.median(
                [101 if e is None else e for e in Arm.of([r for s, r in arm(sets).items() if s < 600]).episodes()]
            )
        )
        for sets in POP_ARMS
    )


def real_003() -> dict:
    """Post 003's sensitive tier on real runs (``results/checks/real_checks.json``)."""
    return json.loads((RESULTS / "checks" / "real_checks.json").read_text())["posts"]["cartpole"]


def real_003_sizes() -> tuple[str, str, str]:
    rows = {r["n"]: r for r in real_003()["sizes"]}
    best = max(max(r["x0.90"], r["x1.10"]) for r in rows.values())
    return f"{rows[40]['x0.90']:.2f}", f"{rows[40]['x1.10']:.2f}", f"{best:.2f}"


def signed(d: dict) -> str:
    """A median difference as the FIDELITY table writes it: +18 [+15, +23]."""
    return f"{d['estimate']:+g} [{d['low']:+g}, {d['high']:+g}]"


def compare_001(matched: bool) -> dict:
    return json.loads(
        (RESULTS / "compare" / "mountaincar" / ("matched-init" if matched else "") / "result.json").read_text()
    )


@cache
def fix_and_published(variant: str, fw: str, seeds: int) -> tuple[int, int]:
    """Successes on seeds 0 to ``seeds`` - 1 of a tutorial-fix proposal's arm, then of the arm as
    published that it is read against (``maintainers/tutorial_fix.py``)."""
    from maintainers.tutorial_fix import PUBLISHED, TUTORIAL_FIXES

    (fix,) = [f for f in TUTORIAL_FIXES if f.variant == variant]
    proposal, published = arm((fix.folder(fw),)), arm(PUBLISHED[fw])
    return tuple(sum(a[s]["success"] for s in range(seeds)) for a in (proposal, published))  # type: ignore[return-value]


@cache
def fix_report(name: str) -> dict[str, tuple[str, ...]]:
    """A report of ``reproductions/tutorial_fix.py`` under ``results/cartpole/tutorial-fix/``
    (``tests/test_tutorial_fix.py`` remakes each from the runs), as the findings quote it: per arm
    (the table's first column) its success count, Wilson interval, median episode, a CPU reader's
    mean duration and its IQR, and the median longest episode; per reading of the planned seeds
    ("success", "ratio") its estimate and 90% interval."""
    text = (RESULTS / "cartpole" / "tutorial-fix" / name).read_text()
    cells: dict[str, tuple[str, ...]] = {}
    for line in text.splitlines():
        row = [c.strip() for c in line.split("|")[1:-1]]
        if len(row) == 7 and re.fullmatch(r"\d+/\d+ \(.*\)", row[3]):
            won, wilson = re.fullmatch(r"(\S+) \((.*)\)", row[3]).groups()  # type: ignore[union-attr]
            mean, iqr = re.fullmatch(r"(\S+) \((.*)\)", row[5]).groups()  # type: ignore[union-attr]
            cells[row[0]] = (won, wilson, row[4], mean, iqr, f"{float(row[6].split()[0]):g}")
    for key, what in (("success", "success rate difference"), ("ratio", "median episodes to threshold, ratio")):
        found = re.search(rf"- {what}: \*\*[^*]+\*\* \(([^;]+); 90% interval (\S+) to (\S+),", text)
        assert found, (name, what)
        cells[key] = found.groups()
    return cells


def quoted(name: str, label: str, *, published: int, cpu: int = 0) -> tuple[str, ...]:
    """A tutorial-fix report's reading in the order the findings quote it: the proposal's (``label``)
    success and Wilson interval; the published arm's success, with its interval if ``published``
    is 2; the success difference and its 90% interval; both medians; the ratio and its interval;
    then, if ``cpu``, a CPU reader's mean duration: the proposal's with its IQR, and the published
    arm's (with its IQR if ``cpu`` is 2)."""
    cells = fix_report(name)
    fix, base = cells[label], cells["published"]
    said = (*fix[:2], *base[:published], *cells["success"], fix[2], base[2], *cells["ratio"])
    return said + ((*fix[3:5], *base[3 : 3 + cpu]) if cpu else ())


def engine_check() -> dict:
    """The tutorial-fix plan's check of the vectorised engine on PR #3384's values (the forest's row)."""
    return forest(
        "vectorised PyTorch engine vs the tutorial's own code", "cartpole, pytorch/tutorials PR #3384's values"
    )


@cache
def thousand_seeds() -> dict:
    """The H200 run of ``benchmarks/thousand_seeds.py`` (issue 53 item 4): its report, its chunks'
    full-batch time per step, and the seeds whose 100-episode mean of steps reaches 475."""
    here = RESULTS / "cartpole" / "vectorised-torch" / "h200"
    report = json.loads((here / "report.json").read_text())
    rows = np.asarray(report["chunks"]["rows"], dtype=float)
    with gzip.open(here / "episodes.csv.gz", "rt") as fh:
        table = np.loadtxt(fh, delimiter=",", skiprows=1, usecols=(0, 2))
    reached = 0
    for seed in np.unique(table[:, 0]):
        steps = table[table[:, 0] == seed, 1]
        reached += bool((np.convolve(steps, np.ones(100) / 100, mode="valid") >= 475).any())
    return {
        **report,
        "full_batch_ms": float(np.median(rows[rows[:, 1] == report["S"], 2])),
        "reached": reached,
        "rows": len(table),
    }


XEON = RESULTS / "cartpole" / "vectorised-torch" / "xeon-cpu"
PINNED = RESULTS / "cartpole" / "vectorised-torch" / "xeon-pinned"
"""The project's own machine as that Xeon's model, with the pinned torch (2026-11-28)."""


def markdown_rows(text: str) -> dict[str, list[str]]:
    """A markdown table's rows: each row's cells after the first, keyed by the first, which must be unique."""
    rows = [line.split("|")[1:-1] for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    keys = [r[0].strip() for r in rows]
    assert len(set(keys)) == len(keys), f"a first cell repeats: {keys}"
    return {k: [c.strip() for c in r[1:]] for k, r in zip(keys, rows)}


def best_arm(rows: dict[str, list[str]]) -> tuple[str, str]:
    """The vectorised arm of a ``benchmarks/torch_vectorised.py`` table with the best ratio to the
    tutorial's code: its S (``S=8``) and that ratio, as printed (bold marks dropped)."""
    ratios = {arm: cells[1].strip("*") for arm, cells in rows.items() if arm.startswith("vectorised")}
    arm = max(ratios, key=lambda a: float(ratios[a].rstrip("x")))
    return arm.split(", ")[1], ratios[arm]


def best_ratio(rows: dict[str, list[str]]) -> str:
    """The best ratio to the tutorial's code over a ``benchmarks/torch_vectorised.py`` table's vectorised arms."""
    return best_arm(rows)[1]


EPYC = RESULTS / "cartpole" / "vectorised-torch" / "epyc-cpu"
"""The project's machine as an AMD EPYC with AVX-512, with the pinned torch (2026-11-30)."""


def span(*values: str, suffix: str = "") -> tuple[str, str]:
    """The lowest and the highest of printed numbers (``suffix``, such as ``x``, dropped to compare)."""
    ordered = sorted(values, key=lambda v: float(v.rstrip(suffix)))
    return ordered[0], ordered[-1]


@cache
def epyc() -> dict:
    """The AMD EPYC's figures for issue 53 item 3, from the outputs in ``epyc-cpu/``: the benchmark's
    run over every S (``torch_vectorised.txt``) and over S=8 and 16 (``torch_vectorised_sizes.txt``),
    each figure as the pair (lowest, highest) over the two runs, and ``gemm_isa.txt``'s products."""
    runs = [markdown_rows((EPYC / name).read_text()) for name in ("torch_vectorised.txt", "torch_vectorised_sizes.txt")]
    products = markdown_rows((EPYC / "gemm_isa.txt").read_text())
    one = runs[0]
    return {
        "run": one,
        "sizes": runs[1],
        "tutorial": span(*(r["the tutorial's code (gathered)"][0] for r in runs)),
        "s8": span(*(r["vectorised, S=8, compiled"][0] for r in runs)),
        "best": span(*(best_ratio(r) for r in runs), suffix="x"),
        "s1_ratio": one["vectorised, S=1, compiled"][1],
        "bmm": products["torch.bmm (MKL), as the engine calls it"][0],
        "products": products,
    }


EPYC_ARMS = (
    "the tutorial's code (gathered)",
    *(f"vectorised, S={s}, {way}" for way in ("eager", "compiled") for s in (1, 8, 32)),
)
"""The rows of ``benchmarks/torch_vectorised.py``'s table over every S, in its order."""

GEMM_ROWS = (
    "torch.bmm (MKL), as the engine calls it",
    "torch.bmm (MKL), MKL_ENABLE_INSTRUCTIONS=AVX512",
    "numpy matmul (OpenBLAS), its own dispatch",
    "numpy matmul (OpenBLAS), OPENBLAS_CORETYPE=Haswell (AVX2)",
    "numpy matmul (OpenBLAS), OPENBLAS_CORETYPE=SkylakeX (AVX-512)",
)
"""The rows of ``benchmarks/gemm_isa.py``'s table."""


def faster_products() -> tuple[str, ...]:
    """docs/performance.md's estimate: the S=8 step with its products at OpenBLAS's AVX-512 rate. A
    seed's step makes four of the 128x128x128 products that ``gemm_isa.py`` times eight of, so the
    products take half its ``bmm`` time of each seed-env-step."""
    products, run = epyc()["products"], epyc()["run"]
    bmm, fast = products[GEMM_ROWS[0]], products[GEMM_ROWS[-1]]
    step = float(run["vectorised, S=8, compiled"][0])
    share = float(bmm[0]) / 2 / step
    estimate = step * (1 - share + share * float(fast[0]) / float(bmm[0]))
    tutorial = float(run["the tutorial's code (gathered)"][0])
    return (
        fast[1],
        bmm[1],
        f"{estimate:.3g}",
        run["vectorised, S=8, compiled"][0],
        f"{share:.0%}",
        f"{tutorial / estimate:.1f}x",
    )


def compile_seconds() -> tuple[str, str]:
    """The fewest and the most seconds a compiled arm of the run over every S took to compile."""
    run = epyc()["run"]
    return span(*(cells[2] for arm, cells in run.items() if arm.endswith("compiled")))


TARGET = 4.0
"""Issue 53's target: the vectorised engine steps a seed this many times faster than the tutorial's code."""


def met(ratio: str) -> str:
    return "met" if float(ratio.rstrip("x")) >= TARGET else "not met"


def cpu_named(folder: Path) -> str:
    """The CPU's vendor and model as ``benchmarks/gemm_isa.py``'s last line names them."""
    named = re.search(r"^CPU: (.*)\. MKL dispatched for:", (folder / "gemm_isa.txt").read_text(), re.M)
    assert named, "gemm_isa.txt names no CPU"
    return named[1]


STACKED_PATHS = RESULTS / "engines" / "stacked-paths"
RETIRE_AT = 1.25
"""Issue 51's rule: a stacked learner is retired where a seed alone costs at most this per seed."""


STACKED_POSTS = {
    "post 001": "post 001 (Keras), the configs the compiled engine refuses",
    "post 000 (PyTorch port)": "post 000 (PyTorch port)",
    "post 001 (PyTorch port)": "post 001 (PyTorch port)",
}
"""Each stacked path as ``benchmarks/seed_batch.py --table`` names it, and as ``stacked-paths/README.md`` does."""


def stacked_kept() -> bool:
    """Whether every stacked path stays by issue 51's rule."""
    return all(stacked_cost(post)[2] == "yes" for post in STACKED_POSTS)


def stacked_cost(post: str) -> tuple[str, str, str]:
    """``benchmarks/seed_batch.py --table``'s 10 seeds against one seed alone, for ``post`` as its
    table names it: that ratio, what a seed alone costs against a seed of the batch, and whether
    the path stays by issue 51's rule."""
    rows = markdown_rows((STACKED_PATHS / "table.txt").read_text())
    batch = rows[f"{post}, 10 seeds in one process against one solo seed"][2]
    alone = 10 / float(batch.rstrip("x"))
    return batch, f"{alone:.2f}x", "yes" if alone > RETIRE_AT else "no"


def study_speedup(post: str) -> str:
    """The same run's 30-seed study: how much faster ``--seed-batch auto`` ran than seeds alone."""
    rows = markdown_rows((STACKED_PATHS / "table.txt").read_text())
    return next(cells[2].split()[0] for what, cells in rows.items() if what.startswith(f"{post}, a 30-seed study"))


def xeon(name: str) -> dict[str, list[str]]:
    """A table the Intel Xeon's CPU printed (issue 53 item 3, ``xeon-cpu/README.md``)."""
    return markdown_rows((XEON / name).read_text())


def mkl_header(folder: Path = XEON) -> str:
    """The instruction set MKL's verbose header named on a Xeon (``benchmarks/gemm_isa.py``'s last line)."""
    named = re.search(
        r"MKL dispatched for: Intel\(R\) 64 architecture (.*)\.$", (folder / "gemm_isa.txt").read_text(), re.M
    )
    assert named, "gemm_isa.txt names no MKL dispatch"
    return named[1]


def mkl_pair() -> dict[str, dict[str, list[str]]]:
    """Run 3 on the Xeon (``mkl_avx512_step.txt``): the S=8 table under MKL's own kernels and under
    ``MKL_ENABLE_INSTRUCTIONS=AVX512``, from the runs that printed one (the last of each)."""
    parts = re.split(r"^== MKL_ENABLE_INSTRUCTIONS=(\S+)$", (XEON / "mkl_avx512_step.txt").read_text(), flags=re.M)
    return {kernels: markdown_rows(body) for kernels, body in zip(parts[1::2], parts[2::2]) if "|" in body}


def faster(before: str, after: str) -> str:
    return f"{100 * (1 - float(after) / float(before)):.0f}%"


def xeon_row(arm: str) -> tuple[str, ...]:
    """One arm's ms and ratio in both runs of ``benchmarks/torch_vectorised.py`` on the Xeon."""
    one, two = xeon("torch_vectorised.txt")[arm], xeon("torch_vectorised_r5.txt")[arm]
    return one[0], one[1], two[0], two[1]


def pinned(name: str, arm: str) -> list[str]:
    """One row of a table the project's Xeon printed with the pinned torch (``xeon-pinned/``)."""
    return markdown_rows((PINNED / name).read_text())[arm]


def xeon_best(name: str) -> str:
    """The best ratio to the tutorial's code over the vectorised arms of one run on the Xeon."""
    return best_ratio(xeon(name))


def xeon_bmm(forced: bool) -> list[str]:
    """The Xeon's ``bmm`` row of ``gemm_isa.txt`` (ms, GFLOP/s): MKL's own kernels, or AVX-512 forced."""
    label = "MKL_ENABLE_INSTRUCTIONS=AVX512" if forced else "as the engine calls it"
    return xeon("gemm_isa.txt")[f"torch.bmm (MKL), {label}"]


def forced_step(kernels: str) -> str:
    """Run 3's compiled S=8 step on the Xeon, ms, under MKL's ``default`` kernels or ``AVX512`` forced."""
    return mkl_pair()[kernels]["vectorised, S=8, compiled"][0]


def regeneration() -> tuple:
    """``results/MANIFEST.json``'s price of regenerating every committed set, as
    ``maintainers/manifest.py`` writes it in ``MANIFEST.md``: process-hours counted once, those of
    PyTorch, compiled-engine and Gymnasium-loop runs, and the wall time on 2, 16, 64 and 256 cores."""
    from maintainers.manifest import by_kind, regeneration_hours

    entries = json.loads((RESULTS / "MANIFEST.json").read_text())
    total, walls, _ = regeneration_hours(entries)
    kinds = by_kind(entries)
    hours = [f"{kinds[k] / 60:.1f}" for k in ("PyTorch", "Keras on the compiled engine", "Keras on the Gymnasium loop")]
    return (f"{total:.1f}", *hours, *(f"{h:.1f}" for h in walls.values()))


@cache
def timed(name: str) -> tuple[str, str, int, str]:
    """A ``results/checks/timing`` output of ``time_check.sh``: its wall time, its CPU seconds (user
    and system), its exit code, and each post's verdict as the check printed it."""
    text = (RESULTS / "checks" / "timing" / name).read_text()
    found = {
        key: re.search(pattern, text, re.M)
        for key, pattern in (
            ("wall", r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)"),
            ("user", r"User time \(seconds\): ([\d.]+)"),
            ("system", r"System time \(seconds\): ([\d.]+)"),
            ("exit", r"^exit (\d+)$"),
        )
    }
    read = {key: match[1] for key, match in found.items() if match is not None}
    if len(read) < len(found):
        raise ConfigError(f"{name} lacks {sorted(set(found) - set(read))}: rerun results/checks/timing/time_check.sh")
    posts = re.findall(r"^(\w+): (consistent|changed|no verdict) \(\w+, (the same bits|[^,]+, p = [\d.]+)", text, re.M)
    said = "; ".join(f"{post} {verdict} ({how.split(', ')[-1]})" for post, verdict, how in posts)
    cpu = f"{float(read['user']) + float(read['system']):.0f}"
    return read["wall"], cpu, int(read["exit"]), said


def twin_power(post: str) -> tuple[str, str]:
    """A post's held-out mutants in ``keras_rl/check/twins.json`` (``calibrate twins``): their twins'
    seeds, and each mutant with its true shift of the median over all its twins and how often the
    rule's twins flag it at Holm's first level (0.01 / 3), resampled."""
    from maintainers.calibrate.twins import SEEN

    entry = json.loads((ROOT / "keras_rl" / "check" / "twins.json").read_text())["posts"][post]
    held = {name: m for name, m in entry["power"].items() if not name.endswith(SEEN)}  # those that chose nothing
    seeds = {m["seeds"] for m in held.values()}
    assert len(seeds) == 1, f"{post}'s held-out mutants ran on different twins: {seeds}"
    missing = [f"`{Path(folder).name}`" for folder in entry.get("missing", [])]
    return seeds.pop(), "; ".join(
        f"`{name}` x{m['true_shift']:.2f}, {m['resampled_holm_first']:.1%}" for name, m in held.items()
    ) + (f" (planned and not landed yet: {', '.join(missing)})" if missing else "")


def minutes(wall: str) -> str:
    """``/usr/bin/time``'s ``m:ss.ss`` (or ``h:mm:ss``) as prose: ``1 min 33 s``."""
    parts = [float(x) for x in wall.split(":")]
    seconds = round(sum(x * 60**i for i, x in enumerate(reversed(parts))))
    return f"{seconds // 60} min {seconds % 60:02d} s"


Claim = tuple[str, str, Callable[[], tuple]]

CLAIMS: list[Claim] = [
    # issue 70: the sensitive command's time, quiet, as installed and under a real change
    *(
        (
            "results/checks/timing/README.md",
            f"`{name}`: {{}} of wall time and {{}} s of CPU, exit {{}}: {{}}",
            lambda name=name: timed(name),
        )
        for name in ("sensitive-unchanged.txt", "sensitive-fastmath.txt")
    ),
    (
        "docs/check.md",
        "for 4 of 4 twins in {} for the three posts; a release that moves the arithmetic runs every twin "
        "(post 000's 80 at about 3-5 s each; post 003's 40 at about half a minute each, each stopping at its "
        "threshold if it gets there): {} for the three posts on a 2-core machine, measured quiet under XLA fast math",
        lambda: tuple(minutes(timed(name)[0]) for name in ("sensitive-unchanged.txt", "sensitive-fastmath.txt")),
    ),
    *(
        (
            "docs/check.md",
            f"{post}'s held-out mutants, run on its twin seeds {{}}, each with its true shift of the median "
            "and how often the rule's twins flag it at 0.01 / 3: {}",
            lambda post=post: twin_power(post),
        )
        for post in ("pendulum", "cartpole")
    ),
    # the price of regenerating results/ (issue 52 item 6), from the manifest
    (
        "docs/performance.md",
        "the committed sets cost {} process-hours: {} of them are PyTorch runs (the tutorial's own code and "
        "the ports, which no compiled engine runs, and the vectorised engine's sets: its certification arm and "
        "both proposals of the tutorial's community fix), {} compiled-engine runs, {} Keras Gymnasium-loop runs "
        "(the reference arms and the ablations the compiled engine does not run, run there on purpose). In wall "
        "time, at least {} h on 2 cores, {} h on 16, {} h on 64 and {} h on 256",
        regeneration,
    ),
    # issue 52 item 4: post 003 on real runs
    (
        "docs/check.md",
        "Its {} no-change checks of 40 compiled seeds that no baseline holds ({}-{}) flagged {} "
        "(Clopper-Pearson upper bound {:.0%})",
        lambda: (
            real_003()["no_change"][0]["holm_first"]["checks"],
            *real_003()["pool_seeds"],
            {0: "none"}.get(real_003()["no_change"][0]["holm_first"]["flagged"], "some"),
            real_003()["no_change"][0]["holm_first"]["ci95"][1],
        ),
    ),
    (
        "docs/check.md",
        "`batch_64` was flagged in {} of {} and the other three in {} of {} (upper bound {:.0%}), though their "
        "medians moved as much or nearly (x{:.3f} for `batch_64`, `eps_decay_x0.5` and `buffer_x0.3`, x{:.3f} "
        "for `grad_clip_1`)",
        lambda: (
            real_003()["mutants"]["batch_64"]["checks"][0]["holm_first"]["flagged"],
            real_003()["mutants"]["batch_64"]["checks"][0]["holm_first"]["checks"],
            sum(
                real_003()["mutants"][m]["checks"][0]["holm_first"]["flagged"]
                for m in ("eps_decay_x0.5", "buffer_x0.3", "grad_clip_1")
            ),
            *{
                real_003()["mutants"][m]["checks"][0]["holm_first"]["checks"]
                for m in ("eps_decay_x0.5", "buffer_x0.3", "grad_clip_1")
            },
            real_003()["mutants"]["grad_clip_1"]["checks"][0]["holm_first"]["ci95"][1],
            *{
                round(real_003()["mutants"][m]["shift"]["ratio"], 3)
                for m in ("batch_64", "eps_decay_x0.5", "buffer_x0.3")
            },
            real_003()["mutants"]["grad_clip_1"]["shift"]["ratio"],
        ),
    ),
    (
        "docs/check.md",
        "40 fresh seeds see a 10% move of the median either way with power {} / {}, and no size up to 100 gets past {}",
        real_003_sizes,
    ),
    # item 3's five numbers, as rewritten
    (
        "docs/findings.md",
        "Seed by seed the engines mostly agree: {} of {} seeds first meet the threshold at the same episode on "
        "both ({} of them also agree on success), and {} agree on success",
        lambda: (
            engines_001()["first"],
            len(table_pairs("engines/mountaincar/report.md")),
            engines_001()["and_success"],
            engines_001()["success"],
        ),
    ),
    (
        "docs/findings.md",
        "{} of the 200 seeds first meet the threshold at the same episode in both frameworks "
        "({} of them also agree on success",
        lambda: (
            same_in_table("compare/mountaincar/cause.md")[0],
            paired(
                arm(("mountaincar/faithful", "checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199")),
                arm(
                    (
                        "mountaincar/faithful-torch-matched-init",
                        "mountaincar/faithful-torch-matched-init-seeds-30-199",
                        "mountaincar/faithful-torch-matched-init-seeds-115-199",
                    )
                ),
                range(200),
            )["and_success"],
        ),
    ),
    (
        "docs/findings.md",
        "({} of the {} seeds first meet the threshold at the same episode in both frameworks)",
        lambda: (planned_001(True)["paired"]["first"], planned_001(True)["n"]),
    ),
    (
        "docs/findings.md",
        "(the seeds still converged at the end: {} of the 600 agree)",
        lambda: (planned_001(True)["paired"]["old"],),
    ),
    (
        "docs/findings.md",
        "seeds 0-9 had given {}/{} vs {}/{}, Fisher p = {:.2f}, and Mann-Whitney p = {:.2f} on the successes' "
        "episodes alone",
        cartpole_first_ten,
    ),
    (
        "results/README.md",
        "median episodes to threshold over the successful seeds {:.1f} (compiled) against {:.1f}, over every seed "
        "({} for a seed that never got there) {:g} against {:g}, ratio {:.2f}",
        cartpole_engines,
    ),
    # post 001's compiled engine (item 1)
    (
        "docs/findings.md",
        "success {}/200 compiled against {}/200 (difference {}, 90% interval {} to {})",
        lambda: (
            *engines_001_successes(),
            *interval(compiled_001()["success"]),
        ),
    ),
    (
        "docs/findings.md",
        "as the plan defines it, {} (90% interval {} to {}) at 200 seeds per engine",
        lambda: interval(compiled_001()["speed"]),
    ),
    (
        "docs/findings.md",
        "the ratio is inconclusive, {} (90% interval {} to {})",
        lambda: interval(compiled_001()["speed_converged_at_end"]),
    ),
    (
        "reproductions/FIDELITY.md",
        "equivalent ({}/200 against {}/200), and so is the median-episodes ratio read as the plan defines it, by "
        "each seed's first passing episode: {} (90% interval {} to {})",
        lambda: (
            *engines_001_successes(),
            *interval(compiled_001()["speed"]),
        ),
    ),
    (
        "reproductions/FIDELITY.md",
        "converged at the end) the ratio is inconclusive, {} ({} to {})",
        lambda: interval(compiled_001()["speed_converged_at_end"]),
    ),
    (
        "reproductions/FIDELITY.md",
        "Seed by seed, {} of the {} seeds first meet the threshold at the same episode on both engines ({} of them "
        "also agree on success)",
        lambda: (
            engines_001()["first"],
            len(table_pairs("engines/mountaincar/report.md")),
            engines_001()["and_success"],
        ),
    ),
    (
        "README.md",
        "ratio {} ({}-{}), 200 seeds each",
        lambda: interval(compiled_001()["speed"]),
    ),
    (
        "README.md",
        "(counted only if converged at the end) gives {} ({}-{})",
        lambda: interval(compiled_001()["speed_converged_at_end"]),
    ),
    (
        "docs/findings.md",
        "that median ({:g} compiled, {:g} on the loop) sits where",
        lambda: tuple(
            np.median([101 if e is None else e for e in Arm.of(a.values()).episodes(CONVERGED_AT_END)])
            for a in (
                arm(("engines/mountaincar/compiled",)),
                arm(("checks/mountaincar/baseline", "mountaincar/faithful-seeds-100-199")),
            )
        ),
    ),
    (
        "docs/findings.md",
        "the interval fits ±10% with probability {} at 200 seeds per arm and {} at 400",
        lambda: tuple(fits("engines/mountaincar/seeds_needed.md")[n] for n in ("200", "400")),
    ),
    # post 001 Keras against PyTorch at the planned seeds
    (
        "docs/findings.md",
        "first meets the threshold later, median episode {} against {}, ratio {} ({} to {}): different on both "
        "readings (by the code's reading, median episode {} against {}, ratio {}, {} to {})",
        lambda: (
            *planned_001(False)["medians"][FIRST_PASSING],
            *(
                f"{float(x):.3g}"
                for x in interval(
                    forest("Keras vs PyTorch, the planned seeds", "mountaincar, default init (200 planned)")["speed"]
                )
            ),
            *planned_001(False)["medians"][CONVERGED_AT_END],
            *interval(
                forest("Keras vs PyTorch, the planned seeds", "mountaincar, default init (200 planned)")[
                    "speed_converged_at_end"
                ]
            ),
        ),
    ),
    (
        "docs/findings.md",
        "the median first passing episode is {} in both",
        lambda: (shared_median(FIRST_PASSING),),
    ),
    (
        "docs/findings.md",
        "ratio 1.00 with a 90% interval of {:.2f} to {:.2f}: **equivalent on the median too**",
        lambda: tuple(
            forest("Keras vs PyTorch, the planned seeds", "mountaincar, matched init (600 planned)")["speed"][k]
            for k in ("low", "high")
        ),
    ),
    (
        "docs/findings.md",
        "By the code's old reading the median is {} in both",
        lambda: (shared_median(CONVERGED_AT_END),),
    ),
    (
        "docs/findings.md",
        "interval, {:.2f} to {:.2f}, is wider than ±10%, inconclusive",
        lambda: tuple(
            forest("Keras vs PyTorch, the planned seeds", "mountaincar, matched init (600 planned)")[
                "speed_converged_at_end"
            ][k]
            for k in ("low", "high")
        ),
    ),
    # post 001 at 30 seeds
    (
        "docs/findings.md",
        "(Mann-Whitney p = {:.2f} over every seed)",
        lambda: (compare_001(False)["mann_whitney"][1],),
    ),
    (
        "docs/findings.md",
        "the median ratio's {} to {} (the code's reading: {} to {})",
        lambda: (
            *interval(forest("Keras vs PyTorch", "mountaincar")["speed"])[1:],
            *interval(forest("Keras vs PyTorch", "mountaincar")["speed_converged_at_end"])[1:],
        ),
    ),
    (
        "docs/findings.md",
        "inconclusive too (Mann-Whitney p = {:.2f})",
        lambda: (compare_001(True)["mann_whitney"][1],),
    ),
    (
        "docs/findings.md",
        "median episode {:g} vs {:g} by the plan's reading (the code's reading, over the converged seeds: "
        "{:g} vs {:g})",
        lambda: (
            *(compare_001(False)["frameworks"][fw]["median"] for fw in ("keras", "torch")),
            *(
                compare_001(False)["frameworks"][fw].get("before_issue_52", compare_001(False)["frameworks"][fw])[
                    "median"
                ]
                for fw in ("keras", "torch")
            ),
        ),
    ),
    # issue 53 item 4: a thousand seeds on one H200
    (
        "results/cartpole/vectorised-torch/h200/README.md",
        "the whole set's wall time, engine built to the last seed's 600th episode | **{:.0f} s**",
        lambda: (thousand_seeds()["set_wall_seconds"],),
    ),
    (
        "results/cartpole/vectorised-torch/h200/README.md",
        "at the full batch) | **{:.2f}** ({:.2f} us per seed-env-step) |",
        lambda: (thousand_seeds()["full_batch_ms"], thousand_seeds()["full_batch_ms"]),
    ),
    (
        "results/cartpole/vectorised-torch/h200/README.md",
        "eager, same run (200 training steps) | {:.2f} |",
        lambda: (thousand_seeds()["eager_baseline"]["ms_per_step"],),
    ),
    (
        "results/cartpole/vectorised-torch/h200/README.md",
        "mean loss of its updates; {:,} rows)",
        lambda: (thousand_seeds()["rows"],),
    ),
    (
        "results/cartpole/vectorised-torch/h200/README.md",
        "**{} of 1,000 ({:.3f},",
        lambda: (thousand_seeds()["reached"], thousand_seeds()["reached"] / 1000),
    ),
    # issue 53 item 3 on the project's machine when it was an Intel Xeon, with the pinned torch
    *[
        (
            "results/cartpole/vectorised-torch/xeon-pinned/README.md",
            f"| {arm} | {{}} | {{}} |",
            lambda arm=arm: tuple(pinned("torch_vectorised.txt", arm)[:2]),
        )
        for arm in (
            "the tutorial's code (gathered)",
            "vectorised, S=1, compiled",
            "vectorised, S=8, compiled",
            "vectorised, S=32, compiled",
        )
    ],
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "best S gives **{}**",
        lambda: (best_ratio(markdown_rows((PINNED / "torch_vectorised.txt").read_text())),),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "The tutorial's code took {} ms, the compiled step {} ms at S=8 ({}) and {} ms at S=32 ({}): the best S "
        "gives **{}**.",
        lambda: (
            pinned("torch_vectorised_quiet.txt", "the tutorial's code (gathered)")[0],
            *pinned("torch_vectorised_quiet.txt", "vectorised, S=8, compiled")[:2],
            *pinned("torch_vectorised_quiet.txt", "vectorised, S=32, compiled")[:2],
            best_ratio(markdown_rows((PINNED / "torch_vectorised_quiet.txt").read_text())),
        ),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "the AMD EPYC the same benchmark gives {} to {}",
        lambda: epyc()["best"],
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "At S=8 it takes {} ms, against {} to {} ms on the",
        lambda: (pinned("torch_vectorised.txt", "vectorised, S=8, compiled")[0], *epyc()["s8"]),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        'MKL names "{}"',
        lambda: (mkl_header(PINNED),),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "`bmm` takes {} ms for the 8 products of 128x128 by 128x128 ({} GFLOP/s), against {} ms there.",
        lambda: (*pinned("gemm_isa.txt", "torch.bmm (MKL), as the engine calls it"), epyc()["bmm"]),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-pinned/README.md",
        "**The tutorial's code is much slower here**: {} ms, against {} to {} ms on the AMD EPYC.",
        lambda: (
            pinned("torch_vectorised.txt", "the tutorial's code (gathered)")[0],
            *epyc()["tutorial"],
        ),
    ),
    (
        "docs/performance.md",
        "The tutorial's code took {} ms a seed-env-step, the compiled step {} ms at S=8 and {} ms at S=32: **{}** at "
        "the best S, **over 4x in one run**. MKL named its AVX-512 path there, and `bmm` took {} ms",
        lambda: (
            pinned("torch_vectorised.txt", "the tutorial's code (gathered)")[0],
            pinned("torch_vectorised.txt", "vectorised, S=8, compiled")[0],
            pinned("torch_vectorised.txt", "vectorised, S=32, compiled")[0],
            best_ratio(markdown_rows((PINNED / "torch_vectorised.txt").read_text())),
            pinned("gemm_isa.txt", "torch.bmm (MKL), as the engine calls it")[0],
        ),
    ),
    (
        "README.md",
        "the tutorial's code: {} on the AMD EPYC; {} on the project's machine when it was an Intel Xeon with AVX-512 "
        "| {}; {} at S=32 ([Xeon](results/cartpole/vectorised-torch/xeon-pinned/README.md)) | {}; **{}**",
        lambda: (
            epyc()["run"]["the tutorial's code (gathered)"][0],
            pinned("torch_vectorised.txt", "the tutorial's code (gathered)")[0],
            epyc()["run"]["vectorised, S=8, compiled"][0],
            pinned("torch_vectorised.txt", "vectorised, S=32, compiled")[0],
            best_ratio(epyc()["run"]),
            best_ratio(markdown_rows((PINNED / "torch_vectorised.txt").read_text())),
        ),
    ),
    (
        "docs/performance.md",
        "with nothing beside it (`--rounds 5 --sizes 8,32`), gave {} at the best S.",
        lambda: (best_ratio(markdown_rows((PINNED / "torch_vectorised_quiet.txt").read_text())),),
    ),
    # issue 53 item 3 on an Intel AVX-512 CPU (the device machine's, 2026-11-28)
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "| the tutorial's code (gathered) | {} | {} |",
        lambda: (xeon_row("the tutorial's code (gathered)")[0], xeon_row("the tutorial's code (gathered)")[2]),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "| vectorised, S=1, compiled | {} ({}) | {} ({}) |",
        lambda: xeon_row("vectorised, S=1, compiled"),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "| vectorised, S=8, compiled | {} ({}) | {} (**{}**) |",
        lambda: xeon_row("vectorised, S=8, compiled"),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "| vectorised, S=32, compiled | {} (**{}**) | {} ({}) |",
        lambda: xeon_row("vectorised, S=32, compiled"),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "best S gives **{}** in run 1 and **{}** in run 2",
        lambda: (xeon_best("torch_vectorised.txt"), xeon_best("torch_vectorised_r5.txt")),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "takes {} ms for 8 products of 128x128 by 128x128 ({} GFLOP/s), against {} ms on the AMD EPYC",
        lambda: (*xeon_bmm(forced=False), epyc()["bmm"]),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "set, `bmm` takes {} ms.",
        lambda: (xeon_bmm(forced=True)[0],),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        'Its verbose header names "{}"',
        lambda: (mkl_header(),),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "On this project's AMD EPYC it does not: {} to {} at the best batch size",
        lambda: epyc()["best"],
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "At S=8 it takes {} to {} ms, against {} to {} ms on the AMD EPYC.",
        lambda: (*xeon_row("vectorised, S=8, compiled")[::2], *epyc()["s8"]),
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "It takes {} to {} ms, against {} to {} ms on the AMD EPYC. Even S=1, one seed alone, reaches {} here, "
        "against {} there.",
        lambda: (
            *xeon_row("the tutorial's code (gathered)")[::2],
            *epyc()["tutorial"],
            xeon_row("vectorised, S=1, compiled")[1],
            epyc()["s1_ratio"],
        ),
    ),
    (
        "docs/performance.md",
        "the same benchmark gives {} and {} at the best S in two runs. The engine's products are no faster "
        "there: `bmm` took {} ms for the 8 products ({} here), and the compiled step at S=8 took {} to {} ms "
        "({} to {} here). The tutorial's code was slower still, at {} to {} ms ({} to {} here).",
        lambda: (
            xeon_best("torch_vectorised.txt"),
            xeon_best("torch_vectorised_r5.txt"),
            xeon_bmm(forced=False)[0],
            epyc()["bmm"],
            *xeon_row("vectorised, S=8, compiled")[::2],
            *epyc()["s8"],
            *xeon_row("the tutorial's code (gathered)")[::2],
            *epyc()["tutorial"],
        ),
    ),
    (
        "docs/performance.md",
        "`MKL_ENABLE_INSTRUCTIONS=AVX512` there made `bmm` alone faster ({} ms)",
        lambda: (xeon_bmm(forced=True)[0],),
    ),
    *(  # run 3's table: one row per choice of MKL's kernels
        (
            "results/cartpole/vectorised-torch/xeon-cpu/README.md",
            f"| {label} | {{}} | {{}} ({{}}) |",
            lambda kernels=kernels: (
                mkl_pair()[kernels]["the tutorial's code (gathered)"][0],
                *mkl_pair()[kernels]["vectorised, S=8, compiled"][:2],
            ),
        )
        for kernels, label in (("default", "its own choice"), ("AVX512", "`MKL_ENABLE_INSTRUCTIONS=AVX512`"))
    ),
    (
        "results/cartpole/vectorised-torch/xeon-cpu/README.md",
        "forced kernel made `bmm` alone {} faster in run 1, but the compiled step only {} faster here",
        lambda: (
            faster(
                xeon_bmm(forced=False)[0],
                xeon_bmm(forced=True)[0],
            ),
            faster(forced_step("default"), forced_step("AVX512")),
        ),
    ),
    (
        "docs/performance.md",
        "but the compiled step at S=8 only {} faster ({} against {} ms, one pair of runs)",
        lambda: (
            faster(forced_step("default"), forced_step("AVX512")),
            forced_step("AVX512"),
            forced_step("default"),
        ),
    ),
    # the sampled audit (issue 52 item 6)
    (
        "results/README.md",
        "{} of the {} committed sets, {} seeds the same bits, {} mismatches",
        audit_counts,
    ),
    # post 001's popping buffer at its 600 planned seeds (issue 52 item 5)
    (
        "reproductions/FIDELITY.md",
        "`popping_buffer=false`), {}/600 seeds end converged against {}/600 with the post's popping buffer: a "
        "difference of {} (90% interval {} to {}). But they first meet the threshold later, median episode {:g} "
        "against {:g}: a ratio of {} ({} to {})",
        lambda: (
            *popping_600(),
            *interval(forest(POP_600, "popping_buffer=false (600 planned)")["success"]),
            *popping_600_medians(),
            *interval(forest(POP_600, "popping_buffer=false (600 planned)")["speed"]),
        ),
    ),
    # post 001's ablations (results/mountaincar/ablations/sweep.json, the FIDELITY table's rows)
    (
        "reproductions/FIDELITY.md",
        "median difference {} episodes by the plan's reading (each seed's first passing episode), {} by the "
        "code's reading before issue 52",
        lambda: (
            signed(ablation("actor_gradient=dpg_intended")["median_difference"]),
            signed(ablation("actor_gradient=dpg_intended")["before_issue_52"]["median_difference"]),
        ),
    ),
    (
        "README.md",
        "#3080's values, {}/100 against {}/100 as published on 100 Keras seeds",
        lambda: fix_and_published("issue-3080", "keras", 100),
    ),
    (
        "README.md",
        "{}/30 against {}/30 in the tutorial's own PyTorch code",
        lambda: fix_and_published("issue-3080", "torch", 30),
    ),
    (
        "README.md",
        "and {}/100 against {}/100 in PyTorch on the vectorised engine",
        lambda: fix_and_published("issue-3080", "vectorised", 100),
    ),
    (
        "README.md",
        "the values PR #3384 merged into the tutorial, {}/100 (**different**)",
        lambda: fix_and_published("pr-3384", "keras", 100)[:1],
    ),
    (
        "README.md",
        "at the 100 seeds planned for a second look, {}/100 against {}/100",
        lambda: fix_and_published("pr-3384", "torch", 100),
    ),
    (
        "README.md",
        "and {}/100 against {}/100 on the vectorised engine, more often and sooner (all **different**)",
        lambda: fix_and_published("pr-3384", "vectorised", 100),
    ),
    (
        "docs/findings.md",
        "within 600 episodes in **{} (90% Wilson {})**, the values of pytorch/tutorials #3080 in **{} ({})**: "
        "a difference of {} (90% interval {} to {}),",
        lambda: (
            (*fix_report("report.md")["published"][:2], *fix_report("report.md")["issue-3080"][:2])
            + fix_report("report.md")["success"]
        ),
    ),
    (
        "docs/findings.md",
        "median episode {} against {} (a seed that never gets there counting as 601), ratio {} (90% interval {} to {})",
        lambda: (
            (fix_report("report.md")["issue-3080"][2], fix_report("report.md")["published"][2])
            + fix_report("report.md")["ratio"]
        ),
    ),
    (
        "docs/findings.md",
        "mean duration {} (IQR {}) as published and {} ({}) with the values of pytorch/tutorials #3080, "
        "the longest episode {} against {}",
        lambda: (
            *fix_report("report.md")["published"][3:5],
            *fix_report("report.md")["issue-3080"][3:5],
            fix_report("report.md")["published"][5],
            fix_report("report.md")["issue-3080"][5],
        ),
    ),
    (
        "docs/findings.md",
        "**{} ({}) against {} ({})** as published, a difference of {} (90% interval {} to {}), **different**; "
        "median episode {} against {}, ratio {} ({} to {}), **different**; a CPU reader's 50 episodes: "
        "mean duration {} (IQR {}) against {} ({})",
        lambda: quoted("report-torch.md", "issue-3080", published=2, cpu=2),
    ),
    *(
        (
            "docs/findings.md",
            "**{} ({}) against {}**, a difference of {} (90% interval {} to {}), **" + verdict + "**; median "
            "episode {} against {}, ratio {} ({} to {}), **different**; a CPU reader's 50 episodes: mean duration "
            "{} (IQR {}) against {}",
            lambda name=name: quoted(name, "pr-3384", published=1, cpu=1),
        )
        for name, verdict in (
            ("report-pr-3384.md", "different"),
            ("report-pr-3384-torch.md", "inconclusive at 30 seeds"),
        )
    ),
    (
        "docs/findings.md",
        "longest episode {} against {}. In the tutorial's own PyTorch code",
        lambda: (fix_report("report-pr-3384.md")["pr-3384"][5], fix_report("report-pr-3384.md")["published"][5]),
    ),
    (
        "docs/findings.md",
        "**{} ({}) against {} ({})**, a difference of {} (90% interval {} to {}), **different**; median episode {} "
        "against {}, ratio {} ({} to {}), **different**; a CPU reader's 50 episodes: mean duration {} (IQR {}) "
        "against {}",
        lambda: quoted("report-pr-3384-torch-100.md", "pr-3384", published=2, cpu=1),
    ),
    *(
        (
            "docs/findings.md",
            "values **{} ({}) against {}" + more + "**, a difference of {} (90% interval {} to {}), **different**; "
            "median episode {} against {}, ratio {} ({} to {}), **different**",
            lambda name=name, label=label, n=n: quoted(name, label, published=n),
        )
        for name, label, more, n in (
            ("report-issue-3080-vectorised.md", "issue-3080", " ({})", 2),
            ("report-pr-3384-vectorised.md", "pr-3384", "", 1),
        )
    ),
    (
        "docs/findings.md",
        "readings: success {}/100 against {}/100, a difference of {} (90% interval {} to {}); "
        "median episodes ratio {} ({} to {})",
        lambda: (
            *(
                sum(arm((f"cartpole/tutorial-fix/pr-3384{suffix}",))[s]["success"] for s in range(100))
                for suffix in ("-vectorised", "-torch")
            ),
            *interval(engine_check()["success"]),
            *interval(engine_check()["speed"]),
        ),
    ),
    # issue 71 item 7: the AMD EPYC's figures of the vectorised engine, from epyc-cpu/ (2026-11-30)
    *(
        ("docs/performance.md", f"| {arm} | {{}} | {{}} | {{}} |", lambda arm=arm: tuple(epyc()["run"][arm]))
        for arm in EPYC_ARMS
    ),
    (
        "docs/performance.md",
        "**{}** on this AMD EPYC: {} at {}",
        lambda: (met(best_ratio(epyc()["run"])), *reversed(best_arm(epyc()["run"]))),
    ),
    (
        "docs/performance.md",
        "`python benchmarks/torch_vectorised.py --rounds 5 --sizes 8,16 --markdown`, straight after, gave the "
        "tutorial's code {} ms, S=8 compiled {} ms ({}), S=16 compiled {} ms ({}); eager {} and {} ms.",
        lambda: (
            epyc()["sizes"]["the tutorial's code (gathered)"][0],
            *epyc()["sizes"]["vectorised, S=8, compiled"][:2],
            *epyc()["sizes"]["vectorised, S=16, compiled"][:2],
            epyc()["sizes"]["vectorised, S=8, eager"][0],
            epyc()["sizes"]["vectorised, S=16, eager"][0],
        ),
    ),
    *(
        ("docs/performance.md", f"| {row} | {{}} | {{}} |", lambda row=row: tuple(epyc()["products"][row]))
        for row in GEMM_ROWS
    ),
    (
        "docs/performance.md",
        'On this host: "{}" and "Intel(R) 64 architecture {}"',
        lambda: (cpu_named(EPYC), mkl_header(EPYC)),
    ),
    (
        "docs/performance.md",
        "With products at {} instead of {} GFLOP/s, the step at S=8 would be about {} ms instead of {} (the products, "
        "four of `bmm`'s eight a seed-env-step, are {} of it): about {} the tutorial's code",
        faster_products,
    ),
    ("docs/performance.md", "{} on the AMD EPYC", lambda: (epyc()["bmm"],)),
    *(
        (
            "results/cartpole/vectorised-torch/epyc-cpu/README.md",
            f"| {arm} | {{}} | {{}} |",
            lambda arm=arm: tuple(epyc()["run"][arm][:2]),
        )
        for arm in (EPYC_ARMS[0], *EPYC_ARMS[4:])
    ),
    (
        "results/cartpole/vectorised-torch/epyc-cpu/README.md",
        "best S gives **{}** in the run over every S, and **{}** in the run over S=8 and 16: issue 53's 4x per seed "
        "at the best S is {} on this CPU",
        lambda: (best_ratio(epyc()["run"]), best_ratio(epyc()["sizes"]), met(epyc()["best"][1])),
    ),
    (
        "results/cartpole/vectorised-torch/epyc-cpu/README.md",
        'MKL dispatched for "{}"',
        lambda: (mkl_header(EPYC),),
    ),
    (
        "results/cartpole/vectorised-torch/epyc-cpu/README.md",
        "`bmm` takes {} ms for the 8 products of 128x128 by 128x128 ({} GFLOP/s), where OpenBLAS's AVX-512 kernel "
        "takes {} ms ({} GFLOP/s).",
        lambda: (*epyc()["products"][GEMM_ROWS[0]], *epyc()["products"][GEMM_ROWS[-1]]),
    ),
    # issue 71 item 1: which stacked learners stay (engines/stacked-paths/, 2026-11-30)
    *(
        (
            "results/engines/stacked-paths/README.md",
            f"| {label} | {{}} | {{}} | {{}} |",
            lambda post=post: stacked_cost(post),
        )
        for post, label in STACKED_POSTS.items()
    ),
    (
        "results/engines/stacked-paths/README.md",
        "batched, they ran {} as fast as seeds alone for post 001 in Keras, whose seeds alone ran on the compiled "
        "engine, {} for post 000's port and {} for post 001's",
        lambda: tuple(study_speedup(post) for post in STACKED_POSTS),
    ),
    (
        "results/engines/stacked-paths/README.md",
        "By that rule, {} of the three paths stay{}.",
        lambda: ("all", "") if stacked_kept() else ("not all", "; the table names the ones that go"),
    ),
    ("docs/performance.md", "The compile took about 380 s there, against {} to {} s here", compile_seconds),
]

BEGIN, END = "<!-- prose:{} -->", "<!-- /prose -->"
BLOCKS = re.compile(r"<!-- prose:([a-z0-9-]+) -->(.*?)<!-- /prose -->", re.S)


def claim_id(fragment: str) -> str:
    """A claim's marker name: the first words of its fragment, slots and punctuation dropped."""
    words = re.findall(r"[a-z0-9]+", re.sub(r"\{[^}]*\}", " ", fragment.lower()))
    return "-".join(words[:6])


def claims() -> dict[str, tuple[str, str, Callable[[], tuple]]]:
    """Every claim by its marker name (a name that repeats gets ``-2``, ``-3``, ... in order)."""
    named: dict[str, tuple[str, str, Callable[[], tuple]]] = {}
    for where, fragment, values in CLAIMS:
        base = name = claim_id(fragment)
        count = 1
        while name in named:
            count += 1
            name = f"{base}-{count}"
        named[name] = (where, fragment, values)
    return named


def _block(name: str) -> re.Pattern[str]:
    return re.compile(re.escape(BEGIN.format(name)) + r"(.*?)" + re.escape(END), re.S)


def said(name: str) -> str:
    """What the data give for one claim's block (a table row's cells without their outer bars)."""
    _, fragment, values = claims()[name]
    text = fragment.format(*values())
    return text[2:-2] if text.startswith("| ") and text.endswith(" |") else text  # a row: markers inside it


def stale(names: list[str] | None = None) -> list[str]:
    """The claims (default: all) whose block on its page is not what the data give."""
    named = claims()
    pages_read: dict[str, dict[str, str]] = {}
    out = []
    for name in names or list(named):
        where = named[name][0]
        blocks = pages_read.setdefault(where, dict(BLOCKS.findall((ROOT / where).read_text())))
        if blocks.get(name) != said(name):
            out.append(name)
    return out


def pages() -> dict[Path, str]:
    """Each page that holds claims, as this module writes it: every block's text formatted from the
    data. A ConfigError (exit 2) names a claim whose block its page lacks, or holds twice."""
    texts: dict[Path, str] = {}
    for name, (where, _, _) in claims().items():
        path = ROOT / where
        text = texts.setdefault(path, path.read_text())
        found = list(_block(name).finditer(text))
        if len(found) != 1:
            raise ConfigError(f"{where} holds {len(found)} blocks {BEGIN.format(name)}, not one")
        start, end = found[0].span(1)
        texts[path] = text[:start] + said(name) + text[end:]
    return texts


def run(args: argparse.Namespace) -> int:
    """Print each block that differs from what the data give (``--write``: and write its page)."""
    written = pages()
    stale = {path: text for path, text in written.items() if path.read_text() != text}
    for path, text in stale.items():
        before = dict(BLOCKS.findall(path.read_text()))
        for name, said in BLOCKS.findall(text):
            if before.get(name) != said:
                print(f"{path.relative_to(ROOT)} {name}:\n  was {before.get(name)!r}\n  now {said!r}")
        if args.write:
            atomic_write_text(path, text)
    verb = "wrote" if args.write else "stale"
    print(f"{len(CLAIMS)} claims on {len(written)} pages; {verb}: {len(stale)} page(s)")
    return 1 if stale and not args.write else 0
