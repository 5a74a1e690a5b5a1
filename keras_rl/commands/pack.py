"""``keras-rl pack``: a finished run set's seed folders into one ``runs.parquet``."""

from __future__ import annotations

import argparse
from pathlib import Path

from keras_rl.commands.common import EXIT_OK


def add_parser(sub) -> None:
    p = sub.add_parser(
        "pack",
        help="pack finished run sets: their seed_<n>/ folders into one runs.parquet each",
        description="Pack each finished run set (a folder of seed_<n>/ run folders) into one runs.parquet "
        "in that folder: one row per episode with its seed, the set's distinct configs once, every "
        "summary.json. The file is read back and compared with the folders (config.json and "
        "summary.json byte for byte, episodes.csv in every column but wall time, kept to the "
        "millisecond) before the folders are removed. Every keras-rl reader takes either form; "
        "pandas.read_parquet reads the episodes. A set already packed takes in its new seed folders.",
    )
    p.add_argument("folders", nargs="+", type=Path, help="run-set folders (with --recursive: folders to search)")
    p.add_argument("--recursive", action="store_true", help="pack every run set found under each folder")
    p.add_argument(
        "--keep-folders",
        action="store_true",
        help="keep in the seed folders what a packed set does not hold (weights, checkpoints, pictures); "
        "the rest (config.json, summary.json, episodes.csv and small text files) moves into runs.parquet",
    )


def pack(args: argparse.Namespace) -> int:
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.packed import pack as pack_set
    from keras_rl.runs.run_set import RunSet

    sets: list[Path] = []
    for folder in args.folders:
        if not folder.is_dir():
            raise RunFolderError(f"{folder} is not a folder")
        sets += [r.folder for r in RunSet.find(folder)] if args.recursive else [folder]
    if not sets:
        raise RunFolderError(f"no run set under {', '.join(map(str, args.folders))}")
    for i, folder in enumerate(sets, 1):
        path, seeds = pack_set(folder, keep_folders=args.keep_folders)
        size = path.stat().st_size / 1e6
        print(f"[{i}/{len(sets)}] {path}: {len(seeds)} seed folder(s) packed, {size:.2f} MB", flush=True)
    return EXIT_OK
