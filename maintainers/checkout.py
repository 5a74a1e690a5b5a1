"""The checkout this keras_rl sits in, and its committed ``results/``.

The maintainers' commands (``python -m maintainers calibrate|tables|manifest``, from a checkout)
read and regenerate what the checkout commits; a package installed outside a checkout has no
``results/``, and those commands say so (``results_dir``). Training, ``check`` and the reports
never need it.
"""

from __future__ import annotations

from pathlib import Path

from keras_rl.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


def results_dir() -> Path:
    """``RESULTS``, or a ConfigError (exit 2) naming where it was looked for."""
    if not RESULTS.is_dir():
        raise ConfigError(
            f"no results/ in this checkout ({ROOT}): this command regenerates a checkout's committed "
            "results; run it from a checkout of the repository (python -m maintainers ...)"
        )
    return RESULTS
