"""A packed run set: every seed of a finished set in one Parquet file, ``runs.parquet``.

Live runs write per-seed folders (``seed_<n>/``: resume, checkpoints, locks). ``keras-rl pack``
turns a finished set into one file in the set's folder, and removes the seed folders only once
the file reads back to what they held:

- one row per episode, ``seed`` first, then ``episodes.csv``'s columns, typed (``episode``,
  ``steps`` and ``total_steps`` as int64, the rest float64, an empty loss as null), sorted by
  seed and episode; wall time (the one column that is not a function of the seed) as whole
  milliseconds, ``wall_ms`` (``wall_seconds`` * 1000, rounded);
- the file's metadata under the key ``keras_rl``: JSON holding the set's distinct configs once
  (``seed`` null), and for each seed its ``summary.json``, the index of the config it ran and
  any other small file its folder held (``evaluation.json``), zstd-compressed (see ``metadata``).

``pandas.read_parquet(path)`` or ``polars.read_parquet(path)`` reads the episodes without this
module; ``metadata(path)`` is the rest in three lines of pyarrow. Every record of a seed comes
back as it was written: ``config.json`` and ``summary.json`` byte for byte, ``episodes.csv``
in every column but wall time (``extract`` writes the folder again). Nothing here imports
TensorFlow.
"""

from __future__ import annotations

import base64
import functools
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from keras_rl.atomic import atomic_write_bytes, atomic_write_text
from keras_rl.errors import RunFolderError, argument
from keras_rl.runs.files import (
    INTEGER_COLUMNS,
    SEED_FOLDER,
    TIMING_COLUMNS,
    format_row,
    read_episodes,
    seed_of,
    seed_rows,
)

PACKED = "runs.parquet"
"""The packed set's file name, in the set's folder."""
FORMAT = 1
RECORDS = ("config.json", "summary.json", "episodes.csv")
"""What every seed folder holds; other small text files travel in the metadata as they are."""
SMALL_FILE = 1 << 20
"""A seed folder's other files are packed when they are text (``.json``, ``.md``, ``.txt``) under 1 MiB."""
TEXT_SUFFIXES = (".json", ".md", ".txt")
WALL, WALL_MS = "wall_seconds", "wall_ms"


def _stored(column: str) -> str:
    """The Parquet column that holds ``episodes.csv``'s ``column``."""
    return WALL_MS if column == WALL else column


def _encoding(column: str) -> str:
    """Each column's Parquet encoding, chosen by measurement over the committed sets (zstd after
    it): counters as deltas, scores split by byte stream, the rest plain: 29% smaller than one
    encoding for all."""
    if column in ("seed", "episode", "total_steps", WALL_MS):
        return "DELTA_BINARY_PACKED"
    if column in ("score", "steps"):
        return "BYTE_STREAM_SPLIT"
    return "PLAIN"


def _json_text(value: Any) -> str:
    """What ``atomic_write_json`` writes for ``value``."""
    from keras_rl.atomic import finite_or_none

    return json.dumps(finite_or_none(value), indent=2, allow_nan=False) + "\n"


def _pyarrow():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a dependency
        raise RunFolderError("reading or writing a packed run set needs pyarrow: pip install pyarrow") from None
    return pa, pq


def metadata(path: Path) -> dict[str, Any]:
    """The packed set's configs and per-seed records (the file's ``keras_rl`` metadata)."""
    pa, pq = _pyarrow()
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowException) as exc:
        raise RunFolderError(f"{path} is not a readable Parquet file ({exc})") from None
    raw = meta.get(b"keras_rl")
    if raw is None:
        raise RunFolderError(f"{path} is a Parquet file without keras_rl's records: not a packed run set")
    head = json.loads(raw)
    if head.get("format") != FORMAT:
        raise RunFolderError(f"{path} is packed in format {head.get('format')!r}; this keras-rl reads {FORMAT}")
    body = pa.decompress(base64.b64decode(head["records"]), decompressed_size=head["size"], codec="zstd", asbytes=True)
    return {**head, "records": json.loads(body)}


@dataclass(frozen=True)
class SeedRecord:
    """One seed of a packed set: its files' contents and its episodes."""

    seed: int
    config_text: str
    summary_text: str
    columns: tuple[str, ...]
    rows: list[dict[str, Any]]
    files: dict[str, str]

    def text_rows(self) -> list[dict[str, str]]:
        """The rows as ``episodes.csv`` writes them, without the timing column."""
        kept = tuple(c for c in self.columns if c not in TIMING_COLUMNS)
        return [format_row(row, kept) for row in self.rows]


class PackedSet:
    """A ``runs.parquet`` read once (cached by path, size and modification time)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        head = metadata(self.path)
        self.columns: tuple[str, ...] = tuple(head["columns"])
        self._configs: list[dict[str, Any]] = head["configs"]
        self._records: dict[int, dict[str, Any]] = {int(r["seed"]): r for r in head["records"]}
        self._episodes: tuple[Any, dict[int, tuple[int, int]]] | None = None

    @property
    def seeds(self) -> list[int]:
        return sorted(self._records)

    def _slices(self) -> tuple[Any, dict[int, tuple[int, int]]]:
        """The episodes table (read once) and each seed's first row and row count in it."""
        if self._episodes is None:
            import numpy as np

            _, pq = _pyarrow()
            table = pq.read_table(self.path)
            seeds, first, count = np.unique(table.column("seed").to_numpy(), return_index=True, return_counts=True)
            spans = {int(s): (int(i), int(n)) for s, i, n in zip(seeds, first, count)}
            self._episodes = (table, spans)
        return self._episodes

    def columns_of(self, seed: int) -> dict[str, list[Any]]:
        """The seed's episodes column by column (``episodes.csv``'s columns, typed as ``rows``)."""
        table, spans = self._slices()
        if seed not in spans:
            return {c: [] for c in self.columns}
        part = table.slice(*spans[seed])
        values = {c: part.column(_stored(c)).to_pylist() for c in self.columns}
        if WALL in values:
            values[WALL] = [None if ms is None else ms / 1000 for ms in values[WALL]]
        return values

    def _seed_rows(self, seed: int) -> list[dict[str, Any]]:
        values = self.columns_of(seed)
        return [dict(zip(self.columns, row)) for row in zip(*(values[c] for c in self.columns))]

    def record(self, seed: int) -> SeedRecord:
        if seed not in self._records:
            raise RunFolderError(f"{self.path} holds no seed {seed} (it holds {_ranges(self.seeds)})")
        r = self._records[seed]
        config_text = r.get("config_text") or _json_text(self.config(seed))
        summary_text = r.get("summary_text") or _json_text(r["summary"])
        return SeedRecord(
            seed, config_text, summary_text, self.columns, self._seed_rows(seed), dict(r.get("files", {}))
        )

    def summary_record(self, seed: int) -> dict[str, Any]:
        r = self._records[seed]
        return json.loads(r["summary_text"]) if "summary_text" in r else r["summary"]

    def config(self, seed: int) -> dict[str, Any]:
        """The seed's ``config.json`` as written: its set's shared config with its seed, or its own
        text where it was written another way."""
        r = self._records[seed]
        if "config_text" in r:
            return json.loads(r["config_text"])
        config = dict(self._configs[r["config"]])
        config["seed"] = seed
        return config

    def rows(self, seed: int) -> list[dict[str, Any]]:
        if seed not in self._records:
            raise RunFolderError(f"{self.path} holds no seed {seed}")
        return self._seed_rows(seed)


@functools.lru_cache(maxsize=128)
def _open(path: str, size: int, mtime_ns: int) -> PackedSet:
    return PackedSet(Path(path))


def open_packed(path: Path) -> PackedSet:
    """The packed set at ``path``, read once per version of the file."""
    path = Path(path)
    try:
        stat = path.stat()
    except OSError as exc:
        raise RunFolderError(f"cannot read {path} ({exc.strerror or exc})") from None
    return _open(os.path.abspath(path), stat.st_size, stat.st_mtime_ns)  # abspath: no syscall per call, as resolve has


def _ranges(seeds: Iterable[int]) -> str:
    """``0-29, 40`` for seeds 0 to 29 and 40."""
    spans: list[list[int]] = []
    for s in sorted(seeds):
        if spans and spans[-1][1] == s - 1:
            spans[-1][1] = s
        else:
            spans.append([s, s])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in spans) or "none"


def refuse_packed(run_dir: Path) -> None:
    """A seed that its set's ``runs.parquet`` holds is never written again beside it."""
    run_dir = Path(run_dir)
    packed = run_dir.parent / PACKED
    if not packed.is_file() or SEED_FOLDER.fullmatch(run_dir.name) is None:
        return
    if seed_of(run_dir) in open_packed(packed).seeds:
        raise RunFolderError(
            f"seed {run_dir.name[5:]} of {run_dir.parent} is packed in {packed}, and a packed run is "
            f"never rewritten: pass {argument('out')} for a folder of your own"
        )


# -- packing ---------------------------------------------------------------------------------


def _seed_entry(
    seed_dir: Path, seed: int, configs: dict[str, int], config_list: list, keep_folders: bool = False
) -> tuple[dict, list, tuple]:
    """One seed folder's record for the metadata, its typed rows and its columns; a
    RunFolderError for a folder that cannot be packed without losing something. With
    ``keep_folders`` the folder stays, so what a packed set does not keep (weights, checkpoints,
    pictures) stays in it and is left out of the record."""
    from keras_rl.runs.summary import RunSummary

    files = {p.name: p for p in seed_dir.iterdir() if not p.name.startswith(".")}
    missing = [n for n in RECORDS if n not in files]
    if missing:
        raise RunFolderError(f"{seed_dir} lacks {', '.join(missing)}: only finished runs are packed")
    others = {n: p for n, p in files.items() if n not in RECORDS}
    unpackable = [
        n
        for n, p in others.items()
        if not p.is_file() or p.suffix not in TEXT_SUFFIXES or p.stat().st_size > SMALL_FILE
    ]
    if keep_folders:
        others = {n: p for n, p in others.items() if n not in unpackable}
    elif unpackable:
        raise RunFolderError(
            f"{seed_dir} holds {', '.join(sorted(unpackable))}, which a packed set does not keep (weights, "
            f"checkpoints, pictures): pack with {argument('keep_folders')} (the packed set holds the "
            f"records, and the folders "
            "keep only those files), or move them out first"
        )
    summary_text = files["summary.json"].read_text()
    summary = RunSummary.read(seed_dir)
    if summary.status == "running":
        raise RunFolderError(f"{seed_dir} is still running (summary.json says so): only finished runs are packed")
    if summary.seed != seed:
        raise RunFolderError(f"{seed_dir} holds the run of seed {summary.seed}, not {seed}")
    entry: dict[str, Any] = {"seed": seed}
    parsed_summary = json.loads(summary_text)
    if _json_text(parsed_summary) == summary_text:
        entry["summary"] = parsed_summary
    else:  # written by another writer: kept as it is
        entry["summary_text"] = summary_text
    config_text = files["config.json"].read_text()
    config = json.loads(config_text)
    if config.get("seed") == seed and _json_text(config) == config_text:
        shared = dict(config)
        shared["seed"] = None
        key = json.dumps(shared)
        if key not in configs:
            configs[key] = len(config_list)
            config_list.append(shared)
        entry["config"] = configs[key]
    else:
        entry["config_text"] = config_text
    if others:
        entry["files"] = {n: others[n].read_text() for n in sorted(others)}
    csv_path = files["episodes.csv"]
    rows = read_episodes(csv_path, expected_rows=summary.rows_expected)
    with open(csv_path, newline="") as fh:
        header = fh.readline().strip().split(",")
    columns = tuple(header)
    typed = [
        {**row, WALL: None if row[WALL] is None else round(row[WALL] * 1000) / 1000} if WALL in row else row
        for row in rows
    ]
    record = SeedRecord(seed, "", "", columns, typed, {})
    if record.text_rows() != seed_rows(csv_path):
        raise RunFolderError(
            f"{csv_path} is not written as keras-rl writes episodes (a value that does not read back to "
            "its own text): it cannot be packed without changing it"
        )
    return entry, typed, columns


def pack_table(seed_dirs: list[tuple[int, Path]], existing: PackedSet | None = None, keep_folders: bool = False):
    """The Parquet table of ``existing``'s seeds and the folders ``seed_dirs``, and its metadata."""
    pa, _ = _pyarrow()
    configs: dict[str, int] = {}
    config_list: list[dict[str, Any]] = []
    entries: dict[int, dict] = {}
    rows_of: dict[int, list[dict[str, Any]]] = {}
    columns: tuple[str, ...] | None = None
    if existing is not None:
        columns = existing.columns
        for seed in existing.seeds:
            r = dict(existing._records[seed])
            if "config" in r:
                shared = existing._configs[r["config"]]
                key = json.dumps(shared)
                if key not in configs:
                    configs[key] = len(config_list)
                    config_list.append(shared)
                r["config"] = configs[key]
            entries[seed], rows_of[seed] = r, existing.rows(seed)
    for seed, seed_dir in seed_dirs:
        if seed in entries:
            raise RunFolderError(f"seed {seed} is both in {existing.path if existing else '?'} and in {seed_dir}")
        entry, rows, cols = _seed_entry(seed_dir, seed, configs, config_list, keep_folders)
        if columns is not None and cols != columns:
            raise RunFolderError(
                f"{seed_dir / 'episodes.csv'} has columns {', '.join(cols)}, the set's other seeds "
                f"{', '.join(columns)}: one set, one kind of run"
            )
        columns = cols
        entries[seed], rows_of[seed] = entry, rows
    if columns is None:
        raise RunFolderError("nothing to pack: no seed_<n>/ folder with a finished run")
    order = sorted(entries)
    data: dict[str, list] = {"seed": [s for s in order for _ in rows_of[s]]}
    for c in columns:
        data[_stored(c)] = [row.get(c) for s in order for row in rows_of[s]]
    if WALL in columns:
        data[WALL_MS] = [None if v is None else round(v * 1000) for v in data[WALL_MS]]
    fields = [pa.field("seed", pa.int64(), nullable=False)] + [
        pa.field(_stored(c), pa.int64() if c in (*INTEGER_COLUMNS, WALL) else pa.float64()) for c in columns
    ]
    body = json.dumps([entries[s] for s in order], separators=(",", ":"), allow_nan=False).encode()
    head = {
        "format": FORMAT,
        "columns": list(columns),
        "configs": config_list,
        "size": len(body),
        "records": base64.b64encode(pa.compress(body, codec="zstd", asbytes=True)).decode("ascii"),
    }
    schema = pa.schema(fields, metadata={b"keras_rl": json.dumps(head, separators=(",", ":")).encode()})
    return pa.table(data, schema=schema)


def write_table(table, path: Path) -> None:
    """The table to ``path`` atomically: zstd at level 19, each column in its own encoding."""
    import io

    _, pq = _pyarrow()
    buf = io.BytesIO()
    pq.write_table(
        table,
        buf,
        compression="zstd",
        compression_level=19,
        use_dictionary=False,
        column_encoding={name: _encoding(name) for name in table.schema.names},
        write_statistics=False,
    )
    atomic_write_bytes(path, buf.getvalue())


def extract(packed: PackedSet, seed: int, dest: Path) -> Path:
    """The seed's folder as it was before packing (``wall_seconds`` to the millisecond) at ``dest``."""
    from keras_rl.runs.files import episodes_csv_text

    record = packed.record(seed)
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    atomic_write_text(dest / "config.json", record.config_text)
    atomic_write_text(dest / "summary.json", record.summary_text)
    atomic_write_text(dest / "episodes.csv", episodes_csv_text(record.rows, record.columns))
    for name, text in record.files.items():
        atomic_write_text(dest / name, text)
    return dest


def pack(folder: Path, keep_folders: bool = False) -> tuple[Path, list[int]]:
    """Pack the finished ``seed_<n>/`` folders of ``folder`` into ``folder/runs.parquet`` (with
    the seeds it already holds), check that the file reads back to every record, then remove the
    folders; with ``keep_folders``, only the files the packed set holds, so that each folder keeps
    what it does not (weights, checkpoints, pictures). Returns the file and the seeds newly packed."""
    import shutil

    folder = Path(folder)
    if not folder.is_dir():
        raise RunFolderError(f"{folder} is not a folder")
    path = folder / PACKED
    existing = open_packed(path) if path.is_file() else None
    kept = set(existing.seeds) if existing is not None else set()
    dirs = sorted(
        (
            p
            for p in folder.iterdir()
            if SEED_FOLDER.fullmatch(p.name)
            and p.is_dir()
            # a folder an earlier --keep-folders left (its files that runs.parquet does not hold) is not a run
            and not (seed_of(p) in kept and not (p / "summary.json").exists())
        ),
        key=seed_of,
    )
    if not dirs:
        if existing is not None:
            return path, []
        raise RunFolderError(f"{folder} holds no seed_<n>/ folders to pack")
    table = pack_table([(seed_of(d), d) for d in dirs], existing, keep_folders)
    tmp = folder / f".{PACKED}.new"
    write_table(table, tmp)
    try:
        check_packed(open_packed(tmp), [(seed_of(d), d) for d in dirs])
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
    packed = open_packed(path)
    for d in dirs:
        if not keep_folders:
            shutil.rmtree(d)
            continue
        # the folder keeps only what the packed set does not (weights, checkpoints, pictures): its
        # records live in runs.parquet alone, so every reader takes the set (no seed in both forms)
        for name in (*RECORDS, *packed.record(seed_of(d)).files):
            (d / name).unlink(missing_ok=True)
    return path, [seed_of(d) for d in dirs]


def check_packed(packed: PackedSet, seed_dirs: list[tuple[int, Path]]) -> None:
    """Each folder's records read back from ``packed`` as they are on disk: ``config.json``,
    ``summary.json`` and the other files byte for byte, ``episodes.csv`` in every column but
    wall time, and wall time within half a millisecond."""
    for seed, seed_dir in seed_dirs:
        record = packed.record(seed)
        for name, text in (("config.json", record.config_text), ("summary.json", record.summary_text)):
            if (seed_dir / name).read_text() != text:
                raise RunFolderError(f"{packed.path}: seed {seed}'s {name} does not read back as written")
        for name, text in record.files.items():
            if (seed_dir / name).read_text() != text:
                raise RunFolderError(f"{packed.path}: seed {seed}'s {name} does not read back as written")
        if record.text_rows() != seed_rows(seed_dir / "episodes.csv"):
            raise RunFolderError(f"{packed.path}: seed {seed}'s episodes do not read back as written")
        walls = [r.get("wall_seconds") for r in read_episodes(seed_dir / "episodes.csv")]
        if any(
            (a is None) != (b is None) or (a is not None and abs(a - b) > 5e-4 + 1e-9)
            for a, b in zip(walls, (r.get("wall_seconds") for r in record.rows))
        ):
            raise RunFolderError(f"{packed.path}: seed {seed}'s wall times do not read back to the millisecond")
