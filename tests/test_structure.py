"""The package's shape, checked: no import cycles (lazy imports included), torch only under
``keras_rl/torch/``, no plotting reachable from training code, one learner table, and
``config.json`` files of every committed run still loading under today's field names."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

from keras_rl.runs.run_set import RunSet

PACKAGE = Path(__file__).resolve().parent.parent / "keras_rl"
RESULTS = PACKAGE.parent / "results"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def imports_of(path: Path) -> set[str]:
    """Every module named by an import anywhere in the file (function bodies included)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def internal_edges(name: str) -> set[str]:
    """The keras_rl modules ``name`` imports (each imported module's parent packages too:
    importing a submodule runs its package's ``__init__``)."""
    edges = set()
    for target in imports_of(MODULES[name]):
        parts = target.split(".")
        for i in range(1, len(parts) + 1):
            candidate = ".".join(parts[:i])
            if candidate in MODULES and candidate != name:
                edges.add(candidate)
    return edges


GRAPH = {name: internal_edges(name) for name in MODULES}


def reachable(start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for nxt in GRAPH[todo.pop()]:
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def test_the_walk_sees_lazy_imports():
    # reproduce imports the registry inside functions only; the graph must still hold the edge
    assert "keras_rl.registry" in GRAPH["keras_rl.commands.reproduce"]


def test_no_import_cycles_among_keras_rl_modules():
    cycles = []
    for name in GRAPH:
        if name in reachable(name):
            path = [name]  # name one cycle through it, for the message
            while True:
                nxt = next(n for n in GRAPH[path[-1]] if name in reachable(n) or n == name)
                path.append(nxt)
                if nxt == name:
                    break
            cycles.append(" -> ".join(path))
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_only_the_torch_folder_imports_torch():
    offenders = sorted(
        name
        for name, path in MODULES.items()
        if not name.startswith("keras_rl.torch")
        and any(t == "torch" or t.startswith("torch.") for t in imports_of(path))
    )
    assert offenders == []


def test_only_the_command_line_imports_argparse():
    """The library takes typed objects; argparse's flags live in ``cli.py`` and ``commands/`` (issue 71)."""
    offenders = sorted(
        name
        for name, path in MODULES.items()
        if not (name == "keras_rl.cli" or name.startswith("keras_rl.commands"))
        and any(t == "argparse" or t.startswith("argparse.") for t in imports_of(path))
    )
    assert offenders == []


def test_keras_learners_never_import_the_torch_side():
    learners = [n for n in MODULES if n.startswith("keras_rl.learners")]
    assert learners and not [n for n in learners if any(m.startswith("keras_rl.torch") for m in reachable(n))]


@pytest.mark.parametrize(
    "prefix",
    [
        "keras_rl.learners",
        "keras_rl.agents",
        "keras_rl.posts",
        "keras_rl.torch",
        "keras_rl.train.loop",
        "keras_rl.dispatch.jobs",  # what every Ray worker loads: the dispatcher and its backends
        "keras_rl.dispatch.ray_backend",
        "keras_rl.dispatch.backends",
        "keras_rl.registry",
    ],
)
def test_training_code_never_reaches_plotting_or_reports(prefix):
    for name in (n for n in MODULES if n.startswith(prefix)):
        bad = sorted(m for m in reachable(name) | {name} if m.startswith("keras_rl.report"))
        bad += sorted(t for m in reachable(name) | {name} for t in imports_of(MODULES[m]) if t.startswith("matplotlib"))
        assert not bad, f"{name} reaches {bad}"


def test_reports_train_nothing():
    """``report/`` reads run folders; making runs is ``runs/``' job (``dispatch/compare_runs.py``
    for compare), so no report reaches the dispatcher or the episode loop."""
    for name in (n for n in MODULES if n.startswith("keras_rl.report")):
        bad = sorted(m for m in reachable(name) if m in ("keras_rl.dispatch.jobs", "keras_rl.train.loop"))
        assert not bad, f"{name} reaches {bad}"


def test_one_learner_table_covers_every_experiment_and_imports_nothing_heavy():
    from keras_rl.learners.table import IMPLEMENTATIONS, frameworks
    from keras_rl.registry import EXPERIMENTS

    assert set(EXPERIMENTS) == {name for name, _ in IMPLEMENTATIONS}
    for name in EXPERIMENTS:
        assert frameworks(name) == ("keras", "torch")
    table_imports = imports_of(MODULES["keras_rl.learners.table"])
    assert {t.split(".")[0] for t in table_imports} <= {
        "__future__",
        "importlib",
        "dataclasses",
        "typing",
        "collections",
        "keras_rl",
    }
    assert {t for t in table_imports if t.startswith("keras_rl")} <= {
        "keras_rl.errors",
        "keras_rl.errors.ConfigError",
        "keras_rl.errors.argument",
    }


COMMITTED_SETS = sorted(s.folder for s in RunSet.find(RESULTS))


def test_there_are_committed_configs_to_check():
    assert len(COMMITTED_SETS) > 90


def distinct_configs(folder) -> list[dict]:
    """Each distinct config a set's seeds recorded (the seed aside), as written."""
    seen: dict[str, dict] = {}
    for values in RunSet(folder).configs():
        seen.setdefault(json.dumps({**values, "seed": None}), values)
    return list(seen.values())


@pytest.mark.parametrize("folder", COMMITTED_SETS, ids=lambda p: str(p.relative_to(RESULTS)))
def test_committed_configs_load_under_todays_field_names(folder):
    for values in distinct_configs(folder):
        check_config_loads(values)


def check_config_loads(values: dict) -> None:
    from keras_rl.registry import get_experiment

    config = get_experiment(values["experiment"]).config_cls.from_dict(values)
    new = config.to_dict()
    for old, new_names in {
        "hidden_units": ("actor_hidden_units", "critic_hidden_units", "q_hidden_units"),
        "actor_hidden": ("actor_hidden_units",),
        "train_above": ("train_start",),
        "ou_sigma": ("noise_sigma",),
        "ou_theta": ("noise_theta",),
        "ou_dt": ("noise_dt",),
        "lr": ("q_lr",),
    }.items():
        if old in values:
            assert [tuple(new[n]) if isinstance(new[n], tuple) else new[n] for n in new_names if n in new] and all(
                (tuple(new[n]) if isinstance(new[n], tuple) else new[n])
                == (tuple(values[old]) if isinstance(values[old], list) else values[old])
                for n in new_names
                if n in new
            )
    if "critic_hidden" in values:
        assert new["critic_hidden_units"] == (values["critic_hidden"],) * 2
    # every value that kept its name is unchanged, and today's dict round-trips
    assert all(new[k] == (tuple(v) if isinstance(v, list) else v) for k, v in values.items() if k in new)
    assert type(config).from_dict(json.loads(json.dumps(new))) == config


def test_a_contradictory_old_and_new_field_is_refused():
    from keras_rl.errors import ConfigError
    from keras_rl.posts.mountaincar import MountainCarDDPGConfig

    with pytest.raises(ConfigError, match="train_above.*contradicts train_start"):
        MountainCarDDPGConfig.from_dict({"train_above": 500, "train_start": 1000})


def test_one_reader_of_seed_folders_and_one_wilson_interval():
    """A set of seed folders is read through ``runs/run_set.RunSet`` and a success rate's Wilson
    interval comes from ``report/stats.wilson_interval``: nowhere else globs ``seed_*`` or asks
    SciPy for a Wilson interval; a generated block goes into a page by ``maintainers/markdown.replace_block``
    alone."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    sources = [
        p for d in ("keras_rl", "maintainers", "reproductions", "tests", "benchmarks") for p in (root / d).rglob("*.py")
    ]
    sources.append(root / "matrix" / "noxfile.py")
    this = Path(__file__).resolve()
    globbers = [p for p in sources if p != this and 'glob("seed_' in p.read_text()]
    wilsons = [p for p in sources if p != this and 'method="wilson"' in p.read_text()]
    assert [p.relative_to(root).as_posix() for p in globbers] == ["keras_rl/runs/run_set.py"]
    assert [p.relative_to(root).as_posix() for p in wilsons] == ["keras_rl/report/stats.py"]
    splices = [p for p in sources if p != this and "def replace_block" in p.read_text()]
    assert [p.relative_to(root).as_posix() for p in splices] == ["maintainers/markdown.py"]  # one Markdown splice


def test_the_cli_is_a_table_and_each_command_module_stays_small():
    """``cli.py`` is the command table and exit codes (at most 150 lines); each command's module
    under ``keras_rl/commands/`` at most 300: a command that grows past it has a concept to
    move to its own home (``runs/``, ``report/``, ``check/``)."""
    package = Path(__file__).resolve().parents[1] / "keras_rl"
    assert len((package / "cli.py").read_text().splitlines()) <= 150
    sizes = {p.name: len(p.read_text().splitlines()) for p in (package / "commands").glob("*.py")}
    assert sizes and all(n <= 300 for n in sizes.values()), sizes


def test_every_command_trains_its_seeds_one_way():
    """``dispatch/backends.train_seeds`` packs, picks the backend and runs; no command picks or
    runs a backend itself (they did, four times, each its own way)."""
    package = Path(__file__).resolve().parents[1] / "keras_rl"
    callers = sorted(
        str(p.relative_to(package))
        for p in package.rglob("*.py")
        if p.name not in ("backends.py", "jobs.py", "ray_backend.py", "pool_backend.py")
        and any(call in p.read_text() for call in ("backend.run(", "backend_for(", "execute("))
    )
    assert callers == [], callers


CHECKOUT_ROOT = "sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's maintainers/"


def test_reproductions_holds_the_ledger_settlements_and_analyses_only():
    """Issue 33: the calibration and the table generators are package commands
    (``python -m maintainers calibrate|tables|manifest``), the matrix scripts sit
    beside ``matrix/noxfile.py``, and no analysis patches ``sys.path`` to reach the package or
    another folder (20 of 21 scripts did). One line is allowed, the same in each: the checkout's
    root, for the analyses that read its plans through ``maintainers/`` (issue 71 item 5 moved
    them out of the installed package; a checkout's scripts, they are run from one)."""
    root = Path(__file__).resolve().parents[1]
    folder = root / "reproductions"
    top = sorted(p.name for p in folder.iterdir() if p.name != "__pycache__")
    assert "FIDELITY.md" in top and "settlements" in top
    scripts = [p for p in folder.glob("*.py")]
    assert sorted(p.name for p in scripts) == sorted(n for n in top if n.endswith(".py"))
    assert all(n.endswith(".py") or n in ("FIDELITY.md", "settlements") for n in top), top
    for path in scripts:
        text = path.read_text()
        patches = [line for line in text.splitlines() if "sys.path" in line]
        assert patches in ([], [CHECKOUT_ROOT]), f"{path.name} patches sys.path: {patches}"
        assert bool(patches) == ("from maintainers" in text), path.name  # only where it reads maintainers/
        assert "calibration.json" not in text and "replace_block" not in text, f"{path.name} generates committed data"
    assert (root / "matrix" / "noxfile.py").is_file() and not (root / "noxfile.py").exists()
    assert {p.name for p in (root / "matrix").glob("compat_*")} >= {"compat_cell.py", "compat_probe.py"}
