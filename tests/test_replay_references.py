"""``python -m maintainers replay-references``: the replay cases' commands, and its bad input (exit 2,
nothing written). The emulated runs themselves are slow and need qemu; their results are committed
(``tests/replay_references/avx2/emulation-EPYC-Rome.md``, ``host.json``) and replayed by
``tests/test_committed_runs_replay.py``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from maintainers import replay_references as rr
from maintainers.cli import main


def by_id(case_id: str) -> rr.Case:
    return next(c for c in rr.CASES if c.id == case_id)


def test_each_kind_reruns_its_seeds_as_their_command_made_them(tmp_path):
    batch = by_id("post001-batch-of-10-first3").command(tmp_path, prefix=("qemu-x86_64", "-cpu", "EPYC-Rome"))
    assert batch[:4] == ["qemu-x86_64", "-cpu", "EPYC-Rome", sys.executable]
    assert batch[batch.index("--seeds") + 1] == "0-9" and batch[batch.index("--seed-batch") + 1] == "10"
    assert batch[batch.index("--episodes") + 1] == "3"
    compiled = by_id("post000-compiled-seeds0-2").command(tmp_path)
    assert compiled[compiled.index("--engine") + 1] == "compiled" and "--episodes" not in compiled  # whole runs
    assert compiled[compiled.index("--workers") + 1] == "1"
    torch = by_id("post003-torch-seed0-first200").command(tmp_path, episodes=7)
    assert torch[torch.index("--episodes") + 1] == "7" and torch[-2:] == ["--framework", "torch"]
    assert {c.framework for c in rr.CASES} == {"keras", "torch"}
    assert len({c.id for c in rr.CASES}) == len(rr.CASES)


def test_every_case_names_committed_seeds():
    results = Path(rr.ROOT) / "results"
    from keras_rl.runs.run_set import RunSet

    for case in rr.CASES:
        for folder in case.seed_folders():
            assert RunSet.seed_at(results / folder).config()["seed"] == int(folder.rsplit("_", 1)[1]), folder


@pytest.mark.parametrize(
    "argv, message",
    [
        (["check", "--emulate", "EPYC-Rome", "--cases", "nope"], "no replay case nope"),
        (["make", "--emulate", "EPYC-Rome", "--write"], "--write saves check's report"),
        (["probe", "--emulate", "EPYC-Rome"], "probe runs the cases named by --cases"),
        (["check", "--emulate", "EPYC-Rome", "--reference-set", "avx1"], "no reference set 'avx1'"),
        (["check", "--emulate", "EPYC-Rome", "--episodes", "0"], "--episodes must be at least 1, not 0"),
        (["make", "--emulate", "EPYC-Rome", "--env", "A=1"], "--env and --native-env are probe's"),
        (["make", "--emulate", "EPYC-Rome", "--episodes", "3"], "--episodes is check's and probe's"),
        (
            ["check", "--emulate", "EPYC-Rome", "--write", "--cases", "post003-seed0-first60"],
            "--write saves check's report over every case",
        ),
        (
            ["probe", "--emulate", "EPYC-Rome", "--cases", "post003-seed0-first60", "--native-env", "MKL"],
            "KEY=VALUE, not 'MKL'",
        ),
        (["check"], "check compares a run under the emulator: name its CPU with --emulate"),
        (["make", "--reference-set", "../elsewhere"], "--reference-set names one folder under"),
        (["probe", "--cases", "post003-seed0-first60"], "name its CPU with --emulate"),
        (["make"], "reference set 'avx2' is not this host's"),  # made natively on a CPU of its own
        (["make", "--emulate", "Haswell", "--reference-set", "portable-torch"], "set is made natively"),
        (["make", "--reference-set", "portable-torch", "--trace"], "--trace counts the instructions"),
        (["make", "--emulate", "Haswell", "--trace"], "check's and probe's"),
    ],
)
def test_bad_input_exits_2_with_the_problem_named_before_the_emulator_is_sought(monkeypatch, capsys, argv, message):
    """Named before anything runs, with no emulator installed, and nothing under the references changes."""
    tree = {p: p.read_bytes() for p in rr.REFERENCES.rglob("*") if p.is_file()}
    sought = []
    monkeypatch.setattr(rr.shutil, "which", lambda name: sought.append(name))
    monkeypatch.setattr(rr, "_isa", lambda: ["sse2"])  # no reference set is this host's
    assert main(["replay-references", *argv]) == 2
    assert message in capsys.readouterr().err
    assert not sought
    assert {p: p.read_bytes() for p in rr.REFERENCES.rglob("*") if p.is_file()} == tree


def test_a_missing_emulator_or_a_bad_setting_is_named(monkeypatch):
    from keras_rl.errors import KerasRLError

    monkeypatch.setattr(rr.shutil, "which", lambda name: None)
    with pytest.raises(KerasRLError, match="qemu-x86_64 is not installed"):
        rr.emulated("EPYC-Rome")
    with pytest.raises(KerasRLError, match="KEY=VALUE, not 'MKL'"):
        rr._settings(["MKL"])
    assert rr._settings(["A=b=c"]) == {"A": "b=c"}


def test_the_emulated_references_are_recorded_with_how_they_were_made():
    host = json.loads(rr.host_file("avx2").read_text())
    made = {f for c in rr.CASES if c.framework in rr.VALIDATED for f in c.seed_folders()}
    for folder, record in host["emulated"]["references"].items():
        assert folder in made and rr.reference_rows("avx2", folder).is_file()
        assert record["command"].startswith("python -m maintainers replay-references make --emulate ")
        assert "-cpu " in record["how"] and " at commit " in record["made"] and "keras_rl tree" in record["made"]
    checked = (rr.REFERENCES / "avx2" / "emulation-EPYC-Rome.md").read_text()
    assert checked.count("the same bits") == 3 and "differs" in checked  # the emulator is the AVX2 host


def test_settings_given_over_several_flags_add_up(monkeypatch):
    """``--native-env A=1 --native-env B=2`` sets both: a second flag replaced the first once, and a
    probe ran with only its last cap, silently."""
    seen = []
    monkeypatch.setattr(rr, "run", lambda args: seen.append(args) or 0)
    argv = ["replay-references", "probe", "--emulate", "Haswell", "--cases", "post003-seed0-first60"]
    assert main([*argv, "--native-env", "A=1", "--native-env", "B=2 C", "--env", "D=4", "--env", "E=5"]) == 0
    assert seen[0].native_env == ["A=1", "B=2 C"] and seen[0].env == ["D=4", "E=5"]


@pytest.mark.parametrize(
    "committed_is_this_hosts, differs", [(False, True), (False, False), (True, False), (True, True)]
)
def test_a_native_make_keeps_a_reference_only_where_the_replay_test_would_read_it(
    tmp_path, monkeypatch, committed_is_this_hosts, differs
):
    """Where the replay test reads the committed run on this host (``why_not_bit_exact`` is None), make
    keeps nothing, and names a rerun that differs a mismatch; elsewhere it keeps every seed's rows and
    config, the same bits or not, listed in the new set's host.json."""
    import argparse
    import csv

    from keras_rl.runs.run_set import RunSet

    case = next(c for c in rr.CASES if c.id == "post003-torch-seed0-first200")
    folder = case.seed_folders()[0]
    committed = RunSet.seed_at(rr.ROOT / "results" / folder)

    def fake_rerun(case, prefix, episodes, work, env=None):
        seed = work / case.id / "seed_0"
        seed.mkdir(parents=True)
        rows = committed.text_rows()[: case.episodes]
        if differs:
            rows[-1] = {**rows[-1], "loss": "0.125"}
        with open(seed / "episodes.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        (seed / "config.json").write_text(json.dumps(committed.config()))
        return work / case.id, 0.0

    monkeypatch.setattr(rr, "REFERENCES", tmp_path)
    monkeypatch.setattr(rr, "rerun", fake_rerun)
    monkeypatch.setattr(rr, "_committed_is_this_hosts", lambda folder, case, native: committed_is_this_hosts)
    args = argparse.Namespace(reference_set="here", emulate=None, cases=[case.id])
    lines = rr.make(args, (), tmp_path / "work")
    kept = rr.reference_rows("here", folder)
    host = json.loads(rr.host_file("here").read_text()) if rr.host_file("here").is_file() else {}
    if committed_is_this_hosts:
        assert not kept.exists() and folder not in host.get("references", {})
        assert ("MISMATCH" in lines[-1]) == differs and "none kept" in lines[-1]
    else:
        assert kept.is_file() and (kept.parent / "config.json").is_file()
        assert (
            host["references"][folder]["command"]
            == f"python -m maintainers replay-references make --reference-set here --cases {case.id}"
        )
        assert (host["cpu_model"], host["cpu_isa"]) == (rr.this_host()["cpu_model"], rr._isa())


def test_the_trace_counts_the_approximate_instructions_a_run_executes(tmp_path, monkeypatch):
    """QEMU's ``-d in_asm`` log, read through a pipe as it is written, over more than one read; and a
    run that dies before opening its log does not leave the reader waiting."""
    import collections

    lines = ["0x4011c0:  vrsqrtps %ymm1, %ymm0", "0x4011c4:  vmulps %ymm0, %ymm1, %ymm2", "0x4011c8:  frsqrtx"]
    lines += ["0x4011d0:  rcpss %xmm0, %xmm1", "0x4011d4:  fsincos", "0x4011d8:  vfmadd231ps %ymm1, %ymm2, %ymm3"]
    writer = (
        "import sys; log = open(sys.argv[1], 'w'); "
        "[log.write('0x%x:  vsqrtps %%ymm0, %%ymm1\\n0x%x:  rsqrtss %%xmm0, %%xmm1\\n' % (i, i)) "
        "for i in range(60000)]; "
        f"log.write({chr(10).join(lines)!r}); log.close()"
    )

    def command(self, out, episodes=None, prefix=()):
        return [sys.executable, "-c", writer, prefix[prefix.index("-D") + 1]]

    monkeypatch.setattr(rr.Case, "command", command)
    case = by_id("post003-torch-seed0-first200")
    counts: collections.Counter = collections.Counter()
    rr.rerun(case, ("qemu-x86_64",), 1, tmp_path / "logged", None, counts)
    assert counts == {"rsqrtss": 60000, "vrsqrtps": 1, "rcpss": 1, "fsincos": 1}
    assert rr.approximate_shown(collections.Counter(fsincos=1, rcpss=2)) == "`fsincos` in 1 block, `rcpss` in 2 blocks"
    monkeypatch.setattr(rr.Case, "command", lambda self, out, episodes=None, prefix=(): [sys.executable, "-c", ""])
    quiet: collections.Counter = collections.Counter()
    rr.rerun(case, ("qemu-x86_64",), 1, tmp_path / "silent", None, quiet)
    assert rr.approximate_shown(quiet) == "none"
