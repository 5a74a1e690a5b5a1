"""The version matrix's cells: what each asks pip for, and the pip command that installs it. Read
by ``noxfile.py`` (which runs them) and by the tests; it imports neither nox nor the project.
"""

from __future__ import annotations

import os
import subprocess

FACTORS = ("tensorflow", "keras", "gymnasium", "numpy", "torch")
REFERENCE: dict[str, str | None] = {
    "tensorflow": "2.21.0",
    "keras": "3.15.1",
    "gymnasium": "1.4.0",
    "numpy": "2.4.6",
    "torch": "2.13.0",
}
PINNED_TORCH = "2.13.0"  # setup.cfg's torch extra: the CPU wheel
STEPS = ("versions", "tests", "envs", "replay", "probe", "check", "speed")
"""``compat_cell.py``'s steps, in order, each a ``<step>.json`` in the cell's folder as it finishes."""

# cell -> the version of each factor it asks for (None: pip resolves it)
CELLS: dict[str, dict[str, str | None]] = {
    "reference": REFERENCE,
    # TensorFlow on its own, each with the Keras 3 and NumPy that pip resolves for it
    "tf2.20.0": {**REFERENCE, "tensorflow": "2.20.0", "keras": None, "numpy": None},
    "tf2.19.1": {**REFERENCE, "tensorflow": "2.19.1", "keras": None, "numpy": None},
    # Keras on its own, on TensorFlow 2.21
    "keras3.14.1": {**REFERENCE, "keras": "3.14.1"},
    "keras3.13.2": {**REFERENCE, "keras": "3.13.2"},
    # Gymnasium on its own
    "gymnasium1.3.0": {**REFERENCE, "gymnasium": "1.3.0"},
    "gymnasium1.2.3": {**REFERENCE, "gymnasium": "1.2.3"},
    # TensorFlow's release candidate as the index serves it (it brings keras-nightly in place of keras)
    "tf2.22.0rc0": {**REFERENCE, "tensorflow": "2.22.0rc0", "keras": None, "numpy": None},
    # the nightlies of 2026-10-26/27, the newest on the index (DISTRIBUTIONS names their packages)
    "nightly": {**REFERENCE, "tensorflow": "2.23.0.dev20261026", "keras": "3.16.0.dev2026102704", "numpy": None},
    # NumPy 1.26 against the reference's 2.x, and 2.5 (released, but not on this machine's index:
    # the cell records its failed install)
    "numpy1.26.4": {**REFERENCE, "numpy": "1.26.4"},
    "numpy2.5": {**REFERENCE, "numpy": "2.5.*"},
    # PyTorch on its own (a CUDA build, run on the CPU)
    "torch2.14.1": {**REFERENCE, "torch": "2.14.1"},
    # combined: the oldest of everything, and the newest pip resolves today (nothing pinned; the
    # machine's cap on torch lifted, so PyTorch is the newest release)
    "oldest": {"tensorflow": "2.19.1", "keras": "3.13.0", "gymnasium": "1.2.0", "numpy": "1.26.4", "torch": "2.13.0"},
    "newest": {factor: None for factor in FACTORS},
}
# cell -> factor -> the package it installs from, where not the factor's own name
DISTRIBUTIONS: dict[str, dict[str, str]] = {"nightly": {"tensorflow": "tf-nightly", "keras": "keras-nightly"}}
# cell -> the factors it installs over the project's own install, past setup.cfg's ranges (which
# stop below TensorFlow 2.22 and Keras 3.16), as a user upgrading would: pip installs them and
# warns of the conflict. A factor taken from another package is uninstalled first.
OVER: dict[str, tuple[str, ...]] = {"tf2.22.0rc0": ("tensorflow",), "nightly": ("tensorflow", "keras")}


def install_commands(
    name: str, spec: dict[str, str | None], python: str
) -> tuple[list[list[str]], dict[str, str] | None]:
    """The cell's pip commands, run in order, and the environment they run in (None: this one).
    The torch extra pins the CPU wheel; a cell with another PyTorch installs the project without
    it."""
    torch = spec.get("torch", PINNED_TORCH)
    extras = "test,torch" if torch == PINNED_TORCH else "test"
    names, over = DISTRIBUTIONS.get(name, {}), OVER.get(name, ())

    def pins(factors) -> list[str]:
        return [
            f"{names.get(factor, factor)}=={spec[factor]}"
            for factor in factors
            if spec[factor] is not None and not (factor == "torch" and torch == PINNED_TORCH)
        ]

    pip = [python, "-m", "pip"]
    commands = [[*pip, "install", "--quiet", "-e", f".[{extras}]", *pins(f for f in spec if f not in over)]]
    if torch is None:
        commands[0].append("torch")
    if over:
        if replaced := [factor for factor in over if factor in names]:
            commands.append([*pip, "uninstall", "--quiet", "--yes", *replaced])
        commands.append([*pip, "install", "--quiet", *pins(over)])
    return commands, None if torch == PINNED_TORCH else lift_torch_cap(python)


def lift_torch_cap(python: str) -> dict[str, str]:
    """An environment in which pip reads none of its configuration files but is given their
    settings, all but ``constraint``, as variables: this machine caps torch at 2.14.1 with a
    constraint in its site-wide pip configuration, and only ``PIP_CONFIG_FILE=/dev/null`` stops
    pip from reading it (an empty ``PIP_CONSTRAINT`` does not)."""
    listed = subprocess.run([python, "-m", "pip", "config", "list"], capture_output=True, text=True, check=True)
    env = {**os.environ, "PIP_CONFIG_FILE": os.devnull}
    for line in listed.stdout.splitlines():
        key, _, value = line.partition("=")
        section, _, option = key.rpartition(".")
        if option == "constraint" or not section.endswith("global") and not section.endswith("install"):
            continue
        variable = "PIP_" + option.upper().replace("-", "_")
        env.setdefault(variable, value.strip("'\""))
    return env
