"""Committed seeds as run folders, for the tests that need a folder on disk.

The committed sets are packed (``results/<set>/runs.parquet``). ``committed_seed("pendulum/faithful/seed_0")``
writes that seed out once per test process (``SeedRun.extract``: ``config.json`` and
``summary.json`` as committed, ``episodes.csv`` with wall time to the millisecond) and returns
the folder; a test that changes what it is given copies it first.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

from keras_rl.runs.run_set import RunSet

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
_made: dict[str, Path] = {}
_scratch: Path | None = None


def committed_seed(seed_path: str) -> Path:
    """``results/<set>/seed_<n>`` as a folder (read-only by convention: copy before changing it)."""
    global _scratch
    if seed_path not in _made:
        if _scratch is None:
            _scratch = Path(tempfile.mkdtemp(prefix="keras-rl-committed-"))
            atexit.register(shutil.rmtree, _scratch, True)
        _made[seed_path] = RunSet.seed_at(RESULTS / seed_path).extract(_scratch / seed_path)
    return _made[seed_path]


def copy_seeds(run_set: Path, dest: Path, keep=lambda seed: True) -> Path:
    """The seeds of ``run_set`` (packed or not) that ``keep`` keeps, as run folders under ``dest``."""
    source = RunSet(run_set)
    for run in source.runs():
        if keep(run.seed):
            run.extract(Path(dest) / f"seed_{run.seed}")
    return Path(dest)


def same_to_rounding(got, want, rel: float = 1e-12) -> bool:
    """Equal JSON values, floats within ``rel`` of each other (a few bits), all else exactly."""
    import math

    if isinstance(want, dict):
        return (
            isinstance(got, dict) and got.keys() == want.keys() and all(same_to_rounding(got[k], want[k]) for k in want)
        )
    if isinstance(want, list):
        return isinstance(got, list) and len(got) == len(want) and all(map(same_to_rounding, got, want))
    if isinstance(want, float) and isinstance(got, float):
        return math.isclose(got, want, rel_tol=rel, abs_tol=0.0)
    return type(got) is type(want) and got == want
