"""Every number the docs' prose takes from the data is regenerated and compared (issue 71 item 7).

``maintainers/prose.py`` writes each claim between its markers from the committed runs and the
files made from them; these tests write every page again in memory and fail on any difference, and
show that a number changed in one committed run changes a page.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from maintainers import prose

ROOT = Path(__file__).resolve().parents[1]


def test_every_claim_on_every_page_is_what_the_data_give():
    assert prose.stale() == [], "stale prose: python -m maintainers tables prose --write"


def test_a_block_no_claim_writes_is_refused():
    """Every block on a page belongs to a claim, so no number sits between markers unwritten."""
    named = prose.claims()
    for path in {ROOT / where for where, _, _ in named.values()}:
        found = [name for name, _ in prose.BLOCKS.findall(path.read_text())]
        assert sorted(found) == sorted(n for n, (w, _, _) in named.items() if ROOT / w == path), path


def test_a_number_changed_in_one_committed_run_changes_the_page(tmp_path, monkeypatch):
    """Post 003's first ten Keras seeds, one of them made to fail: the findings' sentence on them is
    no longer what ``docs/findings.md`` prints."""
    from keras_rl.runs.packed import extract, open_packed

    name = "seeds-0-9-had-given-vs"
    assert prose.claims()[name][0] == "docs/findings.md"
    results = tmp_path / "results"
    (results / "cartpole" / "faithful").mkdir(parents=True)
    for entry in (ROOT / "results").iterdir():
        if entry.name != "cartpole":
            os.symlink(entry, results / entry.name)
    for entry in (ROOT / "results" / "cartpole").iterdir():
        if entry.name != "faithful":
            os.symlink(entry, results / "cartpole" / entry.name)
    packed = open_packed(ROOT / "results" / "cartpole" / "faithful" / "runs.parquet")
    for seed in packed.seeds:
        extract(packed, seed, results / "cartpole" / "faithful" / f"seed_{seed}")
    won = next(s for s in range(10) if packed.summary_record(s)["success"])
    summary = results / "cartpole" / "faithful" / f"seed_{won}" / "summary.json"
    record = json.loads(summary.read_text())
    record["success"] = False
    summary.write_text(json.dumps(record))

    assert prose.stale([name]) == []
    monkeypatch.setattr(prose, "RESULTS", results)
    assert prose.stale([name]) == [name]
    committed = dict(prose.BLOCKS.findall((ROOT / "docs" / "findings.md").read_text()))[name]
    assert prose.said(name) != committed


def test_the_tables_on_bits_that_are_the_chips_are_rows_their_commands_printed():
    """``docs/performance.md``'s tables on torch's square root, the traces and the portable references
    are rows printed by ``benchmarks/approximate_bits.py`` and ``python -m maintainers replay-references``
    (``check --trace``, ``probe --trace``), as committed under ``tests/replay_references``; a table with
    a CPU column names the report (``emulation-<CPU>.md``) its row comes from."""
    text = (ROOT / "docs" / "performance.md").read_text()
    start = text.index("### Why: an instruction whose bits are the chip's")
    section = text[start : text.index("\n## ", start)]
    references = ROOT / "tests" / "replay_references"
    printed = "\n".join(p.read_text() for p in sorted(references.glob("*/*.md")))
    rows = [line for line in section.splitlines() if line.startswith("| ") and "---" not in line]
    rows = [row for row in rows if not row.startswith(("| vendor |", "| case |", "| CPU |"))]
    assert len(rows) >= 10
    for row in rows:
        cpu, _, rest = row[2:].partition(" | ")
        report = references / "portable-torch" / f"emulation-{cpu}.md"
        if report.is_file():
            assert f"| {rest}" in report.read_text().splitlines(), row
        else:
            assert row in printed.splitlines(), row
