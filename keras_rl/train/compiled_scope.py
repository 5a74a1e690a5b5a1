"""What the compiled engine runs, known without TensorFlow: the posts, the framework, the envs and
post 001's quirk switches its programs need at their faithful setting. ``reproduce`` and ``check``
refuse a config it cannot run from here, before TensorFlow loads (``train/compiled.py`` runs it)."""

from __future__ import annotations

import json
from pathlib import Path

from keras_rl.errors import argument

ENGINE = "compiled"
ENV_IDS = {"pendulum": "Pendulum-v1", "cartpole": "CartPole-v1", "mountaincar": "MountainCarContinuous-v0"}
"""The posts the compiled engine runs, each with the env it has in TensorFlow (``keras_rl/tf_envs.py``)."""

SWITCHES = {
    "mountaincar": {
        "popping_buffer": (True, "P001-POP", "the ring buffer trains every env step"),
        "episode_returns_as_rewards": (True, "P001-RETURNS", "transitions stored every step can train mid-episode"),
        "exploration": ("none", "P001-NOEXPLORE", "OU noise is drawn per step of an episode of unknown length"),
        "learning_phase_training": (False, "P001-PHASE", "networks in training mode draw noise inside the act"),
    }
}
"""Per post, the switches its programs need at their faithful setting (post 001: an episode acts
with fixed weights only when nothing trains before its end): field -> (value, ledger ID, why)."""


CERTIFIED_FILE = Path(__file__).with_name("certified.json")
"""Package data written from the forest's "compiled engine vs Gymnasium loop" rows by
``python -m maintainers tables forest --write`` (``tests/test_results_docs.py`` regenerates it)."""
CERTIFIED: dict[tuple[str, str], str] = {
    (post, framework): why
    for key, why in json.loads(CERTIFIED_FILE.read_text()).items()
    for post, framework in [key.split("/")]
}
"""Where the compiled engine is certified, with what says so: the default engine there
(``study.choose_engine``). Read from the forest's verdicts, never written here."""


def refusal(experiment: str, config) -> str | None:
    """Why the compiled engine cannot run ``config`` of ``experiment`` (every reason at once), or None."""
    if experiment not in ENV_IDS:
        loop = argument("engine", "gymnasium")
        return f"the compiled engine runs {' and '.join(ENV_IDS)} so far; run {experiment} with {loop}"
    reasons = []
    if config.framework != "keras":
        reasons.append(f"it runs the Keras learner; the PyTorch side runs with {argument('engine', 'gymnasium')}")
    if config.env_id != ENV_IDS[experiment]:
        reasons.append(f"it has {ENV_IDS[experiment]} in TensorFlow, not env_id {config.env_id!r}")
    off = [
        f"{field}={getattr(config, field)!r} ({quirk} wants {wanted!r}: {why})"
        for field, (wanted, quirk, why) in SWITCHES.get(experiment, {}).items()
        if getattr(config, field) != wanted
    ]
    if off:
        shown = "; ".join(off)
        reasons.append(
            f"it runs {experiment} with its faithful switches only, not {shown}; "
            f"run it with {argument('engine', 'gymnasium')}"
        )
    return "; ".join(reasons) or None
