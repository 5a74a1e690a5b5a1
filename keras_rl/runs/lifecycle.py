"""How each seed folder of a command starts: new, cleared, resumed, kept (``reproduce``)."""

from __future__ import annotations

import sys
from pathlib import Path

from keras_rl.errors import ConfigError, argument


def _seed_folder_state(seed_dir: Path) -> tuple[str, str] | None:
    """None for a folder that does not exist or is empty; else (its summary's status, or
    "unreadable", and what it holds, for messages)."""
    if not seed_dir.is_dir() or not any(seed_dir.iterdir()):
        return None
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.summary import RunSummary

    try:
        s = RunSummary.read(seed_dir)
        return s.status, f"a {s.status} run, {s.episodes_run} episodes"
    except RunFolderError:
        return "unreadable", "files of an earlier run"


def _start_modes(seed_dirs: list[Path], overwrite: bool, resume: bool, episodes: int | None = None) -> list[str]:
    """How each seed folder starts (new, overwrite, resume, keep), or a ConfigError before
    anything runs. With ``--resume``, a completed run asked for more episodes than it played
    is extended from its final checkpoint (``resume``); one that has none is refused."""
    if overwrite and resume:
        raise ConfigError(f"{argument('overwrite')} and {argument('resume')} contradict each other; pick one")
    from keras_rl.runs.checkpoint import CHECKPOINT
    from keras_rl.runs.reuse import joins_its_stopped_batch

    modes, occupied = [], []
    for seed_dir in seed_dirs:
        state = _seed_folder_state(seed_dir)
        status, held = state if state is not None else (None, None)
        if resume:
            extend = status == "completed" and episodes is not None and _extendable(seed_dir, episodes)
            # a finished seed of a stopped batch resumes with it
            rejoins = status == "completed" and joins_its_stopped_batch(seed_dir)
            if (seed_dir / CHECKPOINT).is_file() and (status != "completed" or extend or rejoins):
                modes.append("resume")
            elif held is None:
                modes.append("new")  # nothing to resume: start it
            elif extend:
                raise ConfigError(
                    f"{argument('resume')} {argument('episodes', episodes)}: {seed_dir} completed its "
                    f"budget but holds no final "
                    f"{CHECKPOINT} (a seed-batched run keeps none), so it cannot be extended; "
                    f"{argument('overwrite')} reruns it"
                )
            elif status == "completed":
                modes.append("keep")  # finishing an interrupted set: its finished seeds stay as they are
            else:
                raise ConfigError(
                    f"{argument('resume')}: {seed_dir} holds {held} but no {CHECKPOINT}, so it cannot be "
                    f"continued (use {argument('overwrite')} to run it again)"
                )
        elif held is not None and not overwrite:
            occupied.append(f"{seed_dir} ({held})")
        else:
            modes.append("overwrite" if held is not None else "new")
    if occupied:
        committed = any("results" in Path(d).parts for d in seed_dirs)
        raise ConfigError(
            "these seed folders already hold a run and are left untouched: "
            + "; ".join(occupied[:5])
            + (f" and {len(occupied) - 5} more" if len(occupied) > 5 else "")
            + (
                f". They are results: pass {argument('out')} for a folder of your own "
                f"(for example {argument('out', 'runs/mine')})"
                if committed
                else f". Pass {argument('overwrite')} to replace them, {argument('resume')} to continue "
                f"unfinished ones, or {argument('out')} for another folder"
            )
        )
    return modes


def _extendable(seed_dir: Path, episodes: int) -> bool:
    """A completed run that played its whole budget, fewer episodes than ``episodes`` (one
    stopped at its threshold stops there again in a straight run of any budget: it is kept)."""
    import json

    from keras_rl.runs.summary import RunSummary

    summary = RunSummary.read(seed_dir)
    stop = json.loads((seed_dir / "config.json").read_text()).get("stop_at_threshold", True)
    stopped_early = summary.reached_at_episode is not None and stop
    return summary.episodes_run == summary.budget_episodes < episodes and not stopped_early


def check_keepable(base, seeds_and_dirs: list) -> None:
    """A ConfigError for a completed seed ``--resume`` would keep that another config or code
    version made, which must not join the set unnoticed (``plan`` and the run both ask)."""
    from keras_rl.errors import RunFolderError
    from keras_rl.runs.provenance import code_version
    from keras_rl.runs.reuse import check_reusable

    if not seeds_and_dirs:
        return
    from keras_rl.runs.run_set import RunSet

    version = code_version()
    for seed, seed_dir in seeds_and_dirs:
        try:
            check_reusable(seed_dir, base.replace(seed=seed), version)
        except RunFolderError as exc:
            raise ConfigError(
                f"{argument('resume')} keeps completed seeds, but {str(exc).split('; ')[0]}; "
                f"use {argument('overwrite')} to run it again, or {argument('out')} for another folder"
            ) from None
        # its rows as the set's summary will read them: a damaged episodes.csv is named now, by
        # the dry run too, not after the other seeds have trained (issue 54 item 18)
        run = RunSet.seed_at(seed_dir)
        run.rows(expected_rows=run.summary().rows_expected)


def _kept_runs(base, seeds_and_dirs: list) -> list:
    """The summaries of the completed seeds ``--resume`` keeps (``check_keepable`` first)."""
    from keras_rl.runs.summary import RunSummary

    check_keepable(base, seeds_and_dirs)
    kept = []
    for seed, seed_dir in seeds_and_dirs:
        print(f"seed {seed}: already completed in {seed_dir}, kept", file=sys.stderr)
        kept.append(RunSummary.read(seed_dir))
    return kept


def recorded_engine(seed_dir: Path) -> str | None:
    """The engine that made the run at ``seed_dir``, as its summary records it (the folder's, or
    where the set is packed, its ``runs.parquet``'s) or, where a kill left no summary, its
    checkpoint; None where there is no run. A run that names no engine was made on the
    Gymnasium loop, the only engine before the others came."""
    from keras_rl.errors import KerasRLError
    from keras_rl.runs.checkpoint import CHECKPOINT, read_checkpoint
    from keras_rl.runs.run_set import SEED_FOLDER, RunSet

    seed_dir = Path(seed_dir)
    if SEED_FOLDER.fullmatch(seed_dir.name) and ((seed_dir / "summary.json").is_file() or not seed_dir.is_dir()):
        try:
            record = RunSet.seed_at(seed_dir).summary_record()
        except (KerasRLError, OSError, ValueError):
            record = None
        if isinstance(record, dict):
            return _summary_engine(record)
    if (seed_dir / CHECKPOINT).is_file():
        try:
            return str(read_checkpoint(seed_dir).get("engine", "gymnasium"))
        except KerasRLError:
            return None
    return None


def _summary_engine(record: dict) -> str:
    """The engine a summary record names (the Gymnasium loop where it names none)."""
    return str((record.get("provenance") or {}).get("engine", "gymnasium"))


def set_engine(folder: Path, leaving: list[Path] | tuple[Path, ...] = ()) -> str | None:
    """The engine of the runs in the set ``folder`` (its seed folders and its packed seeds), but
    those in ``leaving`` (to be overwritten); None where it holds none. A set of two engines is a
    ConfigError that names them: what continues it must name its engine."""
    from keras_rl.runs.run_set import RunSet

    folder = Path(folder)
    if not folder.is_dir():
        return None
    in_set = RunSet(folder)
    held: dict[str, list[Path]] = {}
    for seed_dir in in_set.seed_dirs():
        engine = None if seed_dir in leaving else recorded_engine(seed_dir)
        if engine is not None:
            held.setdefault(engine, []).append(seed_dir)
    packed = in_set.packed()  # its records read once, not a seed at a time
    for s in packed.seeds if packed is not None else []:
        seed_dir = folder / f"seed_{s}"
        if seed_dir not in leaving and not seed_dir.is_dir():
            held.setdefault(_summary_engine(packed.summary_record(s)), []).append(seed_dir)
    if len(held) > 1:
        found = "; ".join(f"the {e} engine: {', '.join(d.name for d in dirs[:3])}" for e, dirs in sorted(held.items()))
        raise ConfigError(
            f"{folder} holds runs of more than one engine ({found}), so which to continue on is not "
            f"known; name it with {argument('engine')}"
        )
    return next(iter(held), None)


UNRECORDED_ENGINE = "gymnasium"
"""The Gymnasium loop's name (``train/engine.GymnasiumEngine``, ``train/loop.py``), kept here, below
both: the engine of a run or checkpoint that recorded none (every one made before the engine seam),
and of a job built without one. Not what a user gets by default: that is ``auto``
(``dispatch.options.AUTO``, ``study.choose_engine``), declared once in ``RunOptions``."""


def check_checkpoint_engine(out_dir: Path, state: dict, engine: str) -> None:
    """A RunFolderError where the checkpoint ``state`` of ``out_dir`` was written by another
    engine than the one asked to resume it (every engine's rule, and ``plan``'s)."""
    from keras_rl.errors import RunFolderError

    wrote = state.get("engine", UNRECORDED_ENGINE)
    if wrote != engine:
        raise RunFolderError(
            f"{out_dir}'s checkpoint was written by the {wrote} engine; resume it with {argument('engine', wrote)}, "
            f"or pass {argument('overwrite')} to start again"
        )


def check_resumable(seeds_and_dirs: list, engine: str) -> None:
    """What resuming these seed folders would refuse, found before anything runs: a checkpoint
    of another engine, of a batch this command does not resume whole, or unreadable."""
    from keras_rl.runs.checkpoint import checkpoint_batch, read_batch_checkpoints

    for _, seed_dir in seeds_and_dirs:
        batch = checkpoint_batch(seed_dir)
        if len(batch) > 1:  # a batch's checkpoints are checked together when it resumes
            continue
        (state,) = read_batch_checkpoints([seed_dir], batch)
        check_checkpoint_engine(seed_dir, state, engine)


def check_resume_config(out_dir: Path, wanted: dict, theirs: dict, played: int) -> None:
    """A checkpoint in ``out_dir`` (made with config ``theirs``, ``played`` episodes in) may be
    resumed by a command asking for config ``wanted``: the same fields but the budget, which
    may only grow. A ConfigError that names the first field otherwise (every engine's rule)."""
    import json

    wanted, theirs = json.loads(json.dumps(wanted)), json.loads(json.dumps(theirs))
    if wanted["episodes"] < played:
        raise ConfigError(
            f"{argument('resume')}: {out_dir} has played {played} episodes, more than {argument('episodes')} "
            f"{wanted['episodes']}; a resumed run keeps what it played (ask for at least {played})"
        )
    differing = sorted(k for k in wanted if k != "episodes" and theirs.get(k) != wanted[k])
    if differing:
        k = differing[0]
        raise ConfigError(
            f"{argument('resume')}: the checkpoint in {out_dir} was made with {k}={theirs.get(k)!r}, "
            f"this command asks for {wanted[k]!r}; resume with the same options"
        )
