"""The version matrix's table, from the committed cell folders ``results/compat/<cell>/``.

    python -m maintainers tables compat            # print it
    python -m maintainers tables compat --write    # results/compat/README.md and the README's short table

The cells are made by ``noxfile.py`` (``make matrix``); each folder holds ``install.json`` and,
once the cell has run, ``cell.json`` (see ``matrix/compat_cell.py``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json

from maintainers.checkout import ROOT
from maintainers.markdown import replace_block

COMPAT = ROOT / "results" / "compat"


def _matrix_cells():
    """``matrix/cells.py`` (the cells, their factors and steps), which imports nothing of ours."""
    spec = importlib.util.spec_from_file_location("matrix_cells", ROOT / "matrix" / "cells.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_CELLS = _matrix_cells()
FACTORS: tuple[str, ...] = _CELLS.FACTORS
STEPS: tuple[str, ...] = _CELLS.STEPS
DEFAULT_TORCH: str = _CELLS.PINNED_TORCH
"""The CPU wheel; cells made before PyTorch was a factor used it."""
POSTS = ("pendulum", "cartpole", "mountaincar")
POST_NAMES = {"pendulum": "000", "cartpole": "003", "mountaincar": "001"}
ENV_IDS = ("Pendulum-v1", "CartPole-v1", "MountainCarContinuous-v0")
"""The envs of ``tests/test_tf_envs.py``, whose parametrised names carry them."""
SHORT_BEGIN, SHORT_END = "<!-- compat-short:begin -->", "<!-- compat-short:end -->"
SPEED_KEYS = {
    "pendulum": "pendulum (post 000)",
    "cartpole": "cartpole (post 003)",
    "mountaincar": "mountaincar (post 001)",
}


def cell_order(name: str) -> tuple[int, str]:
    return ({"reference": 0, "oldest": 2, "newest": 3}.get(name, 1), name)


def load_cells() -> list[tuple[str, dict, dict | None]]:
    """(cell, install.json, cell.json or None) for every cell folder, reference first. A cell
    stopped before its last step is read from the steps it finished (``partial``: the others
    show as not run yet); one that finished none is None."""
    cells = []
    for folder in sorted((p for p in COMPAT.iterdir() if p.is_dir()), key=lambda p: cell_order(p.name)):
        install = folder / "install.json"
        if not install.exists():
            continue
        record = json.loads(install.read_text())
        cell: dict | None = None
        if (folder / "cell.json").exists():
            cell = json.loads((folder / "cell.json").read_text())
        elif steps := {s: json.loads(f.read_text()) for s in STEPS if (f := folder / f"{s}.json").exists()}:
            seconds = sum(step["step_seconds"] for step in steps.values()) + record.get("seconds", 0)
            cell = {**steps, "partial": True, "seconds": seconds}
        cells.append((folder.name, record, cell))
    return cells


def ran(cell: dict, step: str, text) -> str:
    """``text(cell)`` where the cell ran ``step``; otherwise that it has not yet."""
    return text(cell) if step in cell else "not run yet"


def versions_text(install: dict, cell: dict | None) -> list[str]:
    """Each factor's installed version (what the cell asked for, until it has run)."""
    got = cell["versions"]["versions"] if cell and "versions" in cell else {}
    spec = {"torch": DEFAULT_TORCH, **install["spec"]}
    return [got.get(f) or (spec.get(f) or "as resolved") for f in FACTORS]


def install_failure(install: dict) -> str:
    """Why an install failed: pip's last ERROR line, which names what it could not find."""
    errors = [line for line in (install.get("error") or "").splitlines() if line.startswith("ERROR:")]
    reason = errors[-1].removeprefix("ERROR:").strip().replace("|", "/") if errors else "see install.json"
    return f"**failed**: {reason}"


def tests_text(cell: dict) -> str:
    t = cell["tests"]
    failed = t["failures"] + t["errors"]
    return (
        f"{t['passed']} passed" if failed == 0 and t["exit_code"] == 0 else f"**{failed} failed**, {t['passed']} passed"
    )


def short_tests_text(cell: dict) -> str:
    """The README's cell: whether the suite passed, without a count that goes stale as tests
    are added (the full table in results/compat/README.md keeps the count with its commit)."""
    t = cell["tests"]
    failed = t["failures"] + t["errors"]
    return "all passed" if failed == 0 and t["exit_code"] == 0 else f"**{failed} failed**"


def envs_text(cell: dict) -> str:
    """Env parity (``tests/test_tf_envs.py`` in the cell): the TensorFlow envs against the
    cell's Gymnasium. A cell run before the step existed says so."""
    if "envs" not in cell:
        return "not run"
    e = cell["envs"]
    failed = e["failures"] + e["errors"]
    if failed == 0 and e["exit_code"] == 0:
        return f"{e['passed']} passed"
    envs: dict[str, int] = {}
    for name in e["failed"]:
        env = next((env for env in ENV_IDS if env in name), "other")
        envs[env] = envs.get(env, 0) + 1
    return f"**{failed} failed**: " + ", ".join(f"{env} ({n})" for env, n in envs.items()) + " (`envs.log`)"


def replay_text(entry: dict) -> str:
    if entry["bit_exact"]:
        return "bit-exact"
    d = entry["divergence"]
    if d is None:
        return f"**no run** (exit {entry['exit_code']})"
    columns = f" ({', '.join(d['columns'])})" if d["columns"] else ""
    return f"differs from ep {d['first_episode']}{columns}"


def probe_text(cell: dict) -> str:
    """The largest difference, over the posts, of the first numbers from the reference's."""
    probe = cell.get("probe")
    if probe is None:
        return "not run"
    if "error" in probe:
        return "**failed**"
    diffs = [v for post in probe["max_abs_difference"].values() for v in post.values()]
    if any(isinstance(v, str) for v in diffs):
        return "**other shapes**"
    worst = max(diffs)
    return "same bits" if worst == 0 else f"rounding ({worst:.0e})" if worst < 1e-5 else f"**differ ({worst:.1e})**"


def post_verdict(entry: dict) -> str:
    """A post-cell test on its own, at its rule's alpha (the check adjusts over its posts)."""
    return "changed" if entry["p"] < entry.get("alpha", 0.01) else "consistent"


def twin_text(run: dict, post: str) -> str:
    """A post's twin check: the same bits as the baseline, or the paired test's verdict."""
    entry = run["posts"].get(post)
    if entry is None:
        return f"**no verdict** (exit {run['exit_code']})"
    if entry.get("same_bits"):
        return f"same bits ({entry['identical']}/{entry['twins']} twins)"
    twins = f", {entry['twins']} twins" if entry.get("twins") else ""
    verdict = post_verdict(entry)
    return f"{'**changed**' if verdict == 'changed' else verdict} (p={entry['p']:.2g}{twins})"


def changes_text(cell: dict) -> str:
    """What the cell's checks name as differing from their baselines': the first post's report of
    the Keras check, and PyTorch's (whose baseline may have been made under other versions)."""
    check = cell["check"]
    if "sensitive" not in check:
        return "not recorded"
    reports = [check["sensitive"], check.get("torch") or {"posts": {}}]
    envs = [e["environment"] for r in reports for e in list(r["posts"].values())[:1] if e.get("environment")]
    if not envs:
        return "-"
    versions = {lib: v for env in envs for lib, v in env["versions"].items()}
    replaced = {was: now for env in envs for was, now in env.get("replaced", {}).items()}
    names = [f"{lib} {v['was']} -> {v['now']}" for lib, v in sorted(versions.items())]
    names += [f"`{was}` -> `{now}`" for was, now in sorted(replaced.items())]
    return "; ".join(names) or "nothing"


def check_text(cell: dict, post: str) -> str:
    check = cell["check"]
    if "sensitive" in check:
        return twin_text(check["sensitive"], post)
    smoke = check["smoke"]["posts"].get(post)
    if smoke is None:
        return f"**no verdict** (exit {check['smoke']['exit_code']})"
    text = f"smoke: {post_verdict(smoke)} (p={smoke['p']:.2g})"
    if post in check["rerun_at_full_tier"]:
        full = (check["full"] or {}).get("posts", {}).get(post)
        text += f"; full tier: {post_verdict(full)} (p={full['p']:.2g})" if full else "; full tier: no verdict"
    return text


def torch_check_text(cell: dict) -> str:
    torch = cell["check"].get("torch")
    if torch is None:
        return "not run"
    entry = torch["posts"].get("cartpole")
    if entry is None:
        return f"**no verdict** (exit {torch['exit_code']})"
    verdict = post_verdict(entry)
    return f"{'**changed**' if verdict == 'changed' else verdict} (p={entry['p']:.2g})"


def speed_text(cell: dict) -> str:
    ratios = cell["speed"]["cell_over_reference"]
    return " / ".join(f"{ratios[SPEED_KEYS[p]]:.2f}" for p in POSTS)


def table() -> str:
    header = (
        "| cell | TensorFlow | Keras | Gymnasium | NumPy | PyTorch | install | fast tests | env parity | replay 000 "
        "| replay 003 | replay 001 | first numbers | check 000 | check 003 | check 001 | check 003 (PyTorch) "
        "| what the check names as changed | ms / reference (000 / 003 / 001) | cost (min) |"
    )
    steps = header.count("|") - 1 - len(FACTORS) - 2  # the columns after install
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for name, install, cell in load_cells():
        versions = versions_text(install, cell)
        if install["exit_code"] != 0:
            lines.append(f"| {name} | {' | '.join(versions)} | {install_failure(install)} |" + " - |" * steps)
            continue
        if cell is None:
            lines.append(f"| {name} | {' | '.join(versions)} | ok |" + " not run yet |" * steps)
            continue
        replays = [ran(cell, "replay", lambda c, p=p: replay_text(c["replay"]["posts"][p])) for p in POSTS]
        checks = [ran(cell, "check", lambda c, p=p: check_text(c, p)) for p in POSTS]
        cost = f"{cell['seconds'] / 60:.0f}" + (" (so far)" if cell.get("partial") else "")
        lines.append(
            f"| {name} | {' | '.join(versions)} | ok ({install['seconds'] / 60:.0f} min) | "
            f"{ran(cell, 'tests', tests_text)} | {ran(cell, 'envs', envs_text)} | {' | '.join(replays)} | "
            f"{ran(cell, 'probe', probe_text)} | {' | '.join(checks)} | {ran(cell, 'check', torch_check_text)} | "
            f"{ran(cell, 'check', changes_text)} | {ran(cell, 'speed', speed_text)} | {cost} |"
        )
    return "\n".join(lines)


def exact_text(cell: dict) -> str:
    exact = [POST_NAMES[p] for p in POSTS if cell["replay"]["posts"][p]["bit_exact"]]
    return f"{', '.join(exact) or 'none'} ({len(exact)}/3)"


def short_check_text(cell: dict) -> str:
    tier = "sensitive" if "sensitive" in cell["check"] else "smoke"
    run = cell["check"][tier]["posts"]
    changed = [POST_NAMES[p] for p in POSTS if p not in run or post_verdict(run[p]) == "changed"]
    if changed:
        return f"{tier}: changed or no verdict: " + ", ".join(changed)
    if all(run[p].get("same_bits") for p in POSTS):
        return f"{tier}: the same bits, all 3"
    return f"{tier}: all 3 consistent"


GROUPS = (
    ("the reference", ("reference",)),
    ("TensorFlow", ("tf", "nightly")),
    ("Keras", ("keras",)),
    ("Gymnasium", ("gymnasium",)),
    ("NumPy", ("numpy",)),
    ("PyTorch", ("torch",)),
    ("all at once", ("oldest", "newest")),
)
"""The README's rows: the cells grouped by the factor they vary (by their names' beginnings)."""


def short_cell(name: str, install: dict, cell: dict | None) -> str:
    """One cell in the README's short table: its versions, then what it found."""
    if install["exit_code"] != 0:
        return f"{name}: install failed"
    if cell is None:
        return f"{name}: not run yet"
    parts = [
        ran(cell, "tests", lambda c: "tests " + short_tests_text(c)),
        ran(cell, "replay", lambda c: "seed 0 bit-exact " + exact_text(c)),
        ran(cell, "check", short_check_text),
    ]
    return f"{name}: " + "; ".join(parts)


def short_table() -> str:
    """The README's table: one row per factor the cells vary, each cell in a line of its own, so
    that a new cell lengthens a row, not the page."""
    lines = ["| what varies | each cell: what it found |", "|---|---|"]
    cells = load_cells()
    grouped = [(title, [c for c in cells if c[0].startswith(prefixes)]) for title, prefixes in GROUPS]
    placed = {c[0] for _, mine in grouped for c in mine}
    grouped.append(("other", [c for c in cells if c[0] not in placed]))
    for title, mine in grouped:
        if mine:
            lines.append(f"| {title} | " + "<br>".join(short_cell(*c) for c in mine) + " |")
    return "\n".join(lines)


def page() -> str:
    cells = load_cells()
    done = [c for _, i, c in cells if c is not None]
    partial = sum(bool(c.get("partial")) for c in done)
    cost = sum(c["seconds"] for c in done) / 60
    return "\n".join(
        [
            "# Version matrix: our scores against library versions",
            "",
            "Generated by `python -m maintainers tables compat --write` from the cell folders beside this",
            "file; the cells are run by `make matrix` (`noxfile.py`: one fresh virtualenv per cell,",
            "`.venv/bin/nox -l` lists them). Each cell varies one factor from `reference`, the versions that",
            "made `results/` (`constraints.txt`); `oldest` and `newest` vary all five. PyTorch is 2.13.0",
            "(the CPU wheel the project pins) but in `torch*` and `newest`, whose releases are CUDA builds",
            "run on the CPU. A failed install is a result too: its row gives pip's reason.",
            "",
            table(),
            "",
            f"{len(done)} cells run{f' ({partial} stopped before their last step)' if partial else ''}, "
            f"{cost:.0f} minutes in all on this project's machine (2 cores).",
            "",
            *(
                ["Why the bits change where they do, with the evidence: [FINDINGS.md](FINDINGS.md).", ""]
                if (COMPAT / "FINDINGS.md").is_file()
                else []
            ),
            *[
                f"An installed TensorFlow is kept: [{p.name}]({p.name}) (`bash matrix/compat_keep_tf.sh`)."
                for p in sorted(COMPAT.glob("keep-tf*.md"))
            ],
            "",
            "How to read it:",
            "",
            '- **fast tests**: `pytest -m "not slow"` in the cell (`tests.json`; a failing suite\'s log is kept).',
            "- **env parity**: `tests/test_tf_envs.py` in the cell: the compiled engine's TensorFlow envs against the",
            "  cell's Gymnasium, one step from 1,000 random states per env (bit for bit on TensorFlow's kernels,",
            "  within stated ulps under XLA) and 200-step trajectories within 1e-6 (`envs.json`); a Gymnasium",
            "  release that changes the dynamics fails here. `not run`: the cell ran before the step existed.",
            "- **replay**: the post's committed seed 0 (Keras, faithful variant) rerun whole in the cell; `bit-exact`",
            "  means every column of `episodes.csv` but `wall_seconds` is equal, otherwise the first episode that",
            "  differs and its columns (`replay.json`).",
            "- **first numbers**: `matrix/compat_probe.py` in the cell and in the reference: each post's",
            "  initial weights, first action, and losses and weights after one update on a fixed batch; the",
            "  largest absolute difference over all of them (`probe.json`). `same bits`; `rounding`: float32",
            "  rounding in a kernel (under 1e-5), which a long run then amplifies into different episodes",
            "  without changing what is learned; `differ`: the computation itself changed.",
            "- **check**: `keras-rl check pendulum cartpole mountaincar --tier sensitive --workers 2`, the twin",
            "  check, against the committed baselines (`check-report.md`): `same bits` where every twin run first",
            "  kept its baseline seed's bits, otherwise the paired test's p over its twins. `smoke:` marks a cell",
            "  run before the twin check existed, with `keras-rl check ... --tier smoke` (a `changed` smoke",
            "  verdict was rerun at the full tier in the same cell and shown beside it). Each post-cell test has",
            "  a false-alarm rate under 1% (`results/checks/calibration.md`).",
            "- **check 003 (PyTorch)**: `keras-rl check cartpole --framework torch --tier smoke`, PyTorch's one",
            "  rule (`check-torch-report.md`).",
            "- **what the check names as changed**: each library whose version differs from the baseline's, and",
            "  a package that replaced another (`keras` -> `keras-nightly`), as the check's report names them.",
            "- **ms / reference**: `benchmarks/step_time.py --keras-only` in the cell over the same in the reference",
            "  cell, alternated five times in one session, median per post (`speed.json`). The reference row",
            "  against itself shows the noise.",
            "- **cost**: install plus all steps, wall minutes.",
            "",
        ]
    )


def run(args: argparse.Namespace) -> int:
    if not args.write:
        print(page())
        return 0
    from keras_rl.atomic import atomic_write_text

    atomic_write_text(COMPAT / "README.md", page())
    readme = ROOT / "README.md"
    atomic_write_text(readme, replace_block(readme.read_text(), SHORT_BEGIN, SHORT_END, short_table()))
    print(f"updated {COMPAT / 'README.md'} and {readme}")
    return 0
