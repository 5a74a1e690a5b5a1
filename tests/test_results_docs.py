"""results/README.md's generated tables match the committed run folders and reports."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_generator(name: str = "findings_table"):
    spec = importlib.util.spec_from_file_location(name, ROOT / "reproductions" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def block(text: str, begin: str, end: str) -> str:
    return text.split(begin, 1)[1].split(end, 1)[0].strip()


def test_the_findings_and_compare_tables_are_up_to_date():
    gen = load_generator()
    readme = (ROOT / "results" / "README.md").read_text()
    assert block(readme, gen.BEGIN, gen.END) == gen.table(), (
        "results/README.md is stale: run python reproductions/findings_table.py --write"
    )
    assert block(readme, gen.COMPARE_BEGIN, gen.COMPARE_END) == gen.compare_table(), (
        "results/README.md is stale: run python reproductions/findings_table.py --write"
    )
    assert block((ROOT / "README.md").read_text(), gen.SHORT_BEGIN, gen.SHORT_END) == gen.short_table(), (
        "README.md's findings are stale: run python reproductions/findings_table.py --write"
    )
    assert "not run" not in gen.table()  # every row of the single table has its runs committed
    for experiment in ("pendulum", "cartpole", "mountaincar"):
        assert (ROOT / "results" / "compare" / experiment / "report.md").is_file(), experiment


def test_the_cartpole_seeds_said_to_fail_are_the_ones_that_failed():
    import json
    import re

    readme = (ROOT / "results" / "README.md").read_text()
    named = re.search(r"seeds? ([\d, and]+?) never got there", readme).group(1)
    said = {int(s) for s in re.findall(r"\d+", named)}
    failed = {
        s
        for s in range(10)
        if not json.loads((ROOT / "results" / "cartpole" / "faithful" / f"seed_{s}" / "summary.json").read_text())[
            "success"
        ]
    }
    assert said == failed


def test_fidelitys_measured_effect_tables_are_up_to_date():
    gen = load_generator("ablation_table")
    ledger = (ROOT / "reproductions" / "FIDELITY.md").read_text()
    for experiment in gen.SOURCES:
        assert block(ledger, *gen.markers(experiment)) == gen.table(experiment), (
            f"FIDELITY.md's {experiment} table is stale: run python reproductions/ablation_table.py --write"
        )
    # every quirk switch of post 000 has its row, with numbers (its ablations are committed)
    pendulum = gen.table("pendulum")
    for ledger_id in ("P000-NOISE", "P000-DONE", "P000-BROADCAST", "P000-TARGETINIT"):
        row = next(line for line in pendulum.splitlines() if line.startswith(f"| {ledger_id} |"))
        assert "not run yet" not in row and "10/10" in row


def test_every_committed_run_records_the_commit_and_clean_tree_that_made_it():
    import json

    summaries = sorted((ROOT / "results").glob("**/seed_*/summary.json"))
    assert len(summaries) > 500
    missing = [
        str(p.parent.relative_to(ROOT))
        for p in summaries
        if not json.loads(p.read_text()).get("provenance", {}).get("commit")
    ]
    dirty = [str(p.parent.relative_to(ROOT)) for p in summaries if json.loads(p.read_text())["provenance"].get("dirty")]
    assert not missing, f"runs without provenance (regenerate them): {missing[:5]}"
    assert not dirty, f"runs made from a dirty tree (regenerate them from a clean checkout): {dirty[:5]}"
