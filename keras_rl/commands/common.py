"""What every command shares: exit codes, the seed list, output-folder checks, the stop code."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from keras_rl.errors import ConfigError, KerasRLError
from keras_rl.study import MAX_SEEDS, check_writable_dir

EXIT_OK, EXIT_CRITERION, EXIT_USAGE, EXIT_NO_VERDICT = 0, 1, 2, 3
"""More seeds than this in one command is taken for a typo (``0-100000``) and refused."""


def _stopped() -> int:
    """The exit code of a command a signal stopped (130 Ctrl-C, 143 SIGTERM)."""
    from keras_rl.runs.signals import stop_exit_code

    return stop_exit_code()


def parse_seeds(text: str) -> list[int]:
    """``"0-9"``, ``"1,3,5"``, ``"0-2,7"`` -> a sorted list of distinct seeds.

    Refused, each with a ConfigError naming it: an empty item (``1,,2``), a seed named twice
    (``1,1``), digits other than ASCII ones, and more than ``MAX_SEEDS`` seeds, which is
    checked from the range's ends before any list is built (``0-4294967295`` would not fit
    in memory)."""
    seeds: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            raise ConfigError(f"seeds {text!r} has an empty item; write a list like 0,1,2 or a range like 0-9")
        if not part.isascii():
            raise ConfigError(f"seeds {text!r}: {part!r} is not written in ASCII digits")
        lo_text, dash, hi_text = part.partition("-") if "-" in part[1:] else (part, "", part)
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise ConfigError(f"cannot read seeds {text!r}: use a list like 0,1,2 or a range like 0-9") from None
        if lo > hi:
            raise ConfigError(f"seed range {part!r} runs backwards; write {hi}-{lo}")
        if lo < 0:
            raise ConfigError(f"seeds must be zero or more, got {lo}")
        if hi >= 2**32:
            raise ConfigError(f"seeds must be below 2**32 (NumPy's and Gymnasium's limit), got {hi}")
        if len(seeds) + hi - lo + 1 > MAX_SEEDS:
            raise ConfigError(f"{text!r} names more than {MAX_SEEDS} seeds; split the run into smaller commands")
        part_seeds = range(lo, hi + 1)
        twice = seeds.intersection(part_seeds)
        if twice:
            raise ConfigError(f"seeds {text!r} names seed {min(twice)} twice")
        seeds.update(part_seeds)
    return sorted(seeds)


def _check_writable_file(path: Path, flag: str) -> None:
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a folder; name a file")
    check_writable_dir(path.parent if str(path.parent) else Path("."), f"{flag}'s folder")


def _config_text(path: Path) -> str:
    """A recorded ``config.json``: the file, or where ``<set>/seed_<n>`` is packed, its copy in the
    set's ``runs.parquet`` (``results/cartpole/faithful/seed_0/config.json`` names either)."""
    from keras_rl.runs.packed import PACKED
    from keras_rl.runs.run_set import SEED_FOLDER, RunSet

    seed_dir = path.parent if path.name == "config.json" else path
    if not path.is_file() and SEED_FOLDER.fullmatch(seed_dir.name) and (seed_dir.parent / PACKED).is_file():
        try:
            run = RunSet.seed_at(seed_dir)
        except KerasRLError:
            pass
        else:
            return json.dumps(run.config())
    return path.read_text()


def _recorded_config(experiment, args: argparse.Namespace):
    """``--config``: the config a run folder recorded, and the engine that made that run (None
    for a config.json with no run beside it); the options it settles must not be given too."""
    import json

    given = [f"--{name.replace('_', '-')}" for name in ("variant", "framework") if getattr(args, name) is not None]
    if args.matched_init:
        given.append("--matched-init")
    if given:
        raise ConfigError(f"--config gives the variant and framework; drop {', '.join(given)}")
    path = args.config if args.config.name == "config.json" or not args.config.is_dir() else args.config / "config.json"
    try:
        values = json.loads(_config_text(path))
    except OSError as exc:
        raise ConfigError(f"--config {path}: cannot read it ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--config {path} is not JSON ({exc})") from None
    if not isinstance(values, dict) or values.get("experiment") != experiment.name:
        theirs = values.get("experiment") if isinstance(values, dict) else None
        raise ConfigError(f"--config {path} is a config of {theirs!r}, not of {experiment.name}")
    import dataclasses

    cls = experiment.config_cls
    lacking = sorted({f.name for f in dataclasses.fields(cls)} - set(cls.upgrade(values)))
    if lacking:
        raise ConfigError(
            f"--config {path} lacks field(s) {', '.join(lacking)}: a recorded config.json names every "
            "field, so none is filled in silently; add them, or use --variant and --set"
        )
    from keras_rl.runs.lifecycle import recorded_engine

    return cls.from_dict(values), recorded_engine(path.parent)
