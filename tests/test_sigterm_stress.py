"""The SIGTERM stress of issue 72, item 18 (``maintainers/sigterm_stress.py``): how a stop is read,
the committed counts as their records give them, and one real stop of the compiled engine."""

from __future__ import annotations

import json

import pytest

from maintainers import sigterm_stress
from maintainers.cli import main


def _stop(**over):
    return {"engine": "compiled", "heap_check": False, "exit": 143, "hung": False, "heap_messages": [], **over} | {
        "reference_bits": over.get("reference_bits", True)
    }


def test_a_stop_is_read_by_its_exit_its_heap_messages_and_its_bits():
    read = sigterm_stress.verdict
    assert read(_stop()) == "stopped"
    assert read(_stop(exit=0)) == "finished first"
    assert read(_stop(exit=-6)) == "abort" and read(_stop(exit=134)) == "abort"
    assert read(_stop(heap_messages=["corrupted"])) == "abort"  # a message even where the exit looks right
    assert read(_stop(hung=True, exit=-9)) == "hung"
    assert read(_stop(exit=-15)) == "killed after its work"
    assert read(_stop(exit=-15, reference_bits=False)) == "exit -15"  # killed mid-run: counted as other
    assert read(_stop(exit=-15, summary_status="running")) == "exit -15"  # its summary not yet final
    assert sigterm_stress.HEAP_MESSAGE.search("corrupted size vs. prev_size while consolidating")
    rows = sigterm_stress.counts([_stop(), _stop(heap_check=True, exit=-6), _stop(reference_bits=False)])
    assert [(r["heap_check"], r["stops"], r["aborts"], r["reference_bits"]) for r in rows] == [
        (False, 2, 0, 1),
        (True, 1, 1, 1),
    ]


def test_the_committed_counts_are_their_stops_as_read_and_show_no_abort():
    """results/reliability/sigterm-stress.json: its counts recomputed from its stops, at least 100 stops
    per engine, half of them under heap checking, no abort, and every seed at the reference's bits."""
    record = json.loads(sigterm_stress.RECORD.read_text())
    assert record["counts"] == sigterm_stress.counts(record["stops"])
    for engine in sigterm_stress.CASES:
        mine = [r for r in record["stops"] if r["engine"] == engine]
        assert len(mine) >= 100, engine
        assert sum(r["heap_check"] for r in mine) == len(mine) // 2 + len(mine) % 2
        allowed = ("stopped", "finished first", "killed after its work")
        assert all(sigterm_stress.verdict(r) in allowed and r["reference_bits"] for r in mine), engine
        assert sum(r["signalled"] and r["exit"] == 143 for r in mine) >= 50  # most landed in training
    assert sigterm_stress.REPORT.read_text() == sigterm_stress.markdown(
        record["counts"], record["references"], record["command"]
    )


@pytest.mark.slow
def test_a_real_stop_of_the_compiled_engine_resumes_to_the_uninterrupted_runs_bits(tmp_path, capsys):
    """The reference seed, then one SIGTERM at a random time after training began under heap
    checking (stop 0), resumed and compared: what the committed counts are made of."""
    assert main(["sigterm-stress", "--stops", "1", "--engines", "compiled", "--out", str(tmp_path)]) == 0
    (stop,) = [json.loads(line) for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
    assert stop["heap_check"] and stop["signalled"] and stop["reference_bits"]
    assert sigterm_stress.verdict(stop) in ("stopped", "finished first", "killed after its work")
    assert "| compiled | yes | 1 |" in capsys.readouterr().out
    assert main(["sigterm-stress", "--stops", "0", "--out", str(tmp_path)]) == 2  # bad input, exit 2
