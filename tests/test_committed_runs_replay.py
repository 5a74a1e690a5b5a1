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
host in its ``host.json``; some made on a real AVX2 host, the rest under an emulated one,
``maintainers/replay_references.py``, which also lists the cases): the whole case, bit for bit.
A CPU of another model name measured to give one framework's committed bits is listed under
``bit_exact`` in ``PLATFORMS.json`` (an Intel Xeon with AVX-512 for Keras) and replays those runs
against the committed ones. Where this machine differs and no reference of its own is kept
(``replay.why_not_bit_exact``, per framework; on an AVX2 host, the PyTorch cases), the test says why
and compares the first 5 episodes only, to float rounding (``agree``): counts exactly, every other
number within a relative 1e-4.

PyTorch's own bits follow the CPU's vendor too, and the emulator cannot make them (it computes the
approximate square-root reciprocal that MKL's square root refines exactly). So every host also
reruns the PyTorch cases under PyTorch's portable arithmetic (``KERAS_RL_PORTABLE_TORCH=1``) against
one set of references made under it (``tests/replay_references/portable-torch``): whole and bit for
bit, on any CPU with AVX2, an AVX2 host's full PyTorch replay.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from keras_rl.runs.provenance import cpu_isa, cpu_model
from keras_rl.runs.run_set import RunSet
from maintainers.replay import seed_rows, why_not_bit_exact
from maintainers.replay_references import CASES, PORTABLE_SET, REFERENCES, VALIDATED, Case, reference_rows, set_env

pytestmark = pytest.mark.slow  # every test here trains whole runs

RESULTS = Path(__file__).resolve().parent.parent / "results"
CASE_PARAMS = [pytest.param(case, id=case.id) for case in CASES]
TORCH_CASES = [pytest.param(case, id=case.id) for case in CASES if case.framework == "torch"]


def host_reference(folder: str) -> Path | None:
    """The ``episodes.csv`` made for committed seed ``folder`` on a host of this machine's CPU
    model and instruction set, where one is kept; None otherwise."""
    for host in sorted(REFERENCES.glob("*/host.json")):
        made_on = json.loads(host.read_text())
        rows = host.parent / folder / "episodes.csv"
        if (made_on.get("cpu_model"), made_on.get("cpu_isa")) == (cpu_model(), cpu_isa()) and rows.is_file():
            return rows
    return None


def read_rows(path: Path) -> list[dict[str, str]]:
    return seed_rows(path)


def committed_rows(seed_path: Path) -> list[dict[str, str]]:
    """A committed seed's rows as written (from its set's runs.parquet), without wall time."""
    return RunSet.seed_at(seed_path).text_rows()


def committed_summary(seed_path: Path) -> dict:
    return RunSet.seed_at(seed_path).summary_record()


def assert_a_kept_reference(folder: str, reference: Path, episodes: int) -> None:
    """A host's reference for committed seed ``folder``: ``episodes`` rows, made with the committed
    run's config but the budget, and different from the committed run (why it is kept)."""
    rows = read_rows(reference)
    assert len(rows) == episodes, folder
    assert rows != committed_rows(RESULTS / folder)[: len(rows)], folder
    ours = json.loads((reference.parent / "config.json").read_text())
    theirs = RunSet.seed_at(RESULTS / folder).config()
    assert {k: v for k, v in ours.items() if k != "episodes"} == {k: v for k, v in theirs.items() if k != "episodes"}, (
        folder
    )


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


@pytest.mark.parametrize("case", CASE_PARAMS)
def test_committed_runs_reproduce_bit_for_bit(tmp_path, case: Case):
    """Each case (``maintainers/replay_references.py``) reruns its committed seeds as their command
    made them: one seed with its recorded command; one ``--seed-batch`` batch, since a batched
    seed's bits depend on its batch mates; or the compiled engine's seeds in one process, where
    every seed after the first runs on the first one's kept program (``train/compiled.py:ProgramCache``)."""
    if "--framework" in case.extra:
        pytest.importorskip("torch", reason="needs the torch extra")
    summary = committed_summary(RESULTS / case.seed_folders()[0])
    if case.kind == "batch":
        assert f"--seed-batch {len(case.seeds)}" in summary["command"]
        assert summary["provenance"]["seed_batch"] == list(case.seeds)
    if case.kind == "compiled":
        assert summary["provenance"]["engine"] == "compiled" and "--workers 1" in summary["command"]
    why = why_not_bit_exact(summary.get("provenance", {}), framework=case.framework)
    references = [host_reference(folder) if why is not None else None for folder in case.seed_folders()]
    episodes = case.episodes
    if why is not None and None in references:
        warnings.warn(
            f"{case.folder} was {why} and no reference of this host is kept: TensorFlow does not promise "
            "bit-exactness across CPUs, so only the first 5 episodes are compared, to float rounding"
            + (
                " (whole and bit for bit under the portable arithmetic: the test after this one)"
                if case.framework == "torch"
                else ""
            ),
            stacklevel=2,
        )
        episodes, references = 5, [None] * len(references)
    out = tmp_path / "run"
    proc = subprocess.run(case.command(out, episodes), capture_output=True, text=True, timeout=900)
    assert proc.returncode in ((0, 1) if case.kind == "seed" else (0,)), proc.stderr
    for folder, reference in zip(case.seed_folders(), references):
        expected = read_rows(reference) if reference is not None else committed_rows(RESULTS / folder)
        expected = expected[:episodes] if episodes is not None else expected
        got = read_rows(out / Path(folder).name / "episodes.csv")
        assert len(got) == len(expected), (
            f"{folder}: {len(got)} episodes against {len(expected)} ({reference or 'committed'})"
        )
        exact = why is None or reference is not None
        for want, have in zip(expected, got):
            assert agree(want, have, exact), f"{folder}: first difference at episode {want['episode']}"


@pytest.mark.parametrize("case", TORCH_CASES)
def test_pytorch_cases_replay_whole_and_bit_for_bit_under_the_portable_arithmetic_on_every_host(tmp_path, case: Case):
    """Each PyTorch case rerun under ``KERAS_RL_PORTABLE_TORCH=1`` (MKL's reproducible branch, ATen's
    AVX2 kernels, torch.optim's fused steps: ``keras_rl.torch.portable_arithmetic``) gives the references
    made under it (``tests/replay_references/portable-torch``), whole and bit for bit, on any CPU with
    AVX2. Its run executes no instruction whose bits are the silicon's own under an emulated Intel or
    AMD CPU, and gives those bits there too (``emulation-<CPU>.md``); so an AVX2 host, which keeps no
    PyTorch reference of its own, replays PyTorch whole here, and every other host checks that the
    arithmetic still travels."""
    pytest.importorskip("torch", reason="needs the torch extra")
    out = tmp_path / "run"
    env = {**os.environ, **set_env(PORTABLE_SET)}
    proc = subprocess.run(case.command(out), capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode in (0, 1), proc.stderr
    for folder in case.seed_folders():
        expected = read_rows(reference_rows(PORTABLE_SET, folder))
        got = read_rows(out / Path(folder).name / "episodes.csv")
        assert len(got) == len(expected) == case.episodes, folder
        for want, have in zip(expected, got):
            assert have == want, f"{folder}: first difference at episode {want['episode']}"
        summary = json.loads((out / Path(folder).name / "summary.json").read_text())
        assert summary["provenance"]["portable_torch"]["optimizer_step"] == "fused"


def test_a_host_without_avx512_replays_every_keras_case_against_its_own_references_in_full(monkeypatch):
    """On the instruction set of ``tests/replay_references/avx2`` every Keras case finds a reference
    for each of its seeds, as long as the case reruns, made with the committed run's config but the
    budget, and differs from the committed AVX-512 run (why references are kept); those not made on
    a real AVX2 host are the ones ``host.json`` says an emulated AVX2 CPU made. The PyTorch cases
    have none (``replay_references.VALIDATED``). This host finds none of another's."""

    made_on = json.loads((REFERENCES / "avx2" / "host.json").read_text())
    here = sys.modules[__name__]
    monkeypatch.setattr(here, "cpu_model", lambda: made_on["cpu_model"])
    monkeypatch.setattr(here, "cpu_isa", lambda: made_on["cpu_isa"])
    emulated = set(made_on["emulated"]["references"])
    whole_run = {  # pendulum stops at its threshold: at 115 on the AVX2 host (95 committed)
        "pendulum/faithful/seed_0": 115,
        "mountaincar/faithful/seed_0": 100,
        **{f"engines/pendulum/compiled/seed_{s}": n for s, n in ((0, 115), (1, 117), (2, 153))},
    }
    for case in CASES:
        if case.framework not in VALIDATED:  # none made under the emulator: 5 episodes, to rounding,
            # until a real AVX2 host makes its own natively (listed under "references")
            assert all(
                host_reference(folder) is None or folder in made_on.get("references", {})
                for folder in case.seed_folders()
            ), case.id
            continue
        for folder in case.seed_folders():
            reference = host_reference(folder)
            assert reference is not None, folder
            # the instruction set changes the bits: why a reference is kept
            assert_a_kept_reference(folder, reference, case.episodes or whole_run[folder])
    assert emulated <= {folder for case in CASES for folder in case.seed_folders()}
    monkeypatch.setattr(here, "cpu_isa", lambda: [*made_on["cpu_isa"], "avx512f"])
    assert host_reference("pendulum/faithful/seed_0") is None


def test_an_intel_xeon_with_avx512_replays_keras_as_committed_and_pytorch_against_its_own_references(monkeypatch):
    """Measured on an Intel Xeon with the committed AMD EPYC's instruction set: every Keras case
    gives the committed bits whole (TensorFlow's kernels follow the instruction set), so
    ``PLATFORMS.json`` lists it as exact for Keras and no Keras reference is kept; PyTorch's differ
    (MKL's products follow the vendor), so each PyTorch case has a reference for every seed, as long
    as the case reruns, made on that host with the committed config, and different from the
    committed run."""
    made_on = json.loads((REFERENCES / "intel-xeon-avx512" / "host.json").read_text())
    here = sys.modules[__name__]
    monkeypatch.setattr(here, "cpu_model", lambda: made_on["cpu_model"])
    monkeypatch.setattr(here, "cpu_isa", lambda: made_on["cpu_isa"])
    from keras_rl.runs import provenance

    monkeypatch.setattr(provenance, "cpu_model", lambda: made_on["cpu_model"])
    monkeypatch.setattr(provenance, "cpu_isa", lambda: made_on["cpu_isa"])
    for case in CASES:
        recorded = committed_summary(RESULTS / case.seed_folders()[0])["provenance"]
        why = why_not_bit_exact(recorded, framework=case.framework)
        if case.framework == "keras":
            assert why is None, case.id
            assert all(host_reference(folder) is None for folder in case.seed_folders()), case.id
            continue
        assert why is not None, case.id
        for folder in case.seed_folders():
            reference = host_reference(folder)
            assert reference is not None and folder in made_on["references"], folder
            assert case.episodes is not None, case.id
            assert_a_kept_reference(folder, reference, case.episodes)


def test_the_portable_set_holds_every_pytorch_case_whole_checked_under_an_emulated_intel_and_amd_cpu():
    """``tests/replay_references/portable-torch``: made under the switch's caps, a reference for every
    seed of every PyTorch case, as long as the case reruns, with the committed config, different from
    the committed run (another arithmetic); and each emulated CPU's report (``check --trace``) gives
    those bits for every case while its runs execute no instruction whose bits are the silicon's own."""
    from keras_rl.torch import PORTABLE_CAPS, PORTABLE_SWITCH

    host = json.loads((REFERENCES / PORTABLE_SET / "host.json").read_text())
    assert host["portable"] == {"switch": f"{PORTABLE_SWITCH}=1", "sets": PORTABLE_CAPS, "optimizer_step": "fused"}
    torch_cases = [case for case in CASES if case.framework == "torch"]
    folders = {folder for case in torch_cases for folder in case.seed_folders()}
    assert set(host["references"]) == folders
    for case in torch_cases:
        assert case.episodes is not None, case.id
        for folder in case.seed_folders():
            assert_a_kept_reference(folder, reference_rows(PORTABLE_SET, folder), case.episodes)
    for cpu, vendor in (("Haswell", "Intel"), ("EPYC-Rome", "AMD")):
        report = (REFERENCES / PORTABLE_SET / f"emulation-{cpu}.md").read_text()
        rows = [line.split(" | ") for line in report.splitlines() if line.startswith("| post")]
        assert len(rows) == len(folders), (cpu, vendor)
        for row in rows:
            assert row[3].startswith("the same bits") and row[-1] == "none |", (cpu, row)
