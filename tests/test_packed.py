"""Packed run sets (``runs/packed.py``): a finished set's seed folders in one ``runs.parquet``,
read back by every reader as the folders were, and refused where packing would lose something."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from committed import RESULTS, copy_seeds

from keras_rl.cli import main
from keras_rl.errors import RunFolderError
from keras_rl.runs.packed import PACKED, metadata, pack
from keras_rl.runs.run_set import RunSet
from maintainers.replay import seed_rows


def folders(tmp_path: Path, run_set: str = "pendulum/faithful", seeds=(0, 1, 2)) -> Path:
    return copy_seeds(RESULTS / run_set, tmp_path / "set", lambda s: s in seeds)


def snapshot(folder: Path) -> dict:
    """Everything a reader sees of a set, wall time aside."""
    rs = RunSet(folder)
    return {
        "seeds": rs.seeds,
        "summaries": rs.summary_records(),
        "configs": rs.configs(),
        "rows": {
            r.seed: [{k: v for k, v in row.items() if k != "wall_seconds"} for row in r.rows()] for r in rs.runs()
        },
        "text": {r.seed: r.text_rows() for r in rs.runs()},
    }


def test_a_packed_set_reads_back_as_its_folders_did(tmp_path):
    folder = folders(tmp_path)
    before = snapshot(folder)
    texts = {s: {n: (folder / f"seed_{s}" / n).read_text() for n in ("config.json", "summary.json")} for s in (0, 1, 2)}
    walls = {r.seed: [row["wall_seconds"] for row in r.rows()] for r in RunSet(folder).runs()}
    path, packed = pack(folder)
    assert path == folder / PACKED and packed == [0, 1, 2]
    assert RunSet(folder).seed_dirs() == []  # the folders went once the file read back
    assert snapshot(folder) == before
    for r in RunSet(folder).runs():
        assert r.folder is None and all(
            abs(a - b) <= 5e-4 + 1e-9 for a, b in zip(walls[r.seed], (x["wall_seconds"] for x in r.rows()))
        )
        out = r.extract(tmp_path / "out" / f"seed_{r.seed}")
        assert {n: (out / n).read_text() for n in ("config.json", "summary.json")} == texts[r.seed]
        assert seed_rows(out / "episodes.csv") == before["text"][r.seed]


def test_the_file_is_plain_parquet_with_the_seed_and_each_config_once(tmp_path):
    folder = folders(tmp_path)
    pack(folder)
    table = pq.read_table(folder / PACKED)  # no keras_rl code
    assert table.column_names[:3] == ["seed", "episode", "steps"] and "wall_ms" in table.column_names
    assert sorted(set(table.column("seed").to_pylist())) == [0, 1, 2]
    head = metadata(folder / PACKED)
    assert len(head["configs"]) == 1 and head["configs"][0]["seed"] is None
    assert [r["seed"] for r in head["records"]] == [0, 1, 2]


def test_a_packed_set_takes_in_new_seed_folders_and_refuses_a_seed_held_twice(tmp_path):
    folder = folders(tmp_path, seeds=(0, 1))
    pack(folder)
    copy_seeds(RESULTS / "pendulum" / "faithful", folder, lambda s: s == 2)
    assert RunSet(folder).seeds == [0, 1, 2]  # both forms at once
    _, packed = pack(folder)
    assert packed == [2] and RunSet(folder).seeds == [0, 1, 2] and RunSet(folder).seed_dirs() == []
    copy_seeds(RESULTS / "pendulum" / "faithful", folder, lambda s: s == 1)
    with pytest.raises(RunFolderError, match="seed 1 is both in"):
        RunSet(folder).runs()


def test_what_a_packed_set_would_lose_is_refused_and_nothing_is_removed(tmp_path):
    folder = folders(tmp_path)
    (folder / "seed_1" / "actor.weights.h5").write_bytes(b"weights")
    with pytest.raises(RunFolderError, match=r"seed_1 holds actor.weights.h5"):
        pack(folder)
    assert sorted(p.name for p in folder.iterdir()) == ["seed_0", "seed_1", "seed_2"]
    (folder / "seed_1" / "actor.weights.h5").unlink()
    summary = json.loads((folder / "seed_2" / "summary.json").read_text())
    (folder / "seed_2" / "summary.json").write_text(json.dumps({**summary, "status": "running"}))
    with pytest.raises(RunFolderError, match="still running"):
        pack(folder)
    assert not (folder / PACKED).exists()


def test_a_packed_set_keeps_small_files_and_an_episodes_csv_not_written_by_us_is_refused(tmp_path):
    folder = folders(tmp_path)
    (folder / "seed_0" / "evaluation.json").write_text('{"mean": 91.5}\n')
    pack(folder, keep_folders=True)
    shutil.rmtree(folder / "seed_0")
    shutil.rmtree(folder / "seed_1")
    shutil.rmtree(folder / "seed_2")
    assert RunSet(folder).run(0).file_text("evaluation.json") == '{"mean": 91.5}\n'
    other = folders(tmp_path / "b")
    csv = other / "seed_0" / "episodes.csv"
    csv.write_text(csv.read_text().replace(",-1169.833467825739,", ",-1169.8334678257390,", 1))
    with pytest.raises(RunFolderError, match="does not read back to its own text"):
        pack(other)


def test_a_damaged_packed_file_is_named(tmp_path):
    folder = tmp_path / "set"
    folder.mkdir()
    (folder / PACKED).write_bytes(b"PAR1 not really")
    with pytest.raises(RunFolderError, match=r"runs.parquet is not a readable Parquet file"):
        RunSet(folder).runs()


def test_a_packed_seed_is_never_rewritten_and_the_command_says_so(tmp_path, capsys):
    folder = folders(tmp_path)
    pack(folder)
    code = main(["reproduce", "pendulum", "--seeds", "1", "--dry-run", "--out", str(folder)])
    assert code == 2 and "is packed in" in capsys.readouterr().err
    assert main(["pack", str(tmp_path / "nowhere")]) == 2
    assert "is not a folder" in capsys.readouterr().err
    assert main(["pack", str(folder)]) == 0  # already packed: nothing to do


def test_every_committed_set_is_packed():
    """results/ commits run sets packed; live seed folders stay out of it. Committed means what git
    tracks: a run someone left under results/ is theirs, not evidence (issue 72 item 1)."""
    from maintainers.manifest import committed_sets

    sets = committed_sets(RESULTS)
    assert len(sets) > 90
    assert [s.folder for s in sets if s.seed_dirs()] == []
    assert all(s.packed() is not None for s in sets)


def test_committed_sets_are_what_git_tracks(tmp_path):
    """A live set beside the committed ones (``make reproduce``'s, before issue 72 moved it to runs/)
    is not read as committed; a committed set is, packed or as seed folders."""
    import subprocess

    from maintainers.manifest import committed_sets

    results = tmp_path / "results"
    copy_seeds(RESULTS / "pendulum/faithful", results / "committed-folders", lambda s: s == 0)
    pack_source = copy_seeds(RESULTS / "pendulum/faithful", results / "committed-packed", lambda s: s in (0, 1))
    pack(pack_source)
    copy_seeds(RESULTS / "pendulum/faithful", results / "live", lambda s: s == 2)
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "results/committed-folders", "results/committed-packed"], check=True)
    subprocess.run([*git, "commit", "-qm", "sets"], check=True)
    found = sorted(s.folder.name for s in committed_sets(results))
    assert found == ["committed-folders", "committed-packed"]


def test_make_reproduce_writes_outside_results():
    """The README's first command must not leave a live set where the suite reads committed evidence
    (``make reproduce && make test`` failed on results/make-reproduce/, issue 72 item 1)."""
    import subprocess

    plan = subprocess.run(["make", "-n", "reproduce"], cwd=RESULTS.parent, capture_output=True, text=True, check=True)
    line = next(line for line in plan.stdout.splitlines() if "keras-rl reproduce" in line)
    out = Path(line.split("--out", 1)[1].split()[0])
    assert out.parts[0] != "results", line
