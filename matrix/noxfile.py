"""The version matrix: one nox session per cell, each a fresh virtualenv holding one combination
of TensorFlow, Keras, Gymnasium, NumPy and PyTorch (``make matrix`` runs them all, the reference first).

    .venv/bin/nox -f matrix/noxfile.py                          # every cell, then the table
    .venv/bin/nox -f matrix/noxfile.py -s cell-tf2.19.1 table   # one cell, then the table
    .venv/bin/nox -f matrix/noxfile.py -l                       # the cells
    .venv/bin/nox -f matrix/noxfile.py -s cell-reference -- --redo check   # one step again
    .venv/bin/nox -f matrix/noxfile.py -s cell-nightly -- --only versions --only check   # its verdict first

The cell scripts sit beside this file (``matrix/``); every session runs from the repository
root, whatever folder nox starts in.

Each cell varies one factor from the reference (the versions that made ``results/``, pinned in
``constraints.txt``), but for the combined cells ``oldest`` and ``newest``. A factor left out of a
cell's spec (``None``) is whatever pip resolves beside the others. Everything else (Ray, SciPy,
...) is resolved by pip in every cell, and recorded in the cell's ``pip-freeze.txt``. PyTorch is
2.13.0, the CPU wheel the project pins, but in the PyTorch cells and ``newest``: any other release
is a CUDA build of several GB, and this machine's pip caps torch at 2.14.1 in a file of its own
configuration, which such a cell's install lifts for itself. The nightly cell takes TensorFlow
and Keras from their nightly packages. The cells, and the pip command of each, are in ``cells.py``.

A cell writes ``results/compat/<cell>/``: ``install.json`` here, then the steps of
``matrix/compat_cell.py`` (tests, bit-exact replay of each post's committed seed 0, the
twin check against the committed baselines in Keras and PyTorch, the speed ratio to the reference
cell). A cell
interrupted midway resumes at its first unfinished step. ``nox -s table`` regenerates
``results/compat/README.md`` and the README's short table from the committed cell folders.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import nox

ROOT = Path(__file__).resolve().parents[1]
COMPAT = ROOT / "results" / "compat"
sys.path.insert(0, str(Path(__file__).resolve().parent))  # matrix/cells.py, beside this file
from cells import CELLS, install_commands  # noqa: E402

nox.options.sessions = [f"cell-{name}" for name in CELLS] + ["table"]
nox.options.reuse_venv = "yes"  # a cell resumes at its first unfinished step, in the venv it made


def _cell(name: str, spec: dict[str, str | None]):
    def session(session: nox.Session) -> None:
        out = COMPAT / name
        out.mkdir(parents=True, exist_ok=True)
        session.chdir(ROOT)
        python = str(Path(session.bin) / "python")
        reference_python = str(Path(session.virtualenv.location).parent / "cell-reference" / "bin" / "python")
        install, env = install_commands(name, spec, python)
        marker = out / "install.json"
        if not marker.exists() or json.loads(marker.read_text())["exit_code"] != 0:
            session.log(" && ".join(" ".join(command[2:]) for command in install))
            start = time.perf_counter()
            done = _pip(install, env)
            record = {
                "spec": spec,
                "command": " && ".join("pip " + " ".join(command[3:]) for command in install),
                "torch_cap_lifted": env is not None,
                "exit_code": done.returncode,
                "seconds": round(time.perf_counter() - start, 1),
                "venv_mb": _megabytes(Path(session.virtualenv.location)),
                "error": done.stderr[-4000:] if done.returncode else None,
            }
            _write_json(marker, record)
            if done.returncode != 0:
                session.error(f"{name}: the install failed (results/compat/{name}/install.json)")
        elif subprocess.run([python, "-c", "import keras_rl, torch"], cwd=ROOT, capture_output=True).returncode:
            # the cell's folder is committed but this machine's virtualenv is new (a fresh machine,
            # or a step added since the cell ran): install again, keeping the first install's record
            session.log(f"{name}: a new virtualenv for a cell run before; installing (install.json kept)")
            done = _pip(install, env)
            if done.returncode != 0:
                session.error(f"{name}: the install failed:\n{done.stderr[-4000:]}")
        session.run(
            python,
            "matrix/compat_cell.py",
            "--cell",
            name,
            "--spec",
            json.dumps(spec),
            "--reference-python",
            reference_python,
            *session.posargs,  # e.g. -- --redo check
            external=True,
        )

    session.__name__ = f"cell_{name}"
    session.__doc__ = ", ".join(f"{f} {v or 'as resolved'}" for f, v in spec.items())
    return session


def _pip(commands: list[list[str]], env: dict[str, str] | None) -> subprocess.CompletedProcess:
    """Run a cell's pip commands in order, stopping at the first that fails (its result)."""
    for command in commands:
        done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, env=env)
        if done.returncode != 0:
            break
    return done


def _megabytes(folder: Path) -> int:
    """What a cell's virtualenv holds on disk (a CUDA build of PyTorch is several GB of it)."""
    return round(sum(f.stat().st_size for f in folder.rglob("*") if f.is_file() and not f.is_symlink()) / 2**20)


def _write_json(path: Path, payload: dict) -> None:
    tmp = path.with_name(f".tmp-{path.name}")
    tmp.write_text(json.dumps(payload, indent=2) + "\n")
    tmp.replace(path)


for _name, _spec in CELLS.items():
    nox.session(name=f"cell-{_name}")(_cell(_name, _spec))


@nox.session(python=False)
def table(session: nox.Session) -> None:
    """results/compat/README.md and the README's short table, from the committed cell folders."""
    session.chdir(ROOT)
    session.run(sys.executable, "-m", "maintainers", "tables", "compat", "--write", external=True)
