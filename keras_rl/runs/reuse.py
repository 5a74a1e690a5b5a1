"""When a run folder can be reused instead of run again (``compare``, ``sweep``)."""

from __future__ import annotations

import json
from pathlib import Path

from keras_rl.errors import RunFolderError, argument
from keras_rl.runs.checkpoint import CHECKPOINT, checkpoint_batch
from keras_rl.runs.provenance import code_version_of
from keras_rl.runs.summary import RunSummary

OUTCOMES = ("completed", "non_finite_loss")
"""Statuses that are what a config and seed do, so a rerun would only repeat them: a loss
that turns NaN is the run's result (post 001 with the learning phase on, at update 1), not
an accident like an interruption or a failed write."""


def check_reusable(seed_dir: Path, expected, code_version: str | None) -> str | None:
    """None if ``seed_dir`` holds a finished run of config ``expected`` (``OUTCOMES``); else why
    it cannot be reused.

    Raises RunFolderError for a run of a *different* config or code version (``code_version``
    None: any code version, for a command that only reports the runs, ``compare --reuse-only``). A folder made
    before a field existed (or under an older field name) is read through the config's
    ``from_dict``, which fills today's defaults and maps renamed fields: it matches only
    if the default is wanted.
    """
    packed = packed_run(seed_dir)
    if packed is not None and not seed_dir.exists():
        return _check_made(packed.where, packed.summary(), packed.config(), expected, code_version)
    if not (seed_dir / "summary.json").is_file():
        if seed_dir.is_dir() and any(seed_dir.iterdir()):  # not a run this project made: never removed unasked
            held = ", ".join(sorted(p.name for p in seed_dir.iterdir())[:5])
            raise RunFolderError(
                f"{seed_dir} holds files ({held}) but no summary.json, so it is not a run that can be "
                f"reused and it is left as it is; move what you keep there and pass {argument('rerun')} to "
                "replace it"
            )
        return "missing"
    summary = RunSummary.read(seed_dir)
    try:
        values = json.loads((seed_dir / "config.json").read_text())
    except (OSError, ValueError) as exc:
        raise RunFolderError(f"{seed_dir} is corrupt ({exc}); delete it or pass {argument('rerun')}") from None
    why = _check_made(str(seed_dir), summary, values, expected, code_version)
    if why is None and joins_its_stopped_batch(seed_dir):
        return JOINS_BATCH
    return why


def packed_run(seed_dir: Path):
    """The seed ``seed_dir`` is named for, where its set's ``runs.parquet`` holds it (else None)."""
    from keras_rl.runs.packed import PACKED
    from keras_rl.runs.run_set import SEED_FOLDER, RunSet

    if SEED_FOLDER.fullmatch(seed_dir.name) is None or not (seed_dir.parent / PACKED).is_file():
        return None
    try:
        return RunSet.seed_at(seed_dir)
    except RunFolderError:
        return None


def _check_made(where: str, summary: RunSummary, values, expected, code_version: str | None) -> str | None:
    """``check_reusable`` for a run that is there, from its summary and recorded config."""
    made_by = values.get("experiment") if isinstance(values, dict) else None
    if made_by is not None and made_by != expected.experiment:
        raise RunFolderError(
            f"{where} holds a run made by {made_by}, not {expected.experiment}; "
            f"pass {argument('out')} (or {argument('runs')}) for another folder"
        )
    try:
        made_config = type(expected).from_dict(values)
    except (TypeError, ValueError) as exc:
        raise RunFolderError(f"{where} is corrupt ({exc}); delete it or pass {argument('rerun')}") from None
    made, wanted = made_config.to_dict(), expected.to_dict()
    differing = made_config.differs_from(expected)
    if differing:
        which = ", ".join(f"{k}={made.get(k)!r} here, {wanted[k]!r} wanted" for k in differing[:3])
        raise RunFolderError(
            f"{where} was made with a different config ({which}); "
            f"refusing to mix runs: pass {argument('rerun')} to replace it, or {argument('runs')} to use another folder"
        )
    theirs = code_version_of(summary.provenance, summary.versions.get("keras_rl"))
    if code_version is not None and theirs != code_version:  # None: report what is there (--reuse-only)
        raise RunFolderError(
            f"{where} was made by code version {theirs}, this is {code_version}; "
            f"refusing to mix code versions: pass {argument('rerun')} to replace it"
        )
    if summary.status not in OUTCOMES:
        return f"unfinished ({summary.status})"
    return None


def made_by_experiment(seed_dir: Path) -> str | None:
    """The experiment whose run a seed folder holds (its config.json says), or None where it
    cannot say."""
    try:
        values = json.loads((seed_dir / "config.json").read_text())
    except (OSError, ValueError):
        return None
    return values.get("experiment") if isinstance(values, dict) else None


JOINS_BATCH = "finished inside a batch that was stopped (it resumes with its batch)"


def joins_its_stopped_batch(seed_dir: Path) -> bool:
    """A finished seed whose folder still holds its batch's checkpoint: the batch was stopped
    after this seed had finished (a batch that ends removes them), and it resumes whole, this
    seed included, from the stack its checkpoints recorded."""
    return len(checkpoint_batch(seed_dir)) > 1


def start_of(seed_dir: Path, reason: str | None) -> str:
    """How a seed that ``check_reusable`` did not pass (``reason``) starts again: an interrupted
    run of the same config and code version resumes from its checkpoint (with its batch whole,
    as ``reproduce --resume`` would), anything else is run anew."""
    unfinished = reason is not None and (reason.startswith("unfinished") or reason == JOINS_BATCH)
    return "resume" if unfinished and (seed_dir / CHECKPOINT).is_file() else "overwrite"
