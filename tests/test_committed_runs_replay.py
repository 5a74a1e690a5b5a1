"""The safety net of every refactor: committed run folders reproduce bit for bit.

Each case reruns a committed seed in a fresh process and asserts that the new
``episodes.csv`` equals the committed one in every column except ``wall_seconds`` (the one
column that is not a function of the seed). A run stopped early (``--episodes N``) must
equal the committed file's first N rows: the budget changes when a run ends, never what
an episode computes.

TensorFlow does not promise bit-exactness across CPUs. Runs record the CPU model and, from
2026-11-24 on, its instruction set in ``summary.json`` (``provenance.cpu_model``, ``cpu_isa``);
``results/PLATFORMS.json`` lists the machines measured not to reproduce the committed bits (a CPU
of the same model name without AVX-512). Capping the instruction set does not make the bits
travel (issue 52 item 7, measured: ``docs/performance.md``), so a host of another instruction set
replays against references made on such a host (``tests/replay_references/<set>/``, with the
host in its ``host.json``): the whole run, bit for bit. Where this machine differs and no
reference of its own is kept (``replay.why_not_bit_exact``), the test says why and compares the
first 5 episodes only, to float rounding (``agree``): counts exactly, every other number within
a relative 1e-4.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from keras_rl.runs.provenance import cpu_isa, cpu_model
from keras_rl.runs.replay import plan_replay, seed_rows, why_not_bit_exact
from keras_rl.runs.run_set import RunSet

pytestmark = pytest.mark.slow  # every test here trains whole runs

RESULTS = Path(__file__).resolve().parent.parent / "results"

CASES = [
    # (committed seed folder, experiment, extra CLI args, episodes to rerun or None for the whole run)
    pytest.param("pendulum/faithful/seed_0", "pendulum", (), None, id="post000-faithful-seed0"),
    pytest.param("mountaincar/faithful/seed_0", "mountaincar", (), None, id="post001-faithful-seed0"),
    pytest.param(
        "pendulum/faithful-torch/seed_0", "pendulum", ("--framework", "torch"), 12, id="post000-torch-seed0-first12"
    ),
    pytest.param("cartpole/faithful/seed_0", "cartpole", (), 60, id="post003-seed0-first60"),
    # 200 episodes: 12,176 steps, past the tutorial's memory of 10,000, so its eviction is replayed too
    pytest.param(
        "cartpole/faithful-torch/seed_0", "cartpole", ("--framework", "torch"), 200, id="post003-torch-seed0-first200"
    ),
]


HOST_REFERENCES = Path(__file__).resolve().parent / "replay_references"


def host_reference(folder: str) -> Path | None:
    """The ``episodes.csv`` made for committed seed ``folder`` on a host of this machine's CPU
    model and instruction set, where one is kept; None otherwise."""
    for host in sorted(HOST_REFERENCES.glob("*/host.json")):
        made_on = json.loads(host.read_text())
        rows = host.parent / folder / "episodes.csv"
        if (made_on["cpu_model"], made_on["cpu_isa"]) == (cpu_model(), cpu_isa()) and rows.is_file():
            return rows
    return None


def read_rows(path: Path) -> list[dict[str, str]]:
    return seed_rows(path)


def committed_rows(seed_path: Path) -> list[dict[str, str]]:
    """A committed seed's rows as written (from its set's runs.parquet), without wall time."""
    return RunSet.seed_at(seed_path).text_rows()


def committed_summary(seed_path: Path) -> dict:
    return RunSet.seed_at(seed_path).summary_record()


def agree(want: dict[str, str], have: dict[str, str], exact: bool) -> bool:
    """Bit for bit; or, on a machine that rounds differently (``exact`` False), every count
    equal and every other number within float32 rounding grown over a few updates (relative
    1e-4): what two CPUs that compute the same thing can give."""
    if exact or have == want:
        return have == want
    if have.keys() != want.keys():
        return False
    for key, w in want.items():
        h = have[key]
        if w.lstrip("-").isdigit() or h.lstrip("-").isdigit() or not w or not h:
            if h != w:
                return False
        elif not math.isclose(float(h), float(w), rel_tol=1e-4, abs_tol=1e-6):
            return False
    return True


@pytest.mark.parametrize("folder, experiment, extra, episodes", CASES)
def test_committed_run_reproduces_bit_for_bit(tmp_path, folder, experiment, extra, episodes):
    committed = RESULTS / folder
    if "--framework" in extra:
        pytest.importorskip("torch", reason="needs the torch extra")
    summary = committed_summary(committed)
    why = why_not_bit_exact(summary.get("provenance", {}))
    reference = host_reference(folder) if why is not None else None
    if why is not None and reference is None:
        warnings.warn(
            f"{folder} was {why}: TensorFlow does not promise bit-exactness across CPUs, so only the "
            "first 5 episodes are compared, to float rounding",
            stacklevel=2,
        )
        episodes = 5
    replay = plan_replay(committed, experiment, episodes)
    expected = replay.expected if reference is None else read_rows(reference)
    exact = why is None or reference is not None
    out = tmp_path / "run"
    proc = subprocess.run(replay.command(out, *extra), capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stderr
    got = read_rows(out / f"seed_{replay.seed}" / "episodes.csv")
    assert len(got) == len(expected), (
        f"{folder}: {len(got)} episodes against {len(expected)} ({reference or 'committed'})"
    )
    for want, have in zip(expected, got):
        assert agree(want, have, exact), f"{folder}: first difference at episode {want['episode']}"


BATCH_CASES = [
    # (committed set, experiment, the batch of seeds its command made together, episodes to rerun)
    # (posts 000 and 003's batched sets were regenerated on the compiled engine when issue 34
    # retired their stacked learners: their compiled seeds are replayed below)
    pytest.param("mountaincar/seed-batch/batch10", "mountaincar", "0-9", 3, id="post001-batch-of-10-first3"),
]


@pytest.mark.parametrize("folder, experiment, seeds, episodes", BATCH_CASES)
def test_committed_seed_batch_reproduces_bit_for_bit(tmp_path, folder, experiment, seeds, episodes):
    """A committed seed-batched set (``--seed-batch 10``): each seed's bits depend on its batch
    mates, so the same batch is rerun and every seed compared."""
    committed = RESULTS / folder
    first, last = (int(x) for x in seeds.split("-"))
    summary = committed_summary(committed / f"seed_{first}")
    assert f"--seed-batch {last - first + 1}" in summary["command"]
    assert summary["provenance"]["seed_batch"] == list(range(first, last + 1))
    why = why_not_bit_exact(summary.get("provenance", {}))
    if why is not None:
        warnings.warn(f"{folder} was {why}: only 5 episodes are compared", stacklevel=2)
        episodes = 5
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "keras_rl",
            "reproduce",
            experiment,
            "--seeds",
            seeds,
            "--seed-batch",
            str(last - first + 1),
            "--episodes",
            str(episodes),
            "--no-progress",
            "--min-success-rate",
            "0",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    for seed in range(first, last + 1):
        expected = committed_rows(committed / f"seed_{seed}")[:episodes]
        got = read_rows(out / f"seed_{seed}" / "episodes.csv")
        assert len(got) == len(expected), f"seed {seed}"
        for want, have in zip(expected, got):
            assert agree(want, have, why is None), (
                f"{folder} seed {seed}: first difference at episode {want['episode']}"
            )


@pytest.mark.parametrize(
    "folder, experiment, seeds, episodes",
    [
        pytest.param("engines/pendulum/compiled", "pendulum", "0-2", None, id="post000-compiled-seeds0-2"),
        pytest.param("engines/cartpole/compiled", "cartpole", "0-1", 120, id="post003-compiled-seeds0-1-first120"),
    ],
)
def test_committed_compiled_seeds_replay_bit_for_bit_on_one_kept_program(tmp_path, folder, experiment, seeds, episodes):
    """The compiled engine's committed seeds (made one program per seed, before programs were
    kept) rerun in one process, where every seed after the first runs on the first one's kept
    program (``train/compiled.py:ProgramCache``): each seed's rows are the committed ones."""
    committed = RESULTS / folder
    first, last = (int(x) for x in seeds.split("-"))
    summary = committed_summary(committed / f"seed_{first}")
    assert summary["provenance"]["engine"] == "compiled" and "--workers 1" in summary["command"]
    why = why_not_bit_exact(summary.get("provenance", {}))
    if why is not None:
        warnings.warn(f"{folder} was {why}: only 5 episodes are compared", stacklevel=2)
        episodes = 5
    budget = ["--episodes", str(episodes)] if episodes else []
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "keras_rl", "reproduce", experiment, "--engine", "compiled", "--seeds", seeds]
        + ["--workers", "1", "--no-progress", "--min-success-rate", "0", *budget, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    for seed in range(first, last + 1):
        expected = committed_rows(committed / f"seed_{seed}")
        expected = expected[:episodes] if episodes else expected
        got = read_rows(out / f"seed_{seed}" / "episodes.csv")
        assert len(got) == len(expected), f"seed {seed}"
        for want, have in zip(expected, got):
            assert agree(want, have, why is None), f"{folder} seed {seed}: differs at episode {want['episode']}"


def test_a_host_without_avx512_replays_against_its_own_references_in_full(monkeypatch):
    """On the instruction set of ``tests/replay_references/avx2`` the three TensorFlow cases find a
    whole-run reference made on that host, which the committed AVX-512 run does not match, each
    made with the committed run's config but the budget; this host finds none of another's."""
    import sys

    made_on = json.loads((HOST_REFERENCES / "avx2" / "host.json").read_text())
    here = sys.modules[__name__]
    monkeypatch.setattr(here, "cpu_model", lambda: made_on["cpu_model"])
    monkeypatch.setattr(here, "cpu_isa", lambda: made_on["cpu_isa"])
    lengths = {"pendulum/faithful/seed_0": 115, "mountaincar/faithful/seed_0": 100, "cartpole/faithful/seed_0": 60}
    for folder, length in lengths.items():
        reference = host_reference(folder)
        assert reference is not None, folder
        rows = read_rows(reference)
        assert len(rows) == length
        committed = committed_rows(RESULTS / folder)[:length]
        assert rows != committed  # the instruction set changes the bits: why a reference is kept
        ours = json.loads((reference.parent / "config.json").read_text())
        theirs = RunSet.seed_at(RESULTS / folder).config()
        assert {k: v for k, v in ours.items() if k != "episodes"} == {
            k: v for k, v in theirs.items() if k != "episodes"
        }
    assert host_reference("pendulum/faithful-torch/seed_0") is None  # no reference: 5 episodes, to rounding
    monkeypatch.setattr(here, "cpu_isa", lambda: [*made_on["cpu_isa"], "avx512f"])
    assert host_reference("pendulum/faithful/seed_0") is None
